//! The HTTP side: a few threads answering the page's routes from a [`Content`].

use super::ImageData;
use std::io::{Cursor, Read};
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use thiserror::Error;
use tiny_http::{Header, Method, Request, Response, ResponseBox};

#[derive(Debug, Error)]
pub enum PreviewError {
    #[error("cannot serve the preview at {address}: {message}")]
    Bind {
        address: SocketAddr,
        message: String,
    },
    /// An address the user gave that cannot be bound: taken, not this machine's, or a port
    /// only root may use.
    #[error("cannot serve the preview at {address}: {message}")]
    Address {
        address: SocketAddr,
        message: String,
    },
}

/// The page: markup, style and script in one file, so nothing is fetched from elsewhere.
const PAGE: &str = include_str!("page.html");

/// Threads answering requests; a long poll holds one for up to [`super::live::LONG_POLL`].
const WORKERS: usize = 4;

/// How long stopping waits for responses still being written. A client that asked for an
/// image and stopped reading blocks its worker in a socket write that nothing here can
/// interrupt; such a worker is left behind rather than waited for, so it cannot hold up the
/// end of the process (which ends it).
const DRAIN: Duration = Duration::from_millis(250);

/// How long one write to a client may make no progress before the connection is dropped: a
/// client that asked for an image and stopped reading frees its worker after this, instead of
/// holding it (and, once all are held, the whole page) for as long as it stays connected.
pub(crate) const WRITE_TIMEOUT: Duration = Duration::from_secs(5);

/// What the page's `/state?since=F&errors=K` asks: wait for a frame newer than `F` (when
/// given), and send the error series from sample `K` on.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct StateQuery {
    pub since: Option<u64>,
    pub errors_from: usize,
}

/// What the routes serve: the live render's or the files'.
pub(crate) trait Content: Send + Sync + 'static {
    /// The page's state as JSON.
    fn state(&self, query: StateQuery) -> String;
    /// Image `index`, when there is one.
    fn image(&self, index: usize) -> Option<ImageData>;
}

/// A running server; dropping it stops the workers and closes the port.
pub struct Server {
    address: SocketAddr,
    http: Arc<tiny_http::Server>,
    stop: Arc<AtomicBool>,
    workers: Vec<JoinHandle<()>>,
    /// One message from each worker as it ends (a panic included).
    ended: Receiver<()>,
}

/// Tells the server that its worker ended, however it ended.
struct Ended(Sender<()>);

impl Drop for Ended {
    fn drop(&mut self) {
        // The server may be gone already, having stopped waiting.
        let _ = self.0.send(());
    }
}

impl Server {
    pub(crate) fn start(
        address: SocketAddr,
        content: Arc<dyn Content>,
    ) -> Result<Self, PreviewError> {
        let bind = |message: String| PreviewError::Bind { address, message };
        let http = listen(address).map_err(|e| {
            use std::io::ErrorKind::{AddrInUse, AddrNotAvailable, PermissionDenied};
            match e.downcast_ref::<std::io::Error>().map(|e| e.kind()) {
                Some(AddrInUse | AddrNotAvailable | PermissionDenied) => PreviewError::Address {
                    address,
                    message: e.to_string(),
                },
                _ => bind(e.to_string()),
            }
        })?;
        let bound = http
            .server_addr()
            .to_ip()
            .ok_or_else(|| bind("not an IP socket".into()))?;
        let http = Arc::new(http);
        let stop = Arc::new(AtomicBool::new(false));
        // On loopback, the port a browser must name in `Host`.
        let loopback = bound.ip().is_loopback().then_some(bound.port());
        let (ending, ended) = mpsc::channel();
        let mut workers = Vec::with_capacity(WORKERS);
        for _ in 0..WORKERS {
            let (serving, content, stopping) = (http.clone(), content.clone(), stop.clone());
            let ending = Ended(ending.clone());
            let worker = std::thread::Builder::new()
                .name("preview-http".into())
                .spawn(move || {
                    // Locals drop in reverse: the server's handle goes before the message.
                    let _ending = ending;
                    let (serving, content) = (serving, content);
                    // A worker freed from a stalled client after `drop` must not wait for
                    // requests again: the wake-ups went to the others.
                    while !stopping.load(Ordering::SeqCst) {
                        // A failed accept stops nothing else; a client that went away needs
                        // no answer.
                        if let Ok(request) = serving.recv() {
                            let _ = answer_request(request, &*content, loopback);
                        }
                    }
                });
            match worker {
                Ok(w) => workers.push(w),
                Err(e) => {
                    // Those already started must not keep the port open.
                    drop(Server {
                        address: bound,
                        http,
                        stop,
                        workers,
                        ended,
                    });
                    return Err(bind(format!("cannot start a thread: {e}")));
                }
            }
        }
        Ok(Server {
            address: bound,
            http,
            stop,
            workers,
            ended,
        })
    }

    /// The address bound to (with the port the system chose for port 0).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// A warning for the user when the page is reachable from other machines, for the caller
    /// to show: bound to loopback it is `None`.
    pub fn warning(&self) -> Option<String> {
        exposure_warning(self.address)
    }
}

