//! `vcm-upg`, VCM whose merges near corners and edges are made by unbiased photon gathering:
//! it passes the furnace, converges to `bpt` as its radius shrinks as `vcm` does, and at a fixed
//! radius its bias in the corners of `corners` is far below `vcm`'s.

mod common;

use common::{floor_view, load, options, render_stats, PixelStats};
use glam::Vec3;
use vmerge::accel::Ray;
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::{RenderOptions, Technique};
use vmerge::render::create_integrator;
use vmerge::scene::{Camera, Scene};

/// Radiance 1 everywhere, within 1%, with a standard error below 0.2%: at vcm's furnace radius
/// (1.5% of the box's side), and at 10%, where UPG makes the merges along the edges.
#[test]
fn vcm_upg_passes_the_furnace() {
    let scene = load("furnace");
    for radius in [0.03, 0.2] {
        let mut o = options(Technique::VcmUpg, 48);
        o.radius = Some(radius);
        let stats = render_stats(&scene, &o, 128);
        stats.assert_furnace(&format!("r {radius}"), 0.01, 0.002);
        assert_eq!(stats.dropped, 0);
    }
}

/// vcm-upg with a shrinking radius (alpha = 0.75) approaches bpt's image, with tests/vcm.rs's
/// statistic: the image mean within 1% of it, and the RMS difference falling as iterations grow.
/// The first radius is 5% of the box, so that merges carry much of the image and the ramp
/// reaches across it. The spheres' mirror and glass put delta vertices next to merges, whose
/// terms the eye sub-paths carry across them.
#[test]
fn vcm_upg_converges_to_bpt() {
    let scene = load("cornell-spheres");
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
    let mut o = floor_view(Technique::VcmUpg, 32);
    o.radius = Some(0.1);
    let short = render_stats(&scene, &o, 64);
    let long = render_stats(&scene, &o, 1024);
    let (m, r) = (long.image_mean(), bpt.image_mean());
    assert!((m - r).abs() < 0.01 * r, "vcm-upg mean {m}, bpt {r}");
    let (early, late) = (short.rms_difference(&bpt), long.rms_difference(&bpt));
    assert!(late < 0.5 * early, "RMS difference {early} -> {late}");
}

/// The pixels whose primary hit (through the pixel's centre) has another surface within
/// `reach`: probes along the 26 directions of a cube's faces, edges and corners, on the
/// surface's side.
fn corner_pixels(scene: &Scene, o: &RenderOptions, reach: f32) -> Vec<bool> {
    let [w, h] = o.resolution.expect("tests set a resolution");
    let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), w, h);
    let probes: Vec<Vec3> = (0..27)
        .map(|k| Vec3::new((k % 3) as f32, (k / 3 % 3) as f32, (k / 9) as f32) - 1.0)
        .filter(|d| *d != Vec3::ZERO)
        .map(Vec3::normalize)
        .collect();
    (0..w * h)
        .map(|i| {
            let ray = camera.generate_ray((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let Some(x) = scene.intersect(&ray) else {
                return false;
            };
            let facing = if x.ng.dot(ray.dir) < 0.0 { x.ng } else { -x.ng };
            probes.iter().filter(|d| d.dot(facing) > 0.0).any(|&d| {
                scene
                    .intersect(&Ray::spawn(x.position, x.ng, d))
                    .is_some_and(|hit| hit.hit.t < reach)
            })
        })
        .collect()
}

/// Over the pixels `keep`, an estimate of the summed squared bias of `a` against the unbiased
/// `reference`, sum of (a - ref)^2 - var_a - var_ref, and its standard deviation (from the
/// normal approximation: Var[e^2] = 4 mu^2 s^2 + 2 s^4 with mu^2 taken as e^2).
fn squared_bias(a: &PixelStats, reference: &PixelStats, keep: &[bool]) -> (f64, f64) {
    let (mut sum, mut var) = (0.0, 0.0);
    for i in (0..a.mean.len()).filter(|&i| keep[i]) {
        let e = a.mean[i] - reference.mean[i];
        let s2 = a.var_of_mean[i] + reference.var_of_mean[i];
        sum += e * e - s2;
        var += 4.0 * e * e * s2 + 2.0 * s2 * s2;
    }
    (sum, var.sqrt())
}

/// `corners` at a fixed radius of 0.15 (alpha = 1), where vcm's density estimates reach across
/// its acute corners: over the pixels within two radii of another surface, vcm-upg's squared
/// bias against bpt lies below vcm's by more than 4 standard deviations of the two estimates
/// together (their sum bounds the difference's whatever their correlation through the shared
/// reference), and below a fifth of vcm's.
#[test]
fn vcm_upg_removes_vcm_bias_in_acute_corners() {
    let scene = load("corners");
    let radius = 0.15;
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 24), 2048);
    let biased = |technique| {
        let mut o = floor_view(technique, 24);
        o.radius = Some(radius);
        o.alpha = Some(1.0);
        render_stats(&scene, &o, 1024)
    };
    let corners = corner_pixels(&scene, &floor_view(Technique::Bpt, 24), 2.0 * radius);
    let count = corners.iter().filter(|&&c| c).count();
    assert!(
        (50..400).contains(&count),
        "{count} corner pixels of {}",
        corners.len()
    );
    let (vcm, vcm_sd) = squared_bias(&biased(Technique::Vcm), &bpt, &corners);
    let (blend, blend_sd) = squared_bias(&biased(Technique::VcmUpg), &bpt, &corners);
    assert!(
        vcm - blend > 4.0 * (vcm_sd + blend_sd) && blend < 0.2 * vcm,
        "squared bias in {count} corner pixels: vcm {vcm} (sd {vcm_sd}), vcm-upg {blend} \
         (sd {blend_sd})"
    );
}

/// The metadata tell how the merges were made: UPG's statistics, and the share of merges UPG
/// made, between 0 and 1 on `corners` at a radius whose ramp reaches across the room.
#[test]
fn statistics_report_the_share_of_merges_upg_made() {
    let scene = load("corners");
    let mut o = floor_view(Technique::VcmUpg, 16);
    o.radius = Some(0.1);
    let [w, h] = o.resolution.unwrap();
    let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), w, h);
    let mut integrator = create_integrator(RenderContext {
        scene: &scene,
        camera,
        options: &o,
    });
    let mut frame = vec![Rgb::BLACK; (w * h) as usize];
    integrator.render_iteration(0, &mut frame);
    let stats = integrator.statistics(std::time::Duration::from_secs(1));
    let get = |name: &str| {
        stats
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no {name} in {stats:?}"))
            .1
            .parse::<f64>()
            .unwrap()
    };
    let share = get("blend_upg_merge_share");
    assert!(share > 0.0 && share < 1.0, "share {share}");
    assert!(get("upg_trials_per_merge") >= 1.0);
    assert!(get("blend_density_merges") > 0.0);
}
