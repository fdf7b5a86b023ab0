//! Programs the tests run beside vmerge (GNU parallel, Chromium): whether they are here, and
//! feeding parallel its command lines.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

/// Whether `program` runs here; tests that need it say so and stop when it does not.
pub fn have(program: &str) -> bool {
    let found = Command::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found {
        eprintln!(
            "skipped: {program} is not installed (`scripts/setup-debian --tests` installs it)"
        );
    }
    found
}

/// Runs the command lines `jobs` through `parallel -j 2` in `dir`, stopping at the first that
/// fails.
pub fn parallel(jobs: &str, dir: &Path) {
    let mut child = Command::new("parallel")
        .args(["--will-cite", "-j", "2", "--halt", "now,fail=1"])
        .current_dir(dir)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(jobs.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "parallel: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}
