//! The preview page: a running render's page updates in headless Chromium, the viewer shows
//! two files split, the server answers its own routes only and is gone when the render ends.
//!
//! The browser tests need `chromium` (`scripts/setup-debian --tests` installs it) and skip, saying so,
//! without it.

mod common;

use common::browser::headless_chromium;
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}/scene.toml"))
}

/// Renders `scene` at 64x64 for `iterations` into `output`.
fn render(scene_name: &str, iterations: u32, output: &Path) {
    let status = vmerge()
        .args(["render", "--resolution", "64x64", "--no-png", "-n"])
        .arg(iterations.to_string())
        .arg("-o")
        .arg(output)
        .arg(scene(scene_name))
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
}

/// A vmerge process serving a page; killed when dropped.
struct Served {
    child: Child,
    address: SocketAddr,
}

impl Served {
    /// Starts `vmerge ARGS` and reads the page's address from the line it prints.
    fn start(args: &[&std::ffi::OsStr]) -> Served {
        let mut child = vmerge()
            .args(args)
            .stderr(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            // The progress bar draws nothing without a terminal; lines are messages.
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Some(rest) = line.split("http://").nth(1) {
                    let address = rest.split('/').next().unwrap_or("").to_string();
                    let _ = tx.send(address);
                }
            }
        });
        let address = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("vmerge printed the page's address")
            .parse()
            .unwrap();
        Served { child, address }
    }

    /// A render of cornell-box for `time` at `resolution` into `out`, with its live page on
    /// loopback, once the page serves its first image (within `wait`).
    fn render_with_image(out: &Path, time: &str, resolution: &str, wait: Duration) -> Served {
        let served = Served::start(&[
            "render".as_ref(),
            scene("cornell-box").as_os_str(),
            "--time".as_ref(),
            time.as_ref(),
            "--resolution".as_ref(),
            resolution.as_ref(),
            "--no-png".as_ref(),
            "-o".as_ref(),
            out.as_os_str(),
            "--preview=127.0.0.1:0".as_ref(),
        ]);
        let local = served.address.to_string();
        let deadline = Instant::now() + wait;
        while request(served.address, "GET", "/image/0", &local) != Some(200) {
            assert!(Instant::now() < deadline, "no image after {wait:?}");
            std::thread::sleep(Duration::from_millis(50));
        }
        served
    }

    fn url(&self) -> String {
        format!("http://{}/", self.address)
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    let found = std::env::split_paths(&path)
        .flat_map(|dir| ["chromium", "chromium-browser"].map(|name| dir.join(name)))
        .find(|p| p.is_file());
    if found.is_none() {
        eprintln!("skipped: no chromium on PATH (`scripts/setup-debian --tests` installs it)");
    }
    found
}

/// The longest a Chromium run may take: a cold start on a loaded machine takes seconds, a run
/// that reaches this has hung, and fails the test rather than holding up the suite.
const CHROMIUM_LIMIT: &str = "60";

/// Runs headless Chromium on `url` with a fresh profile and `mode` (`--dump-dom` or
/// `--screenshot=...`). Virtual time stands still while a request is open, so a budget of
/// `budget_ms` lets the page's timers run that long however long the server takes to answer.
fn headless(browser: &Path, url: &str, mode: &str, budget_ms: u32) -> String {
    let profile = tempfile::tempdir().unwrap();
    let output = headless_chromium(browser, CHROMIUM_LIMIT, "1280,900", profile.path())
        .arg(format!("--virtual-time-budget={budget_ms}"))
        .arg(mode)
        .arg(url)
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .expect("coreutils' timeout runs");
    match output.status.code() {
        Some(0) => String::from_utf8_lossy(&output.stdout).into_owned(),
        Some(124 | 137) => panic!("chromium {mode} took over {CHROMIUM_LIMIT} s on {url}"),
        _ => panic!("chromium {mode} failed on {url}: {}", output.status),
    }
}

/// The text of the element with `id` in a DOM dump (elements of the page hold plain text).
fn element(dom: &str, id: &str) -> Option<String> {
    let start = dom.find(&format!("id=\"{id}\""))?;
    let rest = &dom[start..];
    let open = rest.find('>')? + 1;
    let close = rest[open..].find('<')?;
    Some(rest[open..open + close].to_string())
}

