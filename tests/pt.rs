//! The path tracer: the furnace test (000 sec. 3.5), thread-count independence and its camera
//! packets.

use vmerge::accel::AccelKind;
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::Technique;
use vmerge::options::{RenderOptions, SamplerKind};
use vmerge::render::create_integrator;
use vmerge::render::render_iterations;
use vmerge::scene::{self, Camera, LoadOptions, Scene};

fn load(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}/scene.toml", env!("CARGO_MANIFEST_DIR"));
    let options = LoadOptions {
        accel: AccelKind::Bvh,
        lenient: false,
        shading_normals: true,
    };
    match scene::load(path.as_ref(), &options) {
        Ok(scene) => scene,
        Err(e) => panic!("{e}"),
    }
}

/// The closed furnace (six walls emitting Le = 0.5 with albedo 0.5) has radiance
/// Le / (1 - rho) = 1 everywhere.
#[test]
fn furnace_is_one_everywhere() {
    let scene = load("furnace");
    let (width, height, iterations) = (64u32, 64u32, 64u64);
    let options = RenderOptions {
        technique: Technique::Pt,
        resolution: Some([width, height]),
        // Each iteration an independent estimate, as the variances below take it.
        sampler: SamplerKind::Independent,
        ..Default::default()
    };
    let camera = Camera::new(scene.camera(None).unwrap(), width, height);
    let mut pt = create_integrator(RenderContext {
        scene: &scene,
        camera,
        options: &options,
    });
    let n = (width * height) as usize;
    let mut sum = vec![0.0f64; n];
    let mut sum_sq = vec![0.0f64; n];
    let mut frame = vec![Rgb::BLACK; n];
    for iteration in 0..iterations {
        frame.fill(Rgb::BLACK);
        let stats = pt.render_iteration(iteration, &mut frame);
        assert_eq!(stats.dropped_samples, 0);
        for (i, c) in frame.iter().enumerate() {
            let v = c.average() as f64;
            sum[i] += v;
            sum_sq[i] += v * v;
        }
    }
    let k = iterations as f64;
    let means: Vec<f64> = sum.iter().map(|s| s / k).collect();
    // Variance of each pixel's mean, from its own samples (unbiased sample variance / k).
    let var_of_mean: Vec<f64> = sum_sq
        .iter()
        .zip(&means)
        .map(|(s2, m)| (s2 / k - m * m) * k / (k - 1.0) / k)
        .collect();
    let image_mean = means.iter().sum::<f64>() / n as f64;
    let image_se = (var_of_mean.iter().sum::<f64>()).sqrt() / n as f64;
    // The bound asked of it is 0.5%; it must also be well outside the noise for the test to mean
    // anything, so check the standard error is small against it.
    assert!(
        image_se < 0.001,
        "standard error of the image mean {image_se} too large"
    );
    assert!(
        (image_mean - 1.0).abs() < 0.005,
        "furnace mean {image_mean} (se {image_se})"
    );
    // Per pixel: |mean - 1| within 6 estimated standard errors. For a normal mean, 4096 pixels
    // exceed 5 sigma with probability 4096 * 5.7e-7 = 0.2%; the extra sigma covers the error of
    // estimating each pixel's variance from 64 samples. A pixel with zero variance must be exact.
    for (i, (m, v)) in means.iter().zip(&var_of_mean).enumerate() {
        let bound = 6.0 * v.sqrt() + 1e-6;
        assert!(
            (m - 1.0).abs() <= bound,
            "pixel {i}: {m} off by more than {bound}"
        );
    }
}

/// The same seed gives a bit-identical image with one thread and with several.
#[test]
fn one_thread_and_many_threads_agree_bitwise() {
    let scene = load("cornell-box");
    let options = RenderOptions {
        resolution: Some([48, 40]),
        seed: 7,
        ..Default::default()
    };
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| render_iterations(&scene, &options, 3).unwrap())
    };
    let one = render(1);
    let many = render(4);
    assert!(one
        .sum
        .iter()
        .zip(&many.sum)
        .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits)));
    assert!(one.average()[0] > 0.0);
}

/// The camera rays `pt` traces as packets are those of one ray at a time: each lane's ray is the
/// one its pixel's own sampler makes, and its first hit the one a single query finds, for full
/// packets and for the short one that ends a row of 13 pixels.
#[test]
fn camera_packets_are_single_rays() {
    use vmerge::accel::PACKET;
    use vmerge::integrator::camera_rays::CameraRays;
    use vmerge::sampling::Sampler;
    let path = format!(
        "{}/scenes/cornell-box/scene.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let (width, height) = (13u32, 9u32);
    for accel in [AccelKind::default_kind(), AccelKind::Bvh] {
        let options = LoadOptions {
            accel,
            lenient: false,
            shading_normals: true,
        };
        let scene = scene::load(path.as_ref(), &options).unwrap_or_else(|e| panic!("{e}"));
        for sampler in [SamplerKind::Sobol, SamplerKind::Independent] {
            let options = RenderOptions {
                technique: Technique::Pt,
                resolution: Some([width, height]),
                sampler,
                ..Default::default()
            };
            let camera = Camera::new(scene.camera(None).unwrap(), width, height);
            let ctx = RenderContext {
                scene: &scene,
                camera,
                options: &options,
            };
            let (mut lanes, mut hits) = (0, 0);
            for y in 0..height as usize {
                for start in (0..width as usize).step_by(PACKET) {
                    let len = PACKET.min(width as usize - start);
                    let first = y * width as usize + start;
                    let mut packet = CameraRays::trace(&ctx, 3, first, len);
                    for lane in 0..len {
                        let mut single = Sampler::eye(sampler, 0, 3, (first + lane) as u64);
                        let [jx, jy] = single.next_2d();
                        let x = (start + lane) as f32 + jx;
                        let ray = ctx.camera.generate_ray(x, y as f32 + jy);
                        assert_eq!(packet.rays[lane], ray, "pixel {}", first + lane);
                        // The samplers go on as the single ray's would.
                        assert_eq!(packet.samplers[lane].next_2d(), single.next_2d());
                        let expected = scene.intersect(&ray).map(|h| (h.hit, h.position));
                        let found = packet.first_hit(&ctx, lane).map(|h| (h.hit, h.position));
                        assert_eq!(found, expected, "{accel:?}, pixel {}", first + lane);
                        lanes += 1;
                        hits += usize::from(found.is_some());
                    }
                }
            }
            assert_eq!(lanes, (width * height) as usize);
            assert!(
                hits > lanes / 2,
                "the box fills the view: {hits} of {lanes} hit"
            );
        }
    }
}
