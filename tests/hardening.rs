//! Input built to exhaust: a pbrt file whose one line is tens of megabytes is refused with a
//! short message naming the file and line, never echoed whole.

use std::path::Path;
use std::process::Command;

const HEAD: &str =
    "LookAt 0 1 4  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\nWorldBegin\n";

/// Renders `scene.pbrt` holding `text`; checks exit 2, no panic, a message under 2,000 bytes
/// naming the file and `line`, and nothing written.
fn refused(text: &str, line: u32) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(dir.path().join("scene.pbrt"), text).unwrap();
    let result = Command::new(env!("CARGO_BIN_EXE_vmerge"))
        .args(["render", "--iterations", "1", "--resolution", "8x8", "-o"])
        .arg(out.join("out.exr"))
        .arg("scene.pbrt")
        .current_dir(dir.path())
        .env("TMPDIR", &out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    let short: String = stderr.chars().take(300).collect();
    assert_eq!(result.status.code(), Some(2), "{short}");
    assert!(!stderr.contains("panicked"), "{short}");
    assert!(stderr.len() < 2000, "a message of {} bytes", stderr.len());
    assert!(stderr.contains(&format!("scene.pbrt:{line}:")), "{stderr}");
    assert!(Path::new(&out).read_dir().unwrap().next().is_none());
}

#[test]
fn a_huge_token_is_quoted_as_an_excerpt() {
    let huge = "x".repeat(50 << 20);
    // An unknown directive, a bad number, an unknown shape name, a parameter's declaration.
    refused(&format!("{HEAD}\n{huge}\n"), 5);
    refused(
        &format!("{HEAD}Shape \"sphere\" \"float radius\" [ 1{huge} ]\n"),
        4,
    );
    refused(&format!("{HEAD}Shape \"{huge}\"\n"), 4);
    refused(&format!("{HEAD}Shape \"sphere\" \"float {huge}\" 1\n"), 4);
}