fn number(dom: &str, id: &str) -> u64 {
    let text = element(dom, id).unwrap_or_else(|| panic!("no #{id} in the page"));
    text.trim()
        .parse()
        .unwrap_or_else(|_| panic!("#{id} is {text:?}, not a number"))
}

/// Pixels of a screenshot, as RGB.
fn screenshot(browser: &Path, url: &str, budget_ms: u32) -> Vec<[u8; 3]> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("page.png");
    headless(
        browser,
        url,
        &format!("--screenshot={}", path.display()),
        budget_ms,
    );
    let decoder = png::Decoder::new(std::fs::File::open(&path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    let channels = info.color_type.samples();
    buffer[..info.buffer_size()]
        .chunks(channels)
        .map(|p| [p[0], p[1], p[2]])
        .collect()
}

/// Counts of the Cornell box's wall colours (red, green) and of distinct colours. The page's
/// own style has neither a red nor a green.
fn colours(pixels: &[[u8; 3]]) -> (usize, usize, usize) {
    let red = |p: &[u8; 3]| {
        let [r, g, b] = p.map(i32::from);
        r > g + 60 && r > b + 60
    };
    let green = |p: &[u8; 3]| {
        let [r, g, b] = p.map(i32::from);
        g > r + 40 && g > b + 40
    };
    let distinct: std::collections::HashSet<_> = pixels.iter().collect();
    (
        pixels.iter().filter(|p| red(p)).count(),
        pixels.iter().filter(|p| green(p)).count(),
        distinct.len(),
    )
}

#[test]
fn live_page_follows_the_render() {
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("reference.exr");
    render("cornell-box", 16, &reference);
    let out = dir.path().join("render.exr");
    let served = Served::start(&[
        "render".as_ref(),
        scene("cornell-box").as_os_str(),
        "--time".as_ref(),
        "300s".as_ref(),
        "--resolution".as_ref(),
        "64x64".as_ref(),
        "--no-png".as_ref(),
        "--reference".as_ref(),
        reference.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--preview".as_ref(),
    ]);
    let dom = headless(&browser, &served.url(), "--dump-dom", 1000);
    let updates = number(&dom, "updates");
    let first = number(&dom, "first-iteration");
    let last = number(&dom, "image-iteration");
    assert!(updates >= 2, "the image was drawn {updates} times");
    assert!(
        last > first,
        "the iteration shown went from {first} to {last}"
    );
    assert!(number(&dom, "iteration") >= last);
    let rmse = element(&dom, "rmse").unwrap();
    assert!(rmse.contains('e'), "rmse shown: {rmse:?}");
    assert!(dom.contains("<polyline"), "the error chart has no line");
    assert!(dom.contains(">cornell-box · pt<"), "no title");

    let pixels = screenshot(&browser, &served.url(), 500);
    let (red, green, distinct) = colours(&pixels);
    assert!(distinct > 200, "the screenshot has {distinct} colours");
    assert!(
        red > 5000 && green > 5000,
        "walls: {red} red, {green} green pixels"
    );
}

#[test]
fn viewer_splits_two_files() {
    let Some(browser) = chromium() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("box.exr"), dir.path().join("furnace.exr"));
    render("cornell-box", 8, &a);
    render("furnace", 4, &b);
    let served = Served::start(&["view".as_ref(), a.as_os_str(), b.as_os_str()]);
    let dom = headless(&browser, &served.url(), "--dump-dom", 500);
    assert!(
        dom.contains("id=\"canvas-wrap\" data-view=\"split\""),
        "two files do not open split"
    );
    assert_eq!(number(&dom, "updates"), 2, "both images loaded");
    assert_eq!(element(&dom, "status").as_deref(), Some("2 files loaded"));
    for name in ["box.exr", "furnace.exr"] {
        assert!(
            dom.contains(&format!("{}</h3>", dir.path().join(name).display())),
            "no metadata table for {name}"
        );
    }
    assert!(dom.contains("<td>technique</td><td>pt</td>"));

    // Split in the middle: the box's red wall (left) shows, its green wall (right) is covered
    // by the grey furnace.
    let (red, green, distinct) = colours(&screenshot(&browser, &served.url(), 500));
    assert!(distinct > 200, "the screenshot has {distinct} colours");
    assert!(red > 5000, "{red} red pixels: the left half is not the box");
    assert!(
        green < 100,
        "{green} green pixels: the right half is not the furnace"
    );
}

