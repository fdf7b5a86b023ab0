//! The default Sobol sampler against independent numbers: the same images (no bias), less
//! noise, and the furnace's exact 1 (tests/bidirectional.rs checks that its images do not
//! depend on the thread count).
//!
//! A Sobol render's iterations are stratified together, so its noise is measured over
//! independent seeds ([`render_stats_by_seed`]); the independent renders it is compared with are
//! measured the same way, so both follow the same radius schedule.

mod common;

use common::{assert_agree, floor_view, load, options, render_stats_by_seed, PixelStats};
use vmerge::options::{RenderOptions, SamplerKind, Technique};

fn with(sampler: SamplerKind, options: RenderOptions) -> RenderOptions {
    RenderOptions { sampler, ..options }
}

/// Sobol and independent renders of one view, each over BATCHES / 2 seeds.
fn both(scene: &str, options: &RenderOptions, iterations: u64) -> [PixelStats; 2] {
    let scene = load(scene);
    [SamplerKind::Sobol, SamplerKind::Independent].map(|sampler| {
        let mut o = with(sampler, options.clone());
        // Different seed ranges: equal seeds would not make the two renders dependent (the
        // samplers draw differently), but distinct ones make it obvious.
        o.seed += if sampler == SamplerKind::Sobol {
            0
        } else {
            500
        };
        render_stats_by_seed(&scene, &o, iterations)
    })
}

#[test]
fn sobol_renders_agree_with_independent_ones() {
    for (scene, technique, iterations) in [
        ("cornell-box", Technique::Pt, 16),
        ("cornell-glossy", Technique::Pt, 16),
        ("cornell-glossy", Technique::Bpt, 16),
        ("cornell-box", Technique::Lt, 32),
        ("cornell-glossy", Technique::Vcm, 16),
        ("cornell-box", Technique::Ppm, 16),
        ("cornell-glossy", Technique::Bpm, 32),
        ("cornell-glossy", Technique::Upg, 8),
    ] {
        let mut o = floor_view(technique, 32);
        if technique.merges() {
            // 16 light paths per pixel: the 1024 of one per pixel leave ppm too noisy to see
            // a 2% bias.
            o.light_paths = Some(1 << 14);
        }
        let [sobol, independent] = both(scene, &o, iterations);
        assert_agree(
            &format!("{scene} {technique}: sobol vs independent"),
            &sobol,
            &independent,
        );
    }
}

/// Mean over pixels of the variance of a pixel's mean.
fn mean_variance(stats: &PixelStats) -> f64 {
    stats.var_of_mean.iter().sum::<f64>() / stats.var_of_mean.len() as f64
}

/// Stratified light points, BSDF directions and photons: less noise per iteration. Each
/// variance is estimated from 32 seeds (relative standard error about 25% per pixel, under 2%
/// over the image's 1024 pixels), so a ratio below 0.8 is not noise.
#[test]
fn sobol_is_less_noisy_than_independent_numbers() {
    for (scene, technique) in [
        ("cornell-box", Technique::Pt),
        ("cornell-box", Technique::Ppm),
        ("cornell-glossy", Technique::Vcm),
    ] {
        let [sobol, independent] = both(scene, &options(technique, 32), 16);
        let ratio = mean_variance(&sobol) / mean_variance(&independent);
        eprintln!("{scene} {technique}: Sobol's variance / independent numbers' = {ratio:.3}");
        assert!(ratio < 0.8, "{scene} {technique}: variance ratio {ratio}");
    }
}

/// The furnace's radiance is exactly 1 (000 sec. 3.5); each technique's Sobol estimate must be
/// within 0.5% of it, with a standard error below 0.1% so that the bound is wide.
#[test]
fn sobol_passes_the_furnace() {
    let scene = load("furnace");
    for (technique, iterations) in [
        (Technique::Pt, 8),
        (Technique::Bpt, 8),
        (Technique::Lt, 32),
        (Technique::Vcm, 8),
    ] {
        let o = with(SamplerKind::Sobol, options(technique, 32));
        let stats = render_stats_by_seed(&scene, &o, iterations);
        stats.assert_furnace(&format!("{technique}"), 0.005, 0.001);
    }
}
