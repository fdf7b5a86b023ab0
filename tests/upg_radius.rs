//! UPG's image does not depend on its radius (000 sec. 2.4.6): on `indirect`, whose room is 2
//! units wide with a partition 0.06 thick, a radius of 0.26 makes the r-sphere reach across the
//! partition, into the corners and onto the light, and its merges carry much of the weight;
//! at 0.01 they carry almost none. The two renders share their random numbers (one seed), so
//! the difference of their image means is far less noisy than either against bpt: a bias that
//! grows with the radius (an angular bound too narrow or too wide for large cones, successes
//! counted that no stored light vertex can realise, merges dropped) shows at well under 1%.
//! The same holds with smooth coatings on the walls, whose mirror lobe the tentative rays must
//! leave out where the merges it would reach are not gathered.

mod common;

use common::{load, options};
use vmerge::accel::AccelKind;
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::{RenderOptions, Technique};
use vmerge::render::create_integrator;
use vmerge::scene::{self, Camera, LoadOptions, Scene};

/// Batches of iterations whose means give the standard error: iterations are independent, but
/// single ones are skewed (rare bright merges), batch means far less.
const BATCHES: usize = 64;
const SIZE: u32 = 16;

/// Iterations per render: `upg-camera`'s merges at r 0.26 are noisier than `upg`'s.
fn iterations(technique: Technique) -> u64 {
    match technique {
        Technique::UpgCamera => 3072,
        _ => 2048,
    }
}

/// The image mean of each iteration, and the samples dropped as non-finite.
fn iteration_means(scene: &Scene, o: &RenderOptions) -> (Vec<f64>, u64) {
    let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), SIZE, SIZE);
    let mut integrator = create_integrator(RenderContext {
        scene,
        camera,
        options: o,
    });
    let mut frame = vec![Rgb::BLACK; (SIZE * SIZE) as usize];
    let mut dropped = 0;
    let means = (0..iterations(o.technique))
        .map(|iteration| {
            frame.fill(Rgb::BLACK);
            dropped += integrator
                .render_iteration(iteration, &mut frame)
                .dropped_samples;
            frame.iter().map(|c| c.average() as f64).sum::<f64>() / frame.len() as f64
        })
        .collect();
    (means, dropped)
}

/// Mean and standard error of the mean from BATCHES batch means.
fn mean_and_se(values: &[f64]) -> (f64, f64) {
    let batch_means: Vec<f64> = values
        .chunks(values.len() / BATCHES)
        .map(|batch| batch.iter().sum::<f64>() / batch.len() as f64)
        .collect();
    let b = batch_means.len() as f64;
    let mean = batch_means.iter().sum::<f64>() / b;
    let var = batch_means.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (b - 1.0);
    (mean, (var / b).sqrt())
}

/// The image at radius `large` less the image at 0.01, rendered with one seed: (the image mean
/// at 0.01, the difference, its standard error). Asserts that no sample is dropped and that 4
/// standard errors are at most 1% of the image.
fn paired_difference(scene: &Scene, technique: Technique, large: f32) -> (f64, f64, f64) {
    let render = |radius: f32| {
        let o = RenderOptions {
            radius: Some(radius),
            ..options(technique, SIZE)
        };
        let (means, dropped) = iteration_means(scene, &o);
        assert_eq!(dropped, 0, "{technique:?} r {radius}: samples dropped");
        means
    };
    let small = render(0.01);
    let difference: Vec<f64> = render(large)
        .iter()
        .zip(&small)
        .map(|(l, s)| l - s)
        .collect();
    let (mean, _) = mean_and_se(&small);
    let (d, se) = mean_and_se(&difference);
    println!(
        "{technique:?}: r {large} - r 0.01 = {d:+.5} (se {se:.5}, {:+.3}% of {mean:.5})",
        100.0 * d / mean
    );
    assert!(
        4.0 * se <= 0.01 * mean,
        "{technique:?}: too noisy to see a 1% bias (se {se}, mean {mean})"
    );
    (mean, d, se)
}

/// At radii 0.01 and 0.26, with the same seed, `upg` and `upg-camera` give image means that
/// differ by less than 4 standard errors of the paired difference (a 1% bias shows).
#[test]
fn upg_image_does_not_depend_on_the_radius() {
    let scene = load("indirect");
    for technique in [Technique::Upg, Technique::UpgCamera] {
        let (_, d, se) = paired_difference(&scene, technique, 0.26);
        assert!(
            d.abs() <= 4.0 * se,
            "{technique:?}: the image at r 0.26 differs from r 0.01's by {d} (se {se})"
        );
    }
}

/// `indirect` with its white surfaces under a smooth coating (a mirror lobe over a diffuse
/// base): light vertices reached through the mirror are not merged by `upg`, so its tentative
/// rays must not count the mirror's successes either. Counting them read the image at r 0.3
/// 1.2% dark (10 standard errors).
#[test]
fn upg_is_unbiased_next_to_smooth_coatings() {
    let dir = std::env::temp_dir().join(format!("vmerge-upg-radius-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    let mesh = format!(
        "{}/scenes/indirect/indirect.obj",
        env!("CARGO_MANIFEST_DIR")
    );
    std::fs::write(
        &path,
        format!(
            "[render]\nmax_path_length = 10\n\
             [[camera]]\nposition = [0.0, 1.0, 3.4]\nlook_at = [0.0, 1.0, 0.0]\n\
             up = [0.0, 1.0, 0.0]\nfov = 40.0\n\
             [[mesh]]\nfile = {mesh:?}\n\
             [material.white]\ntype = \"coateddiffuse\"\nreflectance = [0.75, 0.75, 0.75]\n\
             roughness = 0.0\n"
        ),
    )
    .unwrap();
    let load_options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    };
    let scene = scene::load(&path, &load_options);
    std::fs::remove_dir_all(&dir).unwrap();
    let scene = scene.unwrap_or_else(|e| panic!("{e}"));
    let (_, d, se) = paired_difference(&scene, Technique::Upg, 0.3);
    assert!(
        d.abs() <= 4.0 * se,
        "the image at r 0.3 differs from r 0.01's by {d} (se {se})"
    );
}
