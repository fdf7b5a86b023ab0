//! Headless Chromium for the tests of the preview and batch pages.

use std::path::Path;
use std::process::Command;

/// A headless Chromium run under `timeout` (`limit_s` seconds, then a kill), so that a hang
/// fails its test (exit status 124 or 137) instead of holding up the suite; `timeout` runs it in
/// a process group of its own and ends all of it, renderers included. Without
/// `--run-all-compositor-stages-before-draw` a screenshot taken when a virtual-time budget runs
/// out waits, in about half the runs, for a frame that never comes if the page was still
/// updating. The caller adds the mode (`--screenshot=...`, `--dump-dom`) and the URL.
pub fn headless_chromium(browser: &Path, limit_s: &str, window: &str, profile: &Path) -> Command {
    let mut command = Command::new("timeout");
    command
        .args(["--kill-after=5", limit_s])
        .arg(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--run-all-compositor-stages-before-draw",
        ])
        .arg(format!("--window-size={window}"))
        .arg(format!("--user-data-dir={}", profile.display()));
    command
}
