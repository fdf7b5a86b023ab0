//! Light tracing and bidirectional path tracing against the path tracer (issue: exact MIS,
//! cross-checked), and thread-count independence of every technique.

mod common;

use common::{assert_agree, assert_means_agree, floor_view, load, options, render_stats};
use vmerge::options::{SamplerKind, Technique};
use vmerge::render::render_iterations;

/// The furnace's radiance is exactly 1; each estimate must be within 0.5% of it, a bound the
/// test also checks is wide against the noise (the standard error must be below 0.1%).
#[test]
fn lt_and_bpt_pass_the_furnace() {
    let scene = load("furnace");
    for (technique, iterations) in [(Technique::Lt, 256), (Technique::Bpt, 256)] {
        let stats = render_stats(&scene, &options(technique, 64), iterations);
        stats.assert_furnace(&format!("{technique:?}"), 0.005, 0.001);
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
        Technique::Upg,
    ] {
        for sampler in SamplerKind::ALL {
            let mut o = options(technique, 24);
            o.seed = 5;
            o.sampler = sampler;
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
            assert!(
                same,
                "{technique:?} ({sampler:?}) depends on the thread count"
            );
        }
    }
}

/// `bpt` (000's partial sums a_i, A_i) and `vcm --no-vm` (001's d-quantities) are separate
/// implementations that draw the same random numbers for the same seed, so on every shipped
/// scene, light kind and MIS power they must give the same image up to float rounding.
#[test]
fn bpt_and_vcm_without_merging_agree_sample_by_sample() {
    for name in [
        "furnace",
        "cornell-box",
        "cornell-glossy",
        "cornell-spheres",
        "cornell-point",
        "cornell-sun",
        "cornell-sky",
        "indirect",
        "caustic",
        "corners",
    ] {
        let scene = load(name);
        for beta in [1.0, 2.0] {
            let mut o = options(Technique::Bpt, 24);
            o.seed = 11;
            o.beta = beta;
            let bpt = render_iterations(&scene, &o, 4).unwrap();
            o.technique = Technique::Vcm;
            o.no_vm = true;
            let vcm = render_iterations(&scene, &o, 4).unwrap();
            for (i, (a, b)) in bpt.sum.iter().zip(&vcm.sum).enumerate() {
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-4 * a[c].abs().max(1e-2),
                        "{name} (beta {beta}), pixel {i}: bpt {} vcm {}",
                        a[c],
                        b[c]
                    );
                }
            }
        }
    }
}

/// The weighted contributions of every (s, t) technique, rendered one at a time with
/// `--strategy`, add up to the full `bpt` image (same random numbers).
#[test]
fn strategies_add_up_to_the_full_image() {
    let scene = load("cornell-glossy");
    let mut o = options(Technique::Bpt, 16);
    o.seed = 3;
    o.max_path_length = Some(5);
    let full = render_iterations(&scene, &o, 2).unwrap();
    let mut sum = vec![[0.0f64; 3]; full.sum.len()];
    for s in 0..=6u32 {
        for t in 1..=6u32 {
            if s + t < 2 || s + t > 6 {
                continue;
            }
            o.strategy = Some([s, t]);
            let part = render_iterations(&scene, &o, 2).unwrap();
            for (acc, p) in sum.iter_mut().zip(&part.sum) {
                for c in 0..3 {
                    acc[c] += p[c];
                }
            }
        }
    }
    for (i, (a, b)) in full.sum.iter().zip(&sum).enumerate() {
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-4 * a[c].abs().max(1e-2),
                "pixel {i}: full {} vs sum of strategies {}",
                a[c],
                b[c]
            );
        }
    }
}

/// Unweighted, each technique alone estimates all paths of its length that it can sample; on
/// the Cornell box (diffuse, an area light) every technique samples every path, so the
/// techniques of one length agree with each other within noise. Hitting the light by chance
/// (s = 0) is a rare event in the dim pixels, where its per-pixel variance cannot be estimated
/// (no hit at all in thousands of samples reads as zero variance): it is compared by the image
/// mean, on paths of two segments where it is affordable; the others pixel by pixel. An
/// unweighted s, t >= 2 connection is as heavy-tailed (its 1 / d^2 in the corners), so it is
/// checked weighted, by `strategies_add_up_to_the_full_image` and the comparison with `vcm`.
#[test]
fn unweighted_techniques_of_one_length_agree() {
    let scene = load("cornell-box");
    let render = |s: u32, t: u32, iterations: u64| {
        let mut o = floor_view(Technique::Bpt, 32);
        o.seed = 100 + 10 * s as u64 + t as u64;
        o.strategy = Some([s, t]);
        o.unweighted = true;
        render_stats(&scene, &o, iterations)
    };
    let nee = render(1, 2, 1024);
    assert_means_agree("2 segments: s = 0 vs s = 1", &render(0, 3, 8192), &nee);
    assert_agree("2 segments: s = 2 vs s = 1", &render(2, 1, 2048), &nee);
    assert_agree(
        "3 segments: s = 3 vs s = 1",
        &render(3, 1, 2048),
        &render(1, 3, 1024),
    );
}
