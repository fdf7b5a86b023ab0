//! Vertex connection and merging: the furnace for ppm, bpm and vcm, vcm without merging is
//! bpt, and vcm converges to bpt as its radius shrinks.

mod common;

use common::{assert_agree, floor_view, load, options, render_stats, PixelStats};
use vmerge::integrator::Technique;

/// Radiance 1 everywhere: within 1% (merging at a radius of 1.5% of the box's side is biased
/// only in the thin bands along its edges), with a standard error below 0.2% so the test can
/// see a 1% error.
#[test]
fn ppm_bpm_and_vcm_pass_the_furnace() {
    let scene = load("furnace");
    for technique in [Technique::Ppm, Technique::Bpm, Technique::Vcm] {
        let mut o = options(technique, 64);
        o.radius = Some(0.03);
        let stats = render_stats(&scene, &o, 256);
        let (mean, se) = (stats.image_mean(), stats.image_se());
        assert!(se < 0.002, "{technique:?}: standard error {se}");
        assert!(
            (mean - 1.0).abs() < 0.01,
            "{technique:?}: furnace mean {mean} (se {se})"
        );
    }
}

/// With merging off, vcm's weights are bpt's (001 sec. 5.5): the same image within noise.
#[test]
fn vcm_without_merging_is_bpt() {
    let scene = load("cornell-box");
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
    let mut o = floor_view(Technique::Vcm, 32);
    o.no_vm = true;
    let vcm = render_stats(&scene, &o, 2048);
    assert_agree("vcm --no-vm vs bpt", &vcm, &bpt);
}

fn rms_difference(a: &PixelStats, b: &PixelStats) -> f64 {
    let n = a.mean.len() as f64;
    (a.mean
        .iter()
        .zip(&b.mean)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        / n)
        .sqrt()
}

/// vcm with a shrinking radius (alpha = 0.75) approaches bpt's image: the image mean within 1%
/// of it, and the RMS difference falls as iterations grow (bias and noise both shrink).
#[test]
fn vcm_converges_to_bpt() {
    for name in ["cornell-spheres", "cornell-glossy"] {
        let scene = load(name);
        let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
        let short = render_stats(&scene, &floor_view(Technique::Vcm, 32), 64);
        let long = render_stats(&scene, &floor_view(Technique::Vcm, 32), 1024);
        let (m, r) = (long.image_mean(), bpt.image_mean());
        assert!((m - r).abs() < 0.01 * r, "{name}: vcm mean {m}, bpt {r}");
        let (early, late) = (rms_difference(&short, &bpt), rms_difference(&long, &bpt));
        assert!(
            late < 0.5 * early,
            "{name}: RMS difference {early} -> {late}"
        );
    }
}