/// The server on a listener of our own, made as `tiny_http::Server::http` makes it but with a
/// send timeout: tiny_http never sets one on the connections it accepts, and Linux gives each
/// accepted socket the listener's `SO_SNDTIMEO`.
fn listen(
    address: SocketAddr,
) -> Result<tiny_http::Server, Box<dyn std::error::Error + Send + Sync>> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(
        Domain::for_address(address),
        Type::STREAM,
        Some(Protocol::TCP),
    )?;
    // As std's listeners do on Unix: a port in TIME_WAIT from an earlier run is reusable.
    socket.set_reuse_address(true)?;
    socket.set_write_timeout(Some(WRITE_TIMEOUT))?;
    // A timed-out write leaves the connection open, and tiny_http writes to it again as it
    // flushes and drops its writers (a wait each); this closes it instead once the client
    // has taken nothing for as long, so those writes fail at once.
    #[cfg(target_os = "linux")]
    socket.set_tcp_user_timeout(Some(WRITE_TIMEOUT))?;
    socket.bind(&address.into())?;
    socket.listen(128)?;
    tiny_http::Server::from_listener(std::net::TcpListener::from(socket), None)
}

fn exposure_warning(address: SocketAddr) -> Option<String> {
    if address.ip().is_loopback() {
        return None;
    }
    Some(format!(
        "the preview at {address} is reachable from the network, not only from this machine: \
         anyone who can connect to the port sees the image, the scene's path and the render's \
         options, without a password (bind 127.0.0.1 and forward the port over SSH to keep it \
         private)"
    ))
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // One wake-up for each worker: each takes one and, seeing `stop`, ends.
        for _ in &self.workers {
            self.http.unblock();
        }
        let deadline = Instant::now() + DRAIN;
        let mut ended = 0;
        while ended < self.workers.len() {
            let left = deadline.saturating_duration_since(Instant::now());
            if self.ended.recv_timeout(left).is_err() {
                break;
            }
            ended += 1;
        }
        let all = ended == self.workers.len();
        for worker in self.workers.drain(..) {
            // One still writing to a stalled client is left to end with the process (dropping
            // its handle detaches it); one that panicked has nothing left to clean up.
            if all || worker.is_finished() {
                let _ = worker.join();
            }
        }
        // `http` goes after this; the listener closes with its last handle, a detached
        // worker's if there is one.
    }
}

fn answer_request(
    request: Request,
    content: &dyn Content,
    loopback: Option<u16>,
) -> std::io::Result<()> {
    let response = route(&request, content, loopback);
    request.respond(response)
}

fn header(name: &str, value: &str) -> Header {
    // Every name and value here is a constant or a number: ASCII, so this cannot fail.
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("ASCII header")
}

fn respond(
    status: u16,
    content_type: &str,
    body: impl Read + Send + 'static,
    length: usize,
) -> ResponseBox {
    let headers = vec![
        header("Content-Type", content_type),
        header("Cache-Control", "no-store"),
        header("X-Content-Type-Options", "nosniff"),
        header("Referrer-Policy", "no-referrer"),
    ];
    Response::new(status.into(), headers, body, Some(length), None).boxed()
}

fn text(status: u16, body: &str) -> ResponseBox {
    let body = body.as_bytes().to_vec();
    let length = body.len();
    respond(
        status,
        "text/plain; charset=utf-8",
        Cursor::new(body),
        length,
    )
}

fn route(request: &Request, content: &dyn Content, loopback: Option<u16>) -> ResponseBox {
    if loopback.is_some_and(|port| !host_is_loopback(request, port)) {
        return text(403, "this server answers to localhost only\n");
    }
    if *request.method() != Method::Get {
        return text(404, "not found\n");
    }
    let (path, query) = request.url().split_once('?').unwrap_or((request.url(), ""));
    match path {
        "/" => respond(200, "text/html; charset=utf-8", PAGE.as_bytes(), PAGE.len()).with_header(
            header(
                "Content-Security-Policy",
                "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
             connect-src 'self'; img-src 'self' data:; base-uri 'none'; form-action 'none'",
            ),
        ),
        "/state" => match parse_query(query) {
            Some(q) => {
                let body = content.state(q).into_bytes();
                let length = body.len();
                respond(200, "application/json", Cursor::new(body), length)
            }
            None => text(400, "expected /state?since=N&errors=N\n"),
        },
        _ => match path.strip_prefix("/image/").and_then(parse_index) {
            Some(index) => match content.image(index) {
                Some(image) => {
                    let length = image.floats.len();
                    respond(
                        200,
                        "application/octet-stream",
                        Cursor::new(Bytes(image.floats)),
                        length,
                    )
                    .with_header(header("X-Vmerge-Width", &image.width.to_string()))
                    .with_header(header("X-Vmerge-Height", &image.height.to_string()))
                    .with_header(header("X-Vmerge-Iteration", &image.iteration.to_string()))
                }
                None => text(404, "no such image (yet)\n"),
            },
            None => text(404, "not found\n"),
        },
    }
}

