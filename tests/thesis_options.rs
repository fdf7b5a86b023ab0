//! The options the thesis's experiments use (000 ch. 4 and sec. 5.2): `min_path_length`,
//! `light_paths` (n_VM) and merge-only UPG (`upg` with `no_vc`), checked in the furnace, whose
//! radiance is known path length by path length.

mod common;

use common::{load, options, render_stats};
use vmerge::options::{RenderOptions, Technique};
use vmerge::render::render_iterations;

/// The furnace's walls emit Le = 0.5 and reflect rho = 0.5 (scenes/furnace), and its paths
/// stop at 10 segments: a path of k segments carries Le rho^(k - 1), so the radiance of paths
/// of `min` segments and more is the sum of those terms.
fn furnace_radiance(min: u32) -> f64 {
    (min.max(1)..=10)
        .map(|k| 0.5 * 0.5f64.powi(k as i32 - 1))
        .sum()
}

/// Renders `o` in the furnace and checks the image mean against `expected`: the standard
/// error must be small enough to see a 1% error, and the mean within four of them.
fn assert_furnace(label: &str, o: &RenderOptions, iterations: u64, expected: f64) {
    let scene = load("furnace");
    let stats = render_stats(&scene, o, iterations);
    let (mean, se) = (stats.image_mean(), stats.image_se());
    assert!(se < 0.0025 * expected, "{label}: standard error {se}");
    assert!(
        (mean - expected).abs() < 4.0 * se,
        "{label}: furnace mean {mean}, expected {expected} (se {se})"
    );
    assert_eq!(stats.dropped, 0, "{label}");
}

/// Without paths of fewer than 3 segments (direct light, 000 Fig. 4.3) every technique sees
/// rho^2 Le (1 - rho^8) / (1 - rho) of the furnace; merge-only UPG, which cannot sample direct
/// light at all (000 sec. 5.2), sees the same.
#[test]
fn min_path_length_leaves_out_short_paths() {
    let expected = furnace_radiance(3);
    let cases = [
        (Technique::Pt, false),
        (Technique::Bpt, false),
        (Technique::Vcm, false),
        (Technique::Upg, false),
        (Technique::Upg, true),
        (Technique::UpgCamera, true),
    ];
    for (technique, no_vc) in cases {
        let o = RenderOptions {
            min_path_length: 3,
            radius: technique.merges().then_some(0.03),
            no_vc,
            ..options(technique, 32)
        };
        let label = format!("{technique} no_vc {no_vc}");
        // Merges alone are noisier than with connections beside them.
        let iterations = if no_vc { 1024 } else { 128 };
        assert_furnace(&label, &o, iterations, expected);
    }
}

/// One light sub-path per pixel is the default: saying so changes no bit.
#[test]
fn light_paths_default_to_the_pixel_count() {
    let scene = load("cornell-box");
    for technique in [Technique::Vcm, Technique::Upg] {
        let o = options(technique, 16);
        let default = render_iterations(&scene, &o, 2).unwrap();
        let explicit = RenderOptions {
            light_paths: Some(256),
            ..o
        };
        let same = render_iterations(&scene, &explicit, 2).unwrap();
        assert_eq!(default.mean(), same.mean(), "{technique}");
    }
}

/// Fewer and more light sub-paths than pixels (n_VM in the weights and the normalisation, and
/// the light tracer's count) keep the furnace right.
#[test]
fn other_light_path_counts_pass_the_furnace() {
    let expected = furnace_radiance(0);
    for technique in [Technique::Vcm, Technique::Upg, Technique::Lt] {
        for paths in [300, 3000] {
            let o = RenderOptions {
                light_paths: Some(paths),
                radius: technique.merges().then_some(0.03),
                ..options(technique, 32)
            };
            let iterations = if technique == Technique::Lt { 512 } else { 128 };
            assert_furnace(&format!("{technique} {paths}"), &o, iterations, expected);
        }
    }
}
