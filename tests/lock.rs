//! Two processes on one output: while a `render` writes a file, a second `render`, `continue`
//! or `merge` naming it refuses at once (exit 2, naming the holder's pid) and the first
//! finishes its work untouched; once the first has ended, the output is free again.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml")
}

fn run(args: &[&std::ffi::OsStr]) -> Output {
    vmerge().args(args).output().unwrap()
}

fn iterations(path: &Path) -> (u64, f64) {
    let (film, metadata) = vmerge::film::exr::read_render(path).unwrap();
    (film.iterations, metadata.render_seconds)
}

/// A refusal of `output`: exit 2 at once, a message naming the file and the holder.
fn assert_refused(what: &str, out: &Output, output: &Path, holder: u32) {
    let message = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{what}: {message}");
    assert!(
        message.contains(&output.display().to_string()),
        "{what} does not name the file: {message}"
    );
    assert!(
        message.contains(&format!("pid {holder}")),
        "{what} does not name the holder {holder}: {message}"
    );
    assert!(message.len() < 2000, "{what}: {message}");
}

#[test]
fn a_second_process_on_an_output_refuses_until_the_first_ends() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("X.exr");
    let other = dir.path().join("Y.exr");
    let small = ["--resolution", "32x32", "--no-png"];
    let made = vmerge()
        .args(["render", "-n", "2", "-o"])
        .arg(&other)
        .args(small)
        .arg(scene())
        .output()
        .unwrap();
    assert!(made.status.success(), "{made:?}");

    let started = Instant::now();
    let mut first = vmerge()
        .args(["render", "--time", "8s", "-o"])
        .arg(&out)
        .args(small)
        .arg(scene())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // The lock file appears before the scene loads; the pid in it just after.
    let lock = dir.path().join(".X.exr.lock");
    let pid = first.id().to_string();
    while std::fs::read_to_string(&lock).ok().as_deref() != Some(pid.as_str()) {
        assert!(started.elapsed() < Duration::from_secs(5), "no lock file");
        std::thread::sleep(Duration::from_millis(10));
    }

    let scene = scene();
    let (o, y, s) = (out.as_os_str(), other.as_os_str(), scene.as_os_str());
    let cases = [
        (
            "render",
            vec![
                "render".as_ref(),
                "-n".as_ref(),
                "1".as_ref(),
                "-o".as_ref(),
                o,
                "--no-png".as_ref(),
                s,
            ],
        ),
        (
            "continue",
            vec![
                "continue".as_ref(),
                y,
                "-n".as_ref(),
                "1".as_ref(),
                "-o".as_ref(),
                o,
                "--no-png".as_ref(),
            ],
        ),
        ("merge", vec!["merge".as_ref(), o, y]),
    ];
    for (what, args) in &cases {
        let asked = Instant::now();
        let refused = run(args);
        assert_refused(what, &refused, &out, first.id());
        assert!(
            asked.elapsed() < Duration::from_secs(3),
            "{what} was slow to refuse"
        );
    }
    assert!(
        first.try_wait().unwrap().is_none(),
        "the first ended before the refusals were tried: the test proves nothing"
    );

    assert!(first.wait().unwrap().success());
    let (done, seconds) = iterations(&out);
    assert!(
        done > 0 && seconds > 7.0,
        "{done} iterations in {seconds} s"
    );
    assert!(!lock.exists(), "the lock file outlived its render");

    let again = run(&[
        "continue".as_ref(),
        o,
        "-n".as_ref(),
        "1".as_ref(),
        "--no-png".as_ref(),
    ]);
    assert!(again.status.success(), "{again:?}");
    assert_eq!(iterations(&out).0, done + 1);
}