/// The image's bytes, shared with the state rather than copied for each request.
struct Bytes(Arc<Vec<u8>>);

impl AsRef<[u8]> for Bytes {
    fn as_ref(&self) -> &[u8] {
        &self.0
    }
}

/// Digits only: no sign, no path, nothing else.
fn parse_index(s: &str) -> Option<usize> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

fn parse_query(query: &str) -> Option<StateQuery> {
    let mut q = StateQuery::default();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        match pair.split_once('=')? {
            ("since", v) => q.since = Some(parse_index(v)? as u64),
            ("errors", v) => q.errors_from = parse_index(v)?,
            _ => return None,
        }
    }
    Some(q)
}

/// Whether the request's `Host` names this machine's loopback and the port served. A browser
/// always sends it; a page of another site that resolves its own name to 127.0.0.1 sends that
/// name, and is refused. It is parsed whole (a name or address, then `:port` or nothing), not
/// matched by prefix, so `localhost:80.evil.example` is refused too. An SSH tunnel must keep
/// the port number (`-L PORT:localhost:PORT`).
fn host_is_loopback(request: &Request, port: u16) -> bool {
    match request.headers().iter().find(|h| h.field.equiv("Host")) {
        Some(h) => host_allowed(h.value.as_str(), port),
        // Not a browser, so not a page of another site.
        None => true,
    }
}

/// `Host` is `name[:port]` or `[ipv6][:port]`; without a port it means HTTP's default, 80.
fn host_allowed(host: &str, port: u16) -> bool {
    let (name, given) = match host.strip_prefix('[') {
        Some(rest) => {
            let Some((inside, after)) = rest.split_once(']') else {
                return false;
            };
            let loopback = inside.parse::<Ipv6Addr>().is_ok_and(|ip| ip.is_loopback());
            (loopback.then_some(""), after)
        }
        None => {
            let (name, after) = match host.find(':') {
                Some(colon) => host.split_at(colon),
                None => (host, ""),
            };
            let loopback = name.eq_ignore_ascii_case("localhost")
                || name.parse::<Ipv4Addr>().is_ok_and(|ip| ip.is_loopback());
            (loopback.then_some(name), after)
        }
    };
    let given = match given.strip_prefix(':') {
        None if given.is_empty() => Some(80),
        Some(digits) if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) => {
            digits.parse::<u16>().ok()
        }
        _ => None,
    };
    name.is_some() && given == Some(port)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_are_digits_only() {
        assert_eq!(parse_index("12"), Some(12));
        for bad in ["", "+1", "-1", "1/", "../1", "1.0", "0x1", "1 "] {
            assert_eq!(parse_index(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn hosts_are_loopback_with_the_served_port_exactly() {
        for good in [
            "localhost:8123",
            "LOCALHOST:8123",
            "127.0.0.1:8123",
            "127.1.2.3:8123",
            "[::1]:8123",
            "[0:0:0:0:0:0:0:1]:8123",
        ] {
            assert!(host_allowed(good, 8123), "{good:?}");
        }
        for bad in [
            "localhost:80.evil.example",
            "localhost.evil.example:8123",
            "127.0.0.1.evil.example",
            "127.0.0.1.evil.example:8123",
            "evil.example:8123",
            "localhost:8124",
            "localhost:",
            "localhost:+8123",
            "localhost:8123:8123",
            "localhost",
            "[::1]",
            "[::1]8123",
            "[::1:8123",
            "::1:8123",
            "[::2]:8123",
            "[::ffff:7f00:1]evil:8123",
            "0.0.0.0:8123",
            "10.0.0.1:8123",
            "",
        ] {
            assert!(!host_allowed(bad, 8123), "{bad:?}");
        }
        // No port is HTTP's default.
        assert!(host_allowed("localhost", 80) && host_allowed("[::1]", 80));
        // A port beyond 16 bits does not wrap around.
        assert!(!host_allowed("localhost:99999", 34463) && !host_allowed("localhost:65536", 0));
    }

    #[test]
    fn a_public_address_is_warned_of_and_loopback_is_not() {
        assert!(exposure_warning("127.0.0.1:80".parse().unwrap()).is_none());
        assert!(exposure_warning("[::1]:80".parse().unwrap()).is_none());
        let w = exposure_warning("0.0.0.0:8123".parse().unwrap()).unwrap();
        assert!(w.contains("0.0.0.0:8123") && w.contains("network"), "{w}");
    }

    #[test]
    fn queries_name_since_and_errors_only() {
        let q = parse_query("since=3&errors=7").unwrap();
        assert_eq!((q.since, q.errors_from), (Some(3), 7));
        let q = parse_query("").unwrap();
        assert_eq!((q.since, q.errors_from), (None, 0));
        for bad in ["file=/etc/passwd", "since=x", "since", "errors=-1"] {
            assert!(parse_query(bad).is_none(), "{bad:?}");
        }
    }
}
