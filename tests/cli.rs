//! The command line: bad input gets a clear message naming the file, exit code 2, and no
//! output file.

use std::path::Path;
use std::process::Command;

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

/// Every fixture under tests/fixtures/bad/ (a `scene.toml` or a `scene.pbrt`) must be refused
/// with exit code 2, a message naming the offending file, and nothing written. A fixture's
/// `expected` file holds text the message must contain (for pbrt files: `file:line: what`).
#[test]
fn bad_scenes_exit_2_and_write_nothing() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bad");
    let mut cases: Vec<_> = std::fs::read_dir(&fixtures)
        .expect("tests/fixtures/bad exists")
        .map(|e| e.expect("readable fixture").path())
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 30,
        "expected the bad-input fixtures, found {}",
        cases.len()
    );
    for case in cases {
        let toml = case.join("scene.toml");
        let scene = if toml.exists() {
            toml
        } else {
            case.join("scene.pbrt")
        };
        let out = tempfile::tempdir().unwrap();
        let exr = out.path().join("out.exr");
        let result = vmerge()
            .args([
                "render",
                "--iterations",
                "1",
                "--resolution",
                "8x8",
                "--accel",
                "bvh",
                "-o",
            ])
            .arg(&exr)
            .arg(&scene)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(
            result.status.code(),
            Some(2),
            "{}: {stderr}",
            case.display()
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", case.display());
        let name = case.file_name().unwrap().to_string_lossy();
        assert!(
            stderr.contains(&*name),
            "{}: message does not name the file: {stderr}",
            case.display()
        );
        if let Ok(expected) = std::fs::read_to_string(case.join("expected")) {
            assert!(
                stderr.contains(expected.trim()),
                "{}: message lacks '{}': {stderr}",
                case.display(),
                expected.trim()
            );
        }
        let written: Vec<_> = std::fs::read_dir(out.path()).unwrap().collect();
        assert!(written.is_empty(), "{}: wrote {written:?}", case.display());
    }
}

#[test]
fn missing_input_files_exit_2() {
    for args in [
        vec!["average", "does-not-exist.exr"],
        vec!["errors", "a-missing.exr", "b-missing.exr"],
        vec!["continue", "missing-render.exr"],
    ] {
        let result = vmerge().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("missing"), "{args:?}: {stderr}");
    }
}

/// Options that mean nothing for the technique, or a technique that does not exist, are
/// refused before anything renders, naming the option.
#[test]
fn meaningless_strategies_exit_2() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    for (args, expected) in [
        (vec!["-t", "vcm", "--strategy", "1,2"], "--strategy"),
        (vec!["-t", "pt", "--unweighted"], "--unweighted"),
        (vec!["-t", "bpt", "--strategy", "2,0"], "--strategy 2,0"),
        (vec!["-t", "bpt", "--strategy", "two"], "--strategy"),
    ] {
        let out = tempfile::tempdir().unwrap();
        let result = vmerge()
            .args(["render", "--iterations", "1", "--resolution", "8x8", "-o"])
            .arg(out.path().join("out.exr"))
            .args(&args)
            .arg(&scene)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        let written: Vec<_> = std::fs::read_dir(out.path()).unwrap().collect();
        assert!(written.is_empty(), "{args:?}: wrote {written:?}");
    }
}
