//! 002's density-map heuristics (VCM+ and VCM*): the furnace, convergence to bpt as the radius
//! shrinks, and images that depend neither on the thread count nor on where a render was
//! stopped and continued. That their weights sum to one is tests/mis_weights.rs's.

mod common;

use common::{floor_view, load, options, render_stats};
use std::path::Path;
use std::process::Command;
use vmerge::film::exr;
use vmerge::options::{DensityMis, RenderOptions, Technique};

fn with_density(mut o: RenderOptions, mode: DensityMis) -> RenderOptions {
    o.density_mis = Some(mode);
    // A map fixed early, so most of a test's iterations use the final weights.
    o.density_map_iterations = 16;
    o
}

/// Radiance 1 everywhere, within 1% with a standard error below 0.2% (as for plain vcm).
#[test]
fn vcm_plus_and_star_pass_the_furnace() {
    let scene = load("furnace");
    for mode in DensityMis::ALL {
        let mut o = with_density(options(Technique::Vcm, 64), mode);
        o.radius = Some(0.03);
        let stats = render_stats(&scene, &o, 256);
        stats.assert_furnace(&format!("{mode:?}"), 0.01, 0.002);
    }
}

/// With the radius shrinking (alpha = 0.75) both approach bpt's image: the mean within 1%, and
/// the RMS difference at least halves from 64 to 1024 iterations (tests/vcm.rs's statistic).
#[test]
fn vcm_plus_and_star_converge_to_bpt() {
    for name in ["cornell-spheres", "cornell-glossy"] {
        let scene = load(name);
        let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
        for mode in DensityMis::ALL {
            let o = with_density(floor_view(Technique::Vcm, 32), mode);
            let short = render_stats(&scene, &o, 64);
            let long = render_stats(&scene, &o, 1024);
            let (m, r) = (long.image_mean(), bpt.image_mean());
            assert!(
                (m - r).abs() < 0.01 * r,
                "{name} {mode:?}: mean {m}, bpt {r}"
            );
            let (early, late) = (short.rms_difference(&bpt), long.rms_difference(&bpt));
            assert!(
                late < 0.5 * early,
                "{name} {mode:?}: RMS difference {early} -> {late}"
            );
        }
    }
}

fn vmerge(args: &[&str], out: &Path) {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-glossy/scene.toml");
    let status = Command::new(env!("CARGO_BIN_EXE_vmerge"))
        .args(args)
        .arg("-o")
        .arg(out)
        .arg(&scene)
        .status()
        .expect("vmerge runs");
    assert!(status.success(), "vmerge {args:?}");
}

fn sums(path: &Path) -> Vec<[f64; 3]> {
    exr::read_render(path).expect("a render").0.sum
}

const RENDER: [&str; 10] = [
    "render",
    "-t",
    "vcm",
    "--resolution",
    "24x24",
    "--density-map-iterations",
    "5",
    "--no-png",
    "--seed",
    "3",
];

/// The map is filled from integer counts and rebuilt on `continue` from the same light
/// passes: one thread or two, in one go or stopped inside the filling iterations and
/// continued, the sums are the same bits.
#[test]
fn density_images_do_not_depend_on_threads_or_continuing() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    for mode in DensityMis::ALL {
        let name = mode.name();
        let path = |file: &str| dir.path().join(format!("{file}.exr"));
        let base: Vec<&str> = RENDER
            .iter()
            .copied()
            .chain(["--density-mis", name])
            .collect();
        let with =
            |extra: &[&'static str]| -> Vec<&str> { base.iter().chain(extra).copied().collect() };
        vmerge(&with(&["-n", "9", "--threads", "1"]), &path("one"));
        vmerge(&with(&["-n", "9", "--threads", "2"]), &path("two"));
        vmerge(&with(&["-n", "3", "--threads", "2"]), &path("part"));
        let status = Command::new(env!("CARGO_BIN_EXE_vmerge"))
            .args(["continue", "-n", "6", "--no-png"])
            .arg(path("part"))
            .status()
            .expect("vmerge runs");
        assert!(status.success(), "continue");
        let one = sums(&path("one"));
        assert!(one.iter().any(|s| s[0] > 0.0), "{name}: a black image");
        assert_eq!(one, sums(&path("two")), "{name}: 1 thread vs 2");
        assert_eq!(one, sums(&path("part")), "{name}: 3 + 6 continued vs 9");
        // And the heuristic changed the image: plain vcm's differs.
        vmerge(
            &RENDER
                .iter()
                .copied()
                .chain(["-n", "9"])
                .collect::<Vec<_>>(),
            &path("plain"),
        );
        assert_ne!(one, sums(&path("plain")), "{name}: the same as plain vcm");
    }
}