/// One HTTP/1.0 request; the status code, or `None` when nothing listens.
fn request(address: SocketAddr, method: &str, path: &str, host: &str) -> Option<u16> {
    let mut stream = TcpStream::connect(address).ok()?;
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    write!(stream, "{method} {path} HTTP/1.0\r\nHost: {host}\r\n\r\n").ok()?;
    let mut answer = String::new();
    BufReader::new(stream).read_line(&mut answer).ok()?;
    answer.split(' ').nth(1)?.parse().ok()
}

#[test]
fn serves_its_routes_only_and_stops_with_the_render() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("render.exr");
    let mut served = Served::start(&[
        "render".as_ref(),
        scene("cornell-box").as_os_str(),
        "--time".as_ref(),
        "4s".as_ref(),
        "--resolution".as_ref(),
        "32x32".as_ref(),
        "--no-png".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
        "--preview=127.0.0.1:0".as_ref(),
    ]);
    let address = served.address;
    assert!(address.ip().is_loopback());
    let local = address.to_string();
    let get = |path: &str| request(address, "GET", path, &local);
    assert_eq!(get("/"), Some(200));
    assert_eq!(get("/state"), Some(200));
    assert_eq!(get("/state?since=0&errors=0"), Some(200));
    let deadline = Instant::now() + Duration::from_secs(3);
    while get("/image/0") != Some(200) {
        assert!(Instant::now() < deadline, "no image after 3 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    for path in [
        "/index.html",
        "/favicon.ico",
        "/image",
        "/image/1",
        "/image/-1",
        "/image/0/",
        "/image/../state",
        "/image/%30",
        "/state/",
        "/../Cargo.toml",
        "/%2e%2e/Cargo.toml",
        "/etc/passwd",
        "//",
        "/render.exr",
    ] {
        assert_eq!(get(path), Some(404), "{path}");
    }
    assert_eq!(request(address, "POST", "/", &local), Some(404));
    assert_eq!(get("/state?file=/etc/passwd"), Some(400));
    assert_eq!(
        request(address, "GET", "/", "attacker.example"),
        Some(403),
        "another site's name on loopback"
    );
    for host in [
        format!("localhost:{}", address.port()),
        format!("LOCALHOST:{}", address.port()),
        format!("[::1]:{}", address.port()),
    ] {
        assert_eq!(request(address, "GET", "/", &host), Some(200), "{host}");
    }
    for host in [
        format!("localhost:{}.evil.example", address.port()),
        format!("127.0.0.1.evil.example:{}", address.port()),
        format!("localhost:{}", address.port() ^ 1),
        "localhost".to_string(),
    ] {
        assert_eq!(request(address, "GET", "/", &host), Some(403), "{host}");
    }

    let status = served.child.wait().unwrap();
    assert!(status.success());
    assert!(out.is_file());
    assert!(closes(address), "the server outlived the render");
}

