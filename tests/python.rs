//! The Python module's tests (python/tests, pytest), run by `cargo test` so that the test
//! command covers them: scripts/setup-python builds the module into .venv, then pytest runs
//! against the command line of this build. Skipped, with a message, only where there is no
//! Python at all.

use std::path::Path;
use std::process::Command;

#[test]
fn the_python_modules_tests_pass() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("skipping the Python module's tests: no python3 on the PATH");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let setup = Command::new(root.join("scripts/setup-python"))
        .current_dir(root)
        .status()
        .expect("running scripts/setup-python");
    assert!(setup.success(), "scripts/setup-python failed");
    let pytest = Command::new(root.join(".venv/bin/python"))
        .args([
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "python/tests",
        ])
        .current_dir(root)
        .env("VMERGE_BIN", env!("CARGO_BIN_EXE_vmerge"))
        .status()
        .expect("running pytest");
    assert!(pytest.success(), "the Python module's tests failed");
}
