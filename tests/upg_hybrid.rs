//! `upg-hybrid` (each merge gathered from the light or the camera side as its rule picks): the
//! furnace, agreement with `bpt` per pixel where both sides gather, its statistics, and the
//! options it refuses as `upg` does.

mod common;

use common::{assert_agree, floor_view, load, options, render_stats};
use std::process::Command;
use std::time::Duration;
use vmerge::color::Rgb;
use vmerge::integrator::upg::UpgCounters;
use vmerge::integrator::RenderContext;
use vmerge::options::{DensityMis, RenderOptions, Technique};
use vmerge::render::create_integrator;
use vmerge::scene::{Camera, Scene};

const HYBRID: Technique = Technique::UpgHybrid;

/// Radiance 1 everywhere within 0.5%: at a small and a large radius (1.5% and 10% of the box),
/// with every merge gathered from the camera side (a threshold above every surface), with
/// 002's VCM* weights, and with a radius per pixel (light sub-paths re-run at each eye
/// sub-path's radius). At the default threshold the furnace's surfaces are rough: merges next
/// to the light are gathered from the camera side, the rest from the light side.
#[test]
fn upg_hybrid_passes_the_furnace() {
    let scene = load("furnace");
    for (radius, threshold, density, radius_pixels) in [
        (Some(0.03), None, None, None),
        (Some(0.2), Some(2.0), None, None),
        (Some(0.05), None, Some(DensityMis::Star), None),
        (None, None, None, Some(4.0)),
    ] {
        let mut o = options(HYBRID, 48);
        o.radius = radius;
        o.radius_pixels = radius_pixels;
        if let Some(t) = threshold {
            o.hybrid_roughness = t;
        }
        if let Some(mode) = density {
            o.density_mis = Some(mode);
            o.density_map_iterations = 16;
        }
        let stats = render_stats(&scene, &o, 128);
        let label = format!("r {radius:?} ({radius_pixels:?} pixels), {threshold:?}, {density:?}");
        stats.assert_furnace(&label, 0.005, 0.001);
        assert_eq!(stats.dropped, 0);
    }
}

/// On cornell-glossy (Phong walls of alpha 0.41 and 0.14, either side of the default
/// threshold, so both sides gather), in the acute corners of `corners` at a radius where vcm
/// is visibly biased (`tests/upg.rs`), and on `caustic` (a glass sphere lit by a point light,
/// whose merges next to the glass neither side can make), upg-hybrid agrees with bpt per
/// pixel: means and the standardised per-pixel difference.
#[test]
fn upg_hybrid_agrees_with_bpt() {
    for (name, floor, radius) in [
        ("cornell-glossy", true, None),
        ("corners", false, Some(0.15)),
        ("caustic", true, None),
    ] {
        let scene = load(name);
        let view = |t| {
            if floor {
                floor_view(t, 24)
            } else {
                options(t, 24)
            }
        };
        let bpt = render_stats(&scene, &view(Technique::Bpt), 2048);
        let mut o = view(HYBRID);
        o.radius = radius;
        let hybrid = render_stats(&scene, &o, 1024);
        assert_agree(&format!("{name}: upg-hybrid r {radius:?}"), &hybrid, &bpt);
    }
}

/// The statistics name the merges of each side, and the threshold moves merges between them:
/// on cornell-glossy the default gathers a share from each side, a threshold above every
/// surface's roughness gathers all from the camera side.
#[test]
fn the_statistics_count_the_merges_of_each_side() {
    let scene = load("cornell-glossy");
    let share = |threshold: f32| {
        let o = RenderOptions {
            hybrid_roughness: threshold,
            ..floor_view(HYBRID, 32)
        };
        let (counters, statistics) = two_iterations(&scene, &o);
        let stat = |name: &str| -> u64 {
            let value = statistics.iter().find(|(n, _)| n == name);
            value
                .unwrap_or_else(|| panic!("no {name}"))
                .1
                .parse()
                .unwrap()
        };
        let (light, camera) = (
            stat("hybrid_light_side_merges"),
            stat("hybrid_camera_side_merges"),
        );
        assert_eq!(light + camera, stat("upg_merges"));
        assert_eq!(camera, counters.camera_merges);
        camera as f64 / (light + camera) as f64
    };
    let default = share(RenderOptions::DEFAULT.hybrid_roughness);
    assert!(
        default > 0.05 && default < 0.95,
        "camera-side share {default}"
    );
    assert_eq!(share(2.0), 1.0);
}

/// The counters and statistics after two iterations.
fn two_iterations(scene: &Scene, o: &RenderOptions) -> (UpgCounters, Vec<(String, String)>) {
    let [w, h] = o.resolution.unwrap();
    let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), w, h);
    let mut integrator = create_integrator(RenderContext {
        scene,
        camera,
        options: o,
    });
    let mut frame = vec![Rgb::BLACK; (w * h) as usize];
    for iteration in 0..2 {
        integrator.render_iteration(iteration, &mut frame);
    }
    let counters = UpgCounters::from_named(&integrator.counters()).expect("upg-hybrid merged");
    (counters, integrator.statistics(Duration::from_secs(1)))
}

/// Through the command line, upg-hybrid refuses what upg refuses (one-stage storage), takes
/// what upg takes (a radius per pixel, 002's weights), and its threshold belongs to it alone
/// and must be a roughness.
#[test]
fn the_command_line_refuses_what_upg_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let scene = format!(
        "{}/scenes/cornell-box/scene.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let run = |args: &[&str]| {
        let out = dir.path().join("out.exr");
        let output = Command::new(env!("CARGO_BIN_EXE_vmerge"))
            .args(["render", "--iterations", "1", "--resolution", "8x8", "-o"])
            .arg(&out)
            .args(args)
            .arg(&scene)
            .output()
            .unwrap();
        let _ = std::fs::remove_file(&out);
        (
            output.status.code(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    };
    for (technique, args, flag) in [
        ("upg", &["--memory", "one-stage"][..], "--memory"),
        ("upg-hybrid", &["--memory", "one-stage"], "--memory"),
        ("upg", &["--hybrid-roughness", "0.3"], "--hybrid-roughness"),
        ("upg-hybrid", &["--alpha", "0.5"], "--alpha"),
        (
            "upg-hybrid",
            &["--hybrid-roughness=-1"],
            "--hybrid-roughness",
        ),
        (
            "upg-hybrid",
            &["--hybrid-roughness", "nan"],
            "--hybrid-roughness",
        ),
    ] {
        let (code, stderr) = run(&[&["-t", technique][..], args].concat());
        assert_eq!(code, Some(2), "{technique} {args:?}: {stderr}");
        assert!(
            stderr.contains(flag) && !stderr.contains("panicked"),
            "{technique} {args:?}: {stderr}"
        );
    }
    for args in [
        &["--hybrid-roughness", "0.5"][..],
        &["--radius-pixels", "2", "--density-mis", "vcm*"],
        &["--upg-packet", "8", "--no-vc"],
    ] {
        let (code, stderr) = run(&[&["-t", "upg-hybrid"][..], args].concat());
        assert_eq!(code, Some(0), "{args:?}: {stderr}");
    }
}