/// A client that asks for images and never reads the answers blocks a worker in a socket
/// write; the render must still end within a second of writing its image.
#[test]
fn a_stalled_client_does_not_delay_the_exit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("render.exr");
    let mut served = Served::render_with_image(&out, "3s", "64x64", Duration::from_secs(3));
    let address = served.address;
    let local = address.to_string();
    // Pipelined requests for 20 MB of answers, far beyond what the sockets buffer.
    let mut stalled = TcpStream::connect(address).unwrap();
    let one = format!("GET /image/0 HTTP/1.1\r\nHost: {local}\r\n\r\n");
    stalled.write_all(one.repeat(400).as_bytes()).unwrap();
    while !out.exists() {
        assert!(
            served.child.try_wait().unwrap().is_none(),
            "ended without its image"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let written = Instant::now();
    let status = loop {
        if let Some(status) = served.child.try_wait().unwrap() {
            break status;
        }
        assert!(
            written.elapsed() < Duration::from_secs(10),
            "still running 10 s after writing its image"
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    let delay = written.elapsed();
    assert!(status.success());
    assert!(
        delay < Duration::from_secs(1),
        "ended {delay:?} after writing its image"
    );
    drop(stalled);
}

/// Clients that ask for an image each and never read the answer block every worker in a
/// socket write; each write gives up after the server's write timeout (5 s), so the page
/// answers others again instead of staying blocked for as long as the clients stay connected.
#[test]
fn stalled_clients_free_their_workers() {
    use socket2::{Domain, Socket, Type};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("render.exr");
    // 1024x1024: a 12 MiB image, more than a socket's send buffer can hold (4 MiB at most).
    let served = Served::render_with_image(&out, "40s", "1024x1024", Duration::from_secs(20));
    let address = served.address;
    let local = address.to_string();
    // One stalled client per worker (4), each with a small receive buffer so that the image
    // cannot all sit in buffers.
    let stalled: Vec<TcpStream> = (0..4)
        .map(|_| {
            let socket = Socket::new(Domain::for_address(address), Type::STREAM, None).unwrap();
            socket.set_recv_buffer_size(8192).unwrap();
            socket.connect(&address.into()).unwrap();
            let mut stream = TcpStream::from(socket);
            write!(stream, "GET /image/0 HTTP/1.1\r\nHost: {local}\r\n\r\n").unwrap();
            stream
        })
        .collect();
    // Long enough for every worker to be blocked with its socket's buffers full.
    std::thread::sleep(Duration::from_secs(1));
    let asked = Instant::now();
    let mut stream = TcpStream::connect(address).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    write!(stream, "GET /state HTTP/1.0\r\nHost: {local}\r\n\r\n").unwrap();
    let mut answer = String::new();
    let read = BufReader::new(stream).read_line(&mut answer);
    let waited = asked.elapsed();
    assert!(
        read.is_ok() && answer.contains(" 200 "),
        "no answer in {waited:?} while clients stall: {answer:?}"
    );
    assert!(
        waited < Duration::from_secs(8),
        "answered only after {waited:?}"
    );
    eprintln!("answered after {waited:?} with every worker stalled");
    drop(stalled);
}

/// In the library: the server is gone once the render's preview is dropped, while the process
/// lives on.
#[test]
fn the_preview_closes_its_port_when_dropped() {
    use vmerge::options::RenderOptions;
    use vmerge::render::{NewRender, Observer, StopAfter, StopFlag};
    let dir = tempfile::tempdir().unwrap();
    let setup = NewRender {
        scene: scene("cornell-box"),
        options: RenderOptions {
            resolution: Some([16, 16]),
            ..Default::default()
        },
        accel: vmerge::accel::AccelKind::default_kind(),
        lenient: false,
        output: dir.path().join("render.exr"),
        png: false,
        snapshot_every: None,
        reference: None,
        traces: Vec::new(),
        memory_limit: None,
    };
    let scene = setup.load_scene().unwrap();
    let mut job = setup.job(&scene).unwrap();
    let stop = StopAfter {
        iterations: Some(4),
        ..StopAfter::default()
    };
    let mut preview = vmerge::preview::LivePreview::start(
        vmerge::preview::DEFAULT_ADDRESS.parse().unwrap(),
        &job,
        stop,
    )
    .unwrap();
    let address = preview.address();
    let local = address.to_string();
    job.run_observed(
        stop,
        &StopFlag::default(),
        Some(&mut preview as &mut dyn Observer),
        |_| {},
    )
    .unwrap();
    assert_eq!(request(address, "GET", "/image/0", &local), Some(200));
    drop(preview);
    assert!(
        closes(address),
        "still served after the preview was dropped"
    );
}

/// Whether the port at `address` refuses connections within a second (the listener closes on
/// its own thread, just after the server's last handle goes).
fn closes(address: SocketAddr) -> bool {
    let deadline = Instant::now() + Duration::from_secs(1);
    while Instant::now() < deadline {
        if TcpStream::connect(address).is_err() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}
