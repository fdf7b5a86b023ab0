//! Spot lights and two-sided area lights: a spot light's image against its direct illumination
//! computed in closed form, every technique on a box lit by a spot light, and two-sided
//! emitters in the furnace, seen from both sides.

mod common;

use common::{assert_agree, load_file, options, render_stats, PixelStats};
use glam::Vec3;
use std::f64::consts::PI;
use std::path::Path;
use vmerge::light::{Light, SpotCone};
use vmerge::options::{RenderOptions, Technique};
use vmerge::scene::{Camera, Scene};

/// A scene of tests/fixtures/lights.
fn fixture(name: &str) -> Scene {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/lights");
    load_file(dir.join(name).join("scene.toml"))
}

/// The spot light of the plane test, in the scene file's terms.
struct Spot {
    position: Vec3,
    look_at: Vec3,
    intensity: f64,
    cone_angle: f64,
    cone_delta: f64,
}

impl Spot {
    /// Radiance reflected towards anything by the lambertian plane y = 0 of albedo `kd` at
    /// `x`: kd / pi times the irradiance I s(cos) cos_plane / d^2, where s is pbrt-v4's
    /// smoothstep between the cosines of the cone angle and of the angle where the falloff
    /// starts.
    fn reflected(&self, x: Vec3, kd: f64) -> f64 {
        let to_light = (self.position - x).as_dvec3();
        let dist2 = to_light.length_squared();
        let cos_plane = to_light.y / dist2.sqrt();
        kd / PI * self.intensity * self.falloff(x) * cos_plane.max(0.0) / dist2
    }

    /// The intensity's fraction towards `x`.
    fn falloff(&self, x: Vec3) -> f64 {
        let dir = (x - self.position).as_dvec3().normalize();
        let axis = (self.look_at - self.position).as_dvec3().normalize();
        let (a, b) = (
            self.cone_angle.to_radians().cos(),
            (self.cone_angle - self.cone_delta).to_radians().cos(),
        );
        let t = ((dir.dot(axis) - a) / (b - a)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }
}

/// Where a camera ray meets the plane y = 0.
fn on_floor(camera: &Camera, x: f32, y: f32) -> Vec3 {
    let ray = camera.generate_ray(x, y);
    ray.origin - ray.dir * (ray.origin.y / ray.dir.y)
}

/// A lambertian floor seen from above, lit by a tilted spot light whose whole cone (full part,
/// falloff and the dark beyond) lies in view: pt's image against each pixel's mean of the
/// closed form (a 16 x 16 midpoint rule over the pixel). The only noise is the pixel jitter,
/// so the bound is 4 standard errors plus 0.2% of the pixel and 0.1% of the brightest pixel
/// (the quadrature's error is far below both; a pixel the cone's edge barely touches is lit
/// by too few of its samples for their spread to be seen): a 1% error of the intensity or any
/// visible change of the falloff's shape fails it, as does 0.2% over the whole image.
#[test]
fn a_spot_light_gives_its_direct_illumination_on_a_plane() {
    let spot = Spot {
        position: Vec3::new(-0.1, 1.0, 0.05),
        look_at: Vec3::new(0.25, 0.0, 0.1),
        intensity: 3.0,
        cone_angle: 30.0,
        cone_delta: 12.0,
    };
    let kd = 0.5;
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("floor.obj"),
        "v -4 0 -4\nv -4 0 4\nv 4 0 4\nv 4 0 -4\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let [p, l] = [spot.position, spot.look_at].map(|v| v.to_array());
    let toml = format!(
        "[[camera]]\nposition = [0.0, 2.5, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 0.0, -1.0]\n\
         fov = 70.0\n\n[[mesh]]\nfile = \"floor.obj\"\nmaterial = \"floor\"\n\n\
         [material.floor]\ntype = \"lambert\"\nkd = [{kd}, {kd}, {kd}]\n\n\
         [[light]]\ntype = \"spot\"\nposition = {p:?}\nlook_at = {l:?}\n\
         intensity = [{i}, {i}, {i}]\ncone_angle = {a:.1}\ncone_delta = {d:.1}\n",
        i = spot.intensity,
        a = spot.cone_angle,
        d = spot.cone_delta,
    );
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    let scene = load_file(&path);
    let size = 32;
    let stats = render_stats(&scene, &options(Technique::Pt, size), 64);
    let camera = Camera::new(scene.camera(None).unwrap(), size, size);
    const SUB: u32 = 16;
    let expected: Vec<f64> = (0..size * size)
        .map(|k| {
            let (px, py) = ((k % size) as f32, (k / size) as f32);
            let mut sum = 0.0;
            for j in 0..SUB {
                for i in 0..SUB {
                    let x = px + (i as f32 + 0.5) / SUB as f32;
                    let y = py + (j as f32 + 0.5) / SUB as f32;
                    sum += spot.reflected(on_floor(&camera, x, y), kd);
                }
            }
            sum / (SUB * SUB) as f64
        })
        .collect();
    let brightest = expected.iter().cloned().fold(0.0, f64::max);
    let (mut lit, mut ring, mut dark) = (0, 0, 0);
    let (mut sum, mut expected_sum) = (0.0, 0.0);
    for py in 0..size {
        for px in 0..size {
            let k = (py * size + px) as usize;
            let (m, se, expected) = (stats.mean[k], stats.var_of_mean[k].sqrt(), expected[k]);
            assert!(
                (m - expected).abs() <= 4.0 * se + 0.002 * expected + 0.001 * brightest,
                "pixel ({px}, {py}): {m} (se {se}), closed form {expected}"
            );
            match spot.falloff(on_floor(&camera, px as f32 + 0.5, py as f32 + 0.5)) {
                f if f >= 1.0 => lit += 1,
                f if f > 0.0 => ring += 1,
                _ => dark += 1,
            }
            sum += m;
            expected_sum += expected;
        }
    }
    assert!(
        (sum - expected_sum).abs() <= 0.002 * expected_sum,
        "image sum {sum}, closed form {expected_sum}"
    );
    assert!(
        lit > 20 && ring > 20 && dark > 20,
        "pixels in the full cone {lit}, in the falloff {ring}, outside {dark}"
    );
    assert_eq!(stats.dropped, 0);
}

/// Every technique renders the same image of a box lit by a spot light (its floor view, away
/// from the light, where the falloff crosses the floor): the statistic of the other
/// cross-technique tests, each against pt.
#[test]
fn every_technique_agrees_under_a_spot_light() {
    let scene = fixture("spot");
    let view = |technique| RenderOptions {
        camera: Some("floor".into()),
        ..options(technique, 24)
    };
    let pt = render_stats(&scene, &view(Technique::Pt), 2048);
    for (technique, iterations) in [
        (Technique::Lt, 4096),
        (Technique::Bpt, 1024),
        (Technique::Vcm, 1024),
        (Technique::Upg, 1024),
        (Technique::UpgCamera, 1024),
    ] {
        let stats = render_stats(&scene, &view(technique), iterations);
        assert_agree(&format!("spot: {technique:?} vs pt"), &stats, &pt);
        assert_eq!(stats.dropped, 0);
    }
}

/// Mean and standard error over the pixels `mask` selects.
fn region(stats: &PixelStats, mask: &[bool]) -> (f64, f64) {
    let n = mask.iter().filter(|&&m| m).count() as f64;
    let (mut sum, mut var) = (0.0, 0.0);
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        sum += stats.mean[i];
        var += stats.var_of_mean[i];
    }
    (sum / n, var.sqrt() / n)
}

