//! Shared helpers of the statistical tests: render iteration by iteration and keep, per pixel,
//! the mean and the variance of the mean, so bounds come from the noise itself.
#![allow(dead_code)]

pub mod browser;
pub mod chi_square;
pub mod programs;

use vmerge::accel::AccelKind;
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::Technique;
use vmerge::options::{RenderOptions, SamplerKind};
use vmerge::render::create_integrator;
use vmerge::scene::{self, Camera, LoadOptions, Scene};

pub fn load(name: &str) -> Scene {
    load_file(format!(
        "{}/scenes/{name}/scene.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
}

/// The scene at `path`, loaded strictly (no `--lenient`) with shading normals, on the default
/// ray-query backend.
pub fn load_file(path: impl AsRef<std::path::Path>) -> Scene {
    let options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    };
    scene::load(path.as_ref(), &options).unwrap_or_else(|e| panic!("{e}"))
}

/// Options for a square test render. Each technique gets its own seed: renders compared with
/// each other must be independent, and equal seeds would share the eye paths' random numbers.
/// The numbers are independent ones, because [`render_stats`] takes each iteration as an
/// independent estimate; the default Sobol sampler stratifies iterations together, and
/// tests/sampler.rs checks it with [`render_stats_by_seed`].
pub fn options(technique: Technique, size: u32) -> RenderOptions {
    RenderOptions {
        technique,
        resolution: Some([size, size]),
        seed: 1000 + technique as u64,
        sampler: SamplerKind::Independent,
        ..Default::default()
    }
}

/// [`options`] through the scenes' "floor" camera, which sees no emitter directly.
pub fn floor_view(technique: Technique, size: u32) -> RenderOptions {
    RenderOptions {
        camera: Some("floor".into()),
        ..options(technique, size)
    }
}

/// Per-pixel statistics of the channel average over independent iterations.
pub struct PixelStats {
    pub mean: Vec<f64>,
    /// Variance of each pixel's mean (sample variance / iterations).
    pub var_of_mean: Vec<f64>,
    pub dropped: u64,
}

impl PixelStats {
    pub fn image_mean(&self) -> f64 {
        self.mean.iter().sum::<f64>() / self.mean.len() as f64
    }

    /// Standard error of the image mean (pixels are independent).
    pub fn image_se(&self) -> f64 {
        self.var_of_mean.iter().sum::<f64>().sqrt() / self.mean.len() as f64
    }

    /// Asserts a furnace's image, radiance 1 everywhere: the mean within `tolerance` of 1,
    /// measured with a standard error below `max_se` so that the bound is tight against the
    /// noise.
    pub fn assert_furnace(&self, label: &str, tolerance: f64, max_se: f64) {
        let (mean, se) = (self.image_mean(), self.image_se());
        assert!(se < max_se, "{label}: standard error {se}");
        assert!(
            (mean - 1.0).abs() < tolerance,
            "{label}: furnace mean {mean} (se {se})"
        );
    }

    /// The root mean square of the per-pixel differences of the means: with noise and bias
    /// both shrinking, a consistent technique's falls towards zero as its iterations grow.
    pub fn rms_difference(&self, other: &PixelStats) -> f64 {
        let sum: f64 = self
            .mean
            .iter()
            .zip(&other.mean)
            .map(|(x, y)| (x - y) * (x - y))
            .sum();
        (sum / self.mean.len() as f64).sqrt()
    }
}

/// Batches of iterations whose means give each pixel's variance. Path-traced pixels are
/// skewed (rare fireflies), which correlates a pixel's sample mean with its sample variance and
/// biases standardised differences; means of batches are far closer to normal.
const BATCHES: usize = 64;

/// Renders `iterations` iterations (a power of two, at least BATCHES) and returns each pixel's
/// mean and, from BATCHES / 2 batch means, the variance of that mean.
pub fn render_stats(scene: &Scene, options: &RenderOptions, iterations: u64) -> PixelStats {
    assert!(iterations.is_power_of_two() && iterations >= BATCHES as u64);
    assert_eq!(
        options.sampler,
        SamplerKind::Independent,
        "batches of iterations are independent only with independent numbers; a Sobol render \
         is measured over seeds (render_stats_by_seed)"
    );
    let [w, h] = options.resolution.expect("tests set a resolution");
    let camera = Camera::new(scene.camera(options.camera.as_deref()).unwrap(), w, h);
    let mut integrator = create_integrator(RenderContext {
        scene,
        camera,
        options,
    });
    let n = (w * h) as usize;
    let mut batches = vec![vec![0.0f64; n]; BATCHES];
    let mut batch_size = 1u64;
    let mut frame = vec![Rgb::BLACK; n];
    let mut dropped = 0;
    for iteration in 0..iterations {
        frame.fill(Rgb::BLACK);
        dropped += integrator
            .render_iteration(iteration, &mut frame)
            .dropped_samples;
        let batch = &mut batches[(iteration / batch_size) as usize];
        for (b, c) in batch.iter_mut().zip(&frame) {
            *b += c.average() as f64;
        }
        if iteration + 1 == BATCHES as u64 * batch_size {
            // All batches are full: halve their number by merging pairs.
            for j in 0..BATCHES / 2 {
                let merged: Vec<f64> = batches[2 * j]
                    .iter()
                    .zip(&batches[2 * j + 1])
                    .map(|(x, y)| x + y)
                    .collect();
                batches[j] = merged;
            }
            batches[BATCHES / 2..].iter_mut().for_each(|b| b.fill(0.0));
            batch_size *= 2;
        }
    }
    pixel_stats(&batches[..BATCHES / 2], batch_size, dropped)
}

/// Per-pixel statistics from BATCHES / 2 independent renders (seeds `options.seed`,
/// `options.seed + 1`, ...) of `iterations` iterations each: the batches a randomised
/// quasi-Monte Carlo render needs, since its iterations are stratified together and are not
/// independent of each other. Each batch restarts the iteration count, radius included.
pub fn render_stats_by_seed(scene: &Scene, options: &RenderOptions, iterations: u64) -> PixelStats {
    let [w, h] = options.resolution.expect("tests set a resolution");
    let n = (w * h) as usize;
    let mut frame = vec![Rgb::BLACK; n];
    let mut dropped = 0;
    let batches: Vec<Vec<f64>> = (0..(BATCHES / 2) as u64)
        .map(|k| {
            let options = RenderOptions {
                seed: options.seed + k,
                ..options.clone()
            };
            let camera = Camera::new(scene.camera(options.camera.as_deref()).unwrap(), w, h);
            let mut integrator = create_integrator(RenderContext {
                scene,
                camera,
                options: &options,
            });
            let mut batch = vec![0.0f64; n];
            for iteration in 0..iterations {
                frame.fill(Rgb::BLACK);
                dropped += integrator
                    .render_iteration(iteration, &mut frame)
                    .dropped_samples;
                for (b, c) in batch.iter_mut().zip(&frame) {
                    *b += c.average() as f64;
                }
            }
            batch
        })
        .collect();
    pixel_stats(&batches, iterations, dropped)
}

/// Mean and variance of the mean from full batches of `batch_size` iterations each.
fn pixel_stats(batches: &[Vec<f64>], batch_size: u64, dropped: u64) -> PixelStats {
    let b = batches.len() as f64;
    let n = batches[0].len();
    let mut mean = vec![0.0; n];
    let mut var_of_mean = vec![0.0; n];
    for i in 0..n {
        let means: Vec<f64> = batches
            .iter()
            .map(|batch| batch[i] / batch_size as f64)
            .collect();
        let m = means.iter().sum::<f64>() / b;
        let var = means.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (b - 1.0);
        mean[i] = m;
        var_of_mean[i] = var / b;
    }
    PixelStats {
        mean,
        var_of_mean,
        dropped,
    }
}

/// RMS over pixels of the standardised differences (a - b) / sqrt(var_a + var_b), relative
/// to its expectation when both renders estimate the same image: about 1 then, whatever each
/// pixel's noise. The variances come from BATCHES / 2 batch means, so each standardised
/// difference is t-distributed with the Welch-Satterthwaite degrees of freedom nu and has
/// E[t^2] = nu / (nu - 2), not 1; the ratio divides by that. Pixels that are exact in both
/// renders (zero variance) must agree exactly and are left out.
pub fn standardised_rms(a: &PixelStats, b: &PixelStats) -> f64 {
    let batch_dof = (BATCHES / 2 - 1) as f64;
    let (mut sum, mut expected) = (0.0, 0.0);
    for i in 0..a.mean.len() {
        let (va, vb) = (a.var_of_mean[i], b.var_of_mean[i]);
        let d = a.mean[i] - b.mean[i];
        if va + vb > 0.0 {
            let nu = batch_dof * (va + vb) * (va + vb) / (va * va + vb * vb);
            sum += d * d / (va + vb);
            expected += nu / (nu - 2.0);
        } else {
            assert!(
                d.abs() <= 1e-6 * a.mean[i].abs().max(1.0),
                "pixel {i}: exact values {} and {} differ",
                a.mean[i],
                b.mean[i]
            );
        }
    }
    (sum / expected.max(1e-300)).sqrt()
}

/// Two unbiased renders of one image agree when (1) their means differ by less than 1% or 4
/// combined standard errors, whichever is larger, where the renders are long enough that 4
/// standard errors are at most 2% of the mean (a 2% bias is always caught, 1% where the noise
/// allows), and (2) the per-pixel differences are as large as the noise predicts: the RMS of
/// the standardised difference image ([`standardised_rms`]) lies within 10% of 1. A bias in a
/// region raises it; renders that share random numbers lower it. With ~1000 pixels its own
/// noise is about 2.5%.
pub fn assert_agree(label: &str, a: &PixelStats, b: &PixelStats) {
    assert_means_agree(label, a, b);
    let ratio = standardised_rms(a, b);
    assert!(
        (0.9..=1.1).contains(&ratio),
        "{label}: RMS of the standardised difference = {ratio}"
    );
}

/// Part (1) of [`assert_agree`] alone: for estimators whose per-pixel variance cannot be
/// estimated (a pixel whose rare bright samples never came shows zero variance).
pub fn assert_means_agree(label: &str, a: &PixelStats, b: &PixelStats) {
    let (ma, mb) = (a.image_mean(), b.image_mean());
    let se = (a.image_se().powi(2) + b.image_se().powi(2)).sqrt();
    assert!(
        4.0 * se <= 0.02 * mb.abs(),
        "{label}: too noisy to see a 2% bias (se {se}, mean {mb})"
    );
    let tolerance = (0.01 * mb.abs()).max(4.0 * se);
    assert!(
        (ma - mb).abs() <= tolerance,
        "{label}: means {ma} and {mb} differ by more than {tolerance} (se {se})"
    );
}
