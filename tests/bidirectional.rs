//! Light tracing and bidirectional path tracing against the path tracer (issue: exact MIS,
//! cross-checked), and thread-count independence of every technique.

mod common;

use common::{assert_agree, floor_view, load, options, render_stats};
use vmerge::integrator::Technique;
use vmerge::render::render_iterations;

/// The furnace's radiance is exactly 1; each estimate must be within 0.5% of it, a bound the
/// test also checks is wide against the noise (the standard error must be below 0.1%).
#[test]
fn lt_and_bpt_pass_the_furnace() {
    let scene = load("furnace");
    for (technique, iterations) in [(Technique::Lt, 256), (Technique::Bpt, 256)] {
        let stats = render_stats(&scene, &options(technique, 64), iterations);
        let (mean, se) = (stats.image_mean(), stats.image_se());
        assert!(se < 0.001, "{technique:?}: standard error {se}");
        assert!(
            (mean - 1.0).abs() < 0.005,
            "{technique:?}: furnace mean {mean} (se {se})"
        );
        assert_eq!(stats.dropped, 0);
    }
}

/// Renders each technique on the scene's floor view for a fixed number of iterations (never
/// "until the noise is low": stopping on a low variance estimate picks the runs that missed
/// their rare bright samples, a bias towards dark images).
fn floor_renders(name: &str, techniques: &[Technique]) -> Vec<common::PixelStats> {
    let scene = load(name);
    techniques
        .iter()
        .map(|&t| {
            let iterations = match t {
                Technique::Bpt => 2048,
                Technique::Lt => 8192,
                _ => 4096,
            };
            render_stats(&scene, &floor_view(t, 32), iterations)
        })
        .collect()
}

#[test]
fn pt_lt_and_bpt_agree_on_the_cornell_scenes() {
    for name in [
        "cornell-box",
        "cornell-glossy",
        "cornell-point",
        "cornell-sun",
        "cornell-sky",
    ] {
        let r = floor_renders(name, &[Technique::Pt, Technique::Bpt, Technique::Lt]);
        assert_agree(&format!("{name}: bpt vs pt"), &r[1], &r[0]);
        assert_agree(&format!("{name}: lt vs pt"), &r[2], &r[0]);
        assert_agree(&format!("{name}: lt vs bpt"), &r[2], &r[1]);
    }
}

/// Every technique gives a bit-identical image with one thread and with several.
#[test]
fn every_technique_is_independent_of_the_thread_count() {
    let scene = load("cornell-spheres");
    for technique in [
        Technique::Pt,
        Technique::Lt,
        Technique::Bpt,
        Technique::Ppm,
        Technique::Bpm,
        Technique::Vcm,
    ] {
        let mut o = options(technique, 24);
        o.seed = 5;
        let render = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| render_iterations(&scene, &o, 2).unwrap())
        };
        let (one, many) = (render(1), render(3));
        let same = one
            .sum
            .iter()
            .zip(&many.sum)
            .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits));
        assert!(same, "{technique:?} depends on the thread count");
    }
}