/// The furnace with two two-sided panels that emit and reflect like its walls: the radiance
/// is the same everywhere, on both sides of each panel, so every technique must give it over
/// the whole image (within 0.5% or 4 standard errors, with a standard error small enough,
/// 0.25%, that a 1% bias fails) and over the pixels that see the front of the left panel and
/// the back of the right one, where a one-sided emitter would be half as bright (within 1% or
/// 4 standard errors, the standard error below 0.5%).
#[test]
fn two_sided_emitters_pass_the_furnace_from_both_sides() {
    let scene = fixture("twosided");
    let size = 24;
    let camera = Camera::new(scene.camera(None).unwrap(), size, size);
    // The panels' rectangles, at z = -0.3 and -0.4 (panels.obj); a pixel counts when its four
    // corners all land on one.
    let on_panel = |x: f32, y: f32, left: bool| {
        let ray = camera.generate_ray(x, y);
        let z = if left { -0.3 } else { -0.4 };
        let p = ray.origin + ray.dir * ((z - ray.origin.z) / ray.dir.z);
        let (x0, x1) = if left { (-0.7, -0.05) } else { (0.05, 0.7) };
        p.x > x0 && p.x < x1 && p.y.abs() < 0.4
    };
    let mask = |left: bool| -> Vec<bool> {
        (0..size * size)
            .map(|k| {
                let (x, y) = ((k % size) as f32, (k / size) as f32);
                [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                    .iter()
                    .all(|(dx, dy)| on_panel(x + dx, y + dy, left))
            })
            .collect()
    };
    let (front, back) = (mask(true), mask(false));
    assert!(front.iter().filter(|&&m| m).count() > 20);
    assert!(back.iter().filter(|&&m| m).count() > 20);
    let (le, rho) = (0.5f64, 0.5f64);
    let max_length = scene.defaults.max_path_length as i32;
    let expected = le * (1.0 - rho.powi(max_length)) / (1.0 - rho);
    for (technique, iterations) in [
        (Technique::Pt, 128),
        (Technique::Lt, 512),
        (Technique::Bpt, 128),
        (Technique::Vcm, 128),
        (Technique::Upg, 128),
        (Technique::UpgCamera, 128),
    ] {
        let stats = render_stats(&scene, &options(technique, size), iterations);
        let all = vec![true; (size * size) as usize];
        for (what, m, bound) in [
            ("image", &all, 0.005),
            ("front", &front, 0.01),
            ("back", &back, 0.01),
        ] {
            let (mean, se) = region(&stats, m);
            assert!(
                se < 0.5 * bound * expected,
                "{technique:?} {what}: standard error {se}"
            );
            let tolerance = (bound * expected).max(4.0 * se);
            assert!(
                (mean - expected).abs() <= tolerance,
                "{technique:?} {what}: {mean} (se {se}), expected {expected}"
            );
        }
        assert_eq!(stats.dropped, 0);
    }
}

/// pbrt-v4's spot light and two-sided area light as the importer builds them: position, axis
/// and cone from `from`, `to`, `coneangle` and `conedeltaangle` under the transform; `I` times
/// `scale`, or `power` over the falloff's solid angle 2 pi ((1 - cos_start) + (cos_start -
/// cos_end) / 2); `twosided` on the emitters, doubling their power.
#[test]
fn pbrt_spot_and_two_sided_lights_import_as_pbrt_v4_defines_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.pbrt");
    std::fs::write(
        &path,
        "LookAt 0 1 4  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\nWorldBegin\n\
         Translate 0 1 0\n\
         LightSource \"spot\" \"point3 from\" [ 0 1 0 ] \"point3 to\" [ 0 0 0 ]\n\
         \"float coneangle\" [ 40 ] \"float conedeltaangle\" [ 10 ] \"rgb I\" [ 2 2 2 ] \"float scale\" 3\n\
         LightSource \"spot\" \"point3 from\" [ 1 1 0 ] \"point3 to\" [ 1 1 1 ] \"float power\" 10\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ] \"bool twosided\" true\n\
         Shape \"trianglemesh\" \"point3 P\" [ -1 0 -1  1 0 -1  1 0 1 ] \"integer indices\" [ 0 2 1 ]\n\
         AttributeEnd\n\
         AreaLightSource \"diffuse\" \"rgb L\" [ 1 1 1 ]\n\
         Shape \"trianglemesh\" \"point3 P\" [ -1 3 -1  1 3 -1  1 3 1 ] \"integer indices\" [ 0 1 2 ]\n",
    )
    .unwrap();
    let scene = load_file(&path);
    let lights: Vec<&Light> = (0..scene.lights.len() as u32)
        .map(|i| scene.lights.get(i))
        .collect();
    let spots: Vec<_> = lights
        .iter()
        .filter_map(|l| match l {
            Light::Spot {
                position,
                intensity,
                cone,
            } => Some((*position, *intensity, *cone)),
            _ => None,
        })
        .collect();
    assert_eq!(spots.len(), 2);
    let at = |cone: &SpotCone, deg: f32| {
        let (s, c) = deg.to_radians().sin_cos();
        let axis = cone.axis();
        let side = axis.any_orthonormal_vector();
        cone.falloff(axis * c + side * s)
    };
    let (position, intensity, cone) = spots[0];
    assert!((position - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-6);
    assert!((cone.axis() - Vec3::NEG_Y).length() < 1e-6);
    assert_eq!(intensity.r, 6.0);
    assert_eq!(at(&cone, 29.0), 1.0);
    assert!(at(&cone, 35.0) > 0.0 && at(&cone, 35.0) < 1.0);
    assert_eq!(at(&cone, 41.0), 0.0);
    // pbrt-v4's defaults: 30 and 5 degrees.
    let (position, intensity, cone) = spots[1];
    assert!((position - Vec3::new(1.0, 2.0, 0.0)).length() < 1e-6);
    assert!((cone.axis() - Vec3::Z).length() < 1e-6);
    let (cos_start, cos_end) = (25f64.to_radians().cos(), 30f64.to_radians().cos());
    let k_e = 2.0 * PI * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0);
    assert!((intensity.r as f64 - 10.0 / k_e).abs() < 1e-4 * 10.0 / k_e);
    assert_eq!(at(&cone, 24.0), 1.0);
    assert_eq!(at(&cone, 31.0), 0.0);
    let sided: Vec<bool> = lights
        .iter()
        .filter_map(|l| match l {
            Light::Triangle { two_sided, .. } => Some(*two_sided),
            _ => None,
        })
        .collect();
    assert_eq!(sided, [true, false]);
    let powers: Vec<f32> = lights
        .iter()
        .filter(|l| matches!(l, Light::Triangle { .. }))
        .map(|l| l.power())
        .collect();
    assert_eq!(powers[0], 2.0 * powers[1]);
}
