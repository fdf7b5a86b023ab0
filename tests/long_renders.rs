//! Long renders people can trust: continue is bit-identical to one uninterrupted render, a
//! render killed while writing snapshots always leaves a valid image, SIGINT writes what was
//! done, and a reference records falling errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;
use vmerge::film::exr;

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name)
        .join("scene.toml")
}

fn run(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{:?}: {}",
        cmd,
        String::from_utf8_lossy(&out.stderr)
    );
}

fn bits(path: &Path) -> Vec<[u64; 3]> {
    let (film, _) = exr::read_render(path).unwrap();
    film.sum.iter().map(|s| s.map(f64::to_bits)).collect()
}

#[test]
fn continue_equals_one_uninterrupted_render() {
    let dir = tempfile::tempdir().unwrap();
    for technique in ["pt", "bpt", "vcm", "upg"] {
        let whole = dir.path().join(format!("{technique}-whole.exr"));
        let half = dir.path().join(format!("{technique}-half.exr"));
        let common = [
            "--resolution",
            "24x20",
            "--seed",
            "3",
            "--no-png",
            "-t",
            technique,
        ];
        run(vmerge()
            .arg("render")
            .arg(scene("cornell-spheres"))
            .args(common)
            .args(["-n", "6", "-o"])
            .arg(&whole));
        run(vmerge()
            .arg("render")
            .arg(scene("cornell-spheres"))
            .args(common)
            .args(["-n", "3", "-o"])
            .arg(&half));
        run(vmerge()
            .arg("continue")
            .arg(&half)
            .args(["-n", "3", "--no-png"]));
        assert_eq!(
            bits(&whole),
            bits(&half),
            "{technique}: continued render differs"
        );
        let (_, m) = exr::read_render(&half).unwrap();
        assert_eq!(m.iterations, 6);
    }
}

#[test]
fn continue_refuses_a_changed_scene_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/furnace");
    for f in ["scene.toml", "furnace.obj", "furnace.mtl"] {
        std::fs::copy(source.join(f), dir.path().join(f)).unwrap();
    }
    let out = dir.path().join("r.exr");
    run(vmerge()
        .arg("render")
        .arg(dir.path().join("scene.toml"))
        .args(["-n", "1", "--resolution", "8x8", "--no-png", "-o"])
        .arg(&out));
    let mtl = dir.path().join("furnace.mtl");
    let text = std::fs::read_to_string(&mtl)
        .unwrap()
        .replace("Kd 0.5 0.5 0.5", "Kd 0.4 0.4 0.4");
    std::fs::write(&mtl, text).unwrap();
    let refused = vmerge()
        .arg("continue")
        .arg(&out)
        .args(["-n", "1", "--no-png"])
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("changed"));
    run(vmerge()
        .arg("continue")
        .arg(&out)
        .args(["-n", "1", "--no-png", "--force"]));
}

/// Kills renders at random moments while they write a snapshot every few milliseconds: the
/// file is always either absent (no snapshot yet) or a complete, readable render.
#[test]
fn sigkill_never_leaves_a_broken_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("snap.exr");
    let mut rng = vmerge::sampling::Rng::for_sample(1, 0, 0, vmerge::sampling::Stream::Eye);
    let mut seen_valid = 0;
    for round in 0..20 {
        let mut child = vmerge()
            .arg("render")
            .arg(scene("cornell-box"))
            .args([
                "--resolution",
                "64x64",
                "--time",
                "60s",
                "--snapshot",
                "1ms",
                "-o",
            ])
            .arg(&out)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(50 + (rng.next_f32() * 400.0) as u64));
        child.kill().unwrap();
        child.wait().unwrap();
        if out.exists() {
            let (film, m) = exr::read_render(&out).unwrap_or_else(|e| panic!("round {round}: {e}"));
            assert_eq!(film.iterations, m.iterations);
            assert!(m.iterations > 0);
            seen_valid += 1;
        }
    }
    assert!(
        seen_valid > 10,
        "only {seen_valid} rounds had written a snapshot"
    );
}

#[test]
fn sigint_writes_the_iterations_done() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("int.exr");
    let child = vmerge()
        .arg("render")
        .arg(scene("cornell-box"))
        .args(["--resolution", "32x32", "--time", "60s", "-o"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let pid = child.id().to_string();
    run(Command::new("kill").args(["-INT", &pid]));
    let start = std::time::Instant::now();
    let status = child.wait_with_output().unwrap().status;
    assert!(status.success(), "{status:?}");
    assert!(start.elapsed() < Duration::from_secs(5));
    let (film, m) = exr::read_render(&out).unwrap();
    assert!(m.iterations > 0 && film.iterations == m.iterations);
    assert!(
        m.render_seconds > 0.3 && m.render_seconds < 5.0,
        "{}",
        m.render_seconds
    );
}

/// Errors against a reference of the same technique, made from more iterations, fall.
#[test]
fn reference_errors_fall_and_plot_draws_them() {
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("ref.exr");
    let out = dir.path().join("run.exr");
    let common = ["--resolution", "32x32", "--no-png", "-t", "bpt"];
    run(vmerge()
        .arg("render")
        .arg(scene("cornell-box"))
        .args(common)
        .args(["-n", "512", "--seed", "1", "-o"])
        .arg(&reference));
    run(vmerge()
        .arg("render")
        .arg(scene("cornell-box"))
        .args(common)
        .args([
            "-n",
            "64",
            "--seed",
            "2",
            "--trace",
            "16x16x4",
            "--reference",
        ])
        .arg(&reference)
        .arg("-o")
        .arg(&out));
    let (_, m) = exr::read_render(&out).unwrap();
    assert!(m.errors.len() >= 2, "{} error samples", m.errors.len());
    let (first, last) = (&m.errors[0], &m.errors[m.errors.len() - 1]);
    assert!(
        last.rmse < 0.7 * first.rmse,
        "RMS error {} -> {}",
        first.rmse,
        last.rmse
    );
    assert_eq!(last.traces.len(), 1);
    let chart = dir.path().join("chart.png");
    run(vmerge().arg("plot").arg(&chart).arg(&out));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&chart).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    reader.next_frame(&mut buf).unwrap();
    let distinct: std::collections::HashSet<&[u8]> = buf.chunks(3).collect();
    assert!(distinct.len() > 2, "blank chart");
}
