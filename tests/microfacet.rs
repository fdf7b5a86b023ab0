//! The Trowbridge-Reitz lobes of `conductor` and `dielectric`: sampling follows the reported
//! pdf (chi-square over a binned sphere, several alphas, anisotropic ones, incidences down to
//! grazing, from outside and inside), forward and reverse pdfs agree, reflection is reciprocal
//! and refraction adjoint, and the albedo of a white rough conductor matches an independent
//! quadrature in f64. In scenes: the furnace (a white rough conductor loses what the
//! quadrature says, a rough glass sphere vanishes) and every technique agreeing on the
//! shipped `microfacets` scene.

mod common;

use common::chi_square::{chi_square, direction};
use common::load_file;
use glam::Vec3;
use std::f64::consts::PI;
use vmerge::bsdf::microfacet::Roughness;
use vmerge::bsdf::{Bsdf, MaterialKind, TransportMode};
use vmerge::color::Rgb;
use vmerge::options::Technique;
use vmerge::sampling::{Rng, Stream};
use vmerge::scene::Scene;

/// A unit direction at polar angle `theta_deg` in the xz plane turned by 30 degrees of
/// azimuth (so anisotropic lobes are seen off their axes).
fn wo_at(theta_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), 30f32.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()).normalize()
}

fn roughness(u: f32, v: f32) -> Roughness {
    Roughness { u, v, remap: false }
}

/// A conductor that reflects everything (F = 1 to 4e-8): eta 1, k 1e4.
fn white_conductor(ax: f32, ay: f32) -> MaterialKind {
    MaterialKind::Conductor {
        eta: Rgb::WHITE,
        k: Rgb::splat(1e4),
        roughness: roughness(ax, ay),
    }
}

fn gold(ax: f32, ay: f32) -> MaterialKind {
    MaterialKind::Conductor {
        eta: Rgb::new(0.143, 0.375, 1.442),
        k: Rgb::new(3.983, 2.386, 1.603),
        roughness: roughness(ax, ay),
    }
}

fn rough_glass(ax: f32, ay: f32) -> MaterialKind {
    MaterialKind::Dielectric {
        eta: 1.5,
        roughness: roughness(ax, ay),
    }
}

fn bsdf(kind: &MaterialKind, wo: Vec3, mode: TransportMode) -> Bsdf<'_> {
    Bsdf::new(kind, Vec3::Z, wo, mode).expect("wo off the plane")
}

#[test]
fn conductor_sampling_matches_its_pdf() {
    let kinds = [
        gold(0.1, 0.1),
        gold(0.35, 0.35),
        gold(0.1, 0.45),
        gold(0.8, 0.8),
    ];
    for (i, kind) in kinds.iter().enumerate() {
        for (j, angle) in [0.0, 45.0, 85.0].into_iter().enumerate() {
            chi_square(kind, wo_at(angle), 200_000, (10 * i + j) as u64);
        }
    }
}

#[test]
fn dielectric_sampling_matches_its_pdf_from_both_sides() {
    let kinds = [
        rough_glass(0.15, 0.15),
        rough_glass(0.5, 0.5),
        rough_glass(0.1, 0.4),
    ];
    for (i, kind) in kinds.iter().enumerate() {
        // From outside, and from inside (where much of the sphere is total internal reflection).
        for (j, angle) in [10.0, 60.0, 85.0, 150.0, 175.0].into_iter().enumerate() {
            chi_square(kind, wo_at(angle), 200_000, (100 + 10 * i + j) as u64);
        }
    }
}

/// Pairs of directions over the sphere, the first in the upper hemisphere when `upper`.
fn pairs(n: usize, seed: u64, upper: bool) -> Vec<(Vec3, Vec3)> {
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let dir = |rng: &mut Rng, up: bool| {
        let c = if up {
            rng.next_f64() * 0.98 + 0.01
        } else {
            rng.next_f64() * 1.98 - 0.99
        };
        direction(c, rng.next_f64() * 2.0 * PI)
    };
    (0..n)
        .map(|_| (dir(&mut rng, upper), dir(&mut rng, false)))
        .collect()
}

/// Values are compared to 1e-3 relative and 1e-5 absolute: near the critical angle 1 - F
/// turns with infinite slope, and the two sides' microfacet normals, equal but rounded
/// apart, then give transmissions of order 1e-5 that differ by a few percent.
#[test]
fn reverse_pdfs_are_forward_pdfs_seen_from_the_other_side() {
    let kinds = [
        gold(0.3, 0.3),
        gold(0.1, 0.5),
        rough_glass(0.3, 0.3),
        rough_glass(0.2, 0.6),
    ];
    let mut nonzero = 0;
    for kind in &kinds {
        for (wo, wi) in pairs(2000, 7, false) {
            for mode in [TransportMode::Radiance, TransportMode::Importance] {
                let forward = bsdf(kind, wo, mode).eval(wi);
                let backward = bsdf(kind, wi, mode).eval(wo);
                let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * a.abs().max(b.abs()) + 1e-5;
                assert!(
                    close(forward.rev_pdf_w, backward.pdf_w)
                        && close(forward.pdf_w, backward.rev_pdf_w),
                    "{kind:?} wo={wo} wi={wi}: {forward:?} vs {backward:?}"
                );
                nonzero += (forward.pdf_w > 0.0) as usize;
            }
        }
    }
    assert!(nonzero > 4000, "{nonzero} pairs with a positive pdf");
}

#[test]
fn reflection_is_reciprocal_and_refraction_adjoint() {
    let close = |a: f32, b: f32| (a - b).abs() <= 2e-4 * a.abs().max(b.abs()) + 1e-5;
    let mut transmitted = 0;
    for kind in [
        gold(0.3, 0.3),
        gold(0.1, 0.5),
        rough_glass(0.3, 0.3),
        rough_glass(0.2, 0.6),
    ] {
        for (wo, wi) in pairs(2000, 11, false) {
            let radiance = bsdf(&kind, wo, TransportMode::Radiance).eval(wi).f;
            let swapped = bsdf(&kind, wi, TransportMode::Radiance).eval(wo).f;
            let importance = bsdf(&kind, wo, TransportMode::Importance).eval(wi).f;
            if wo.z * wi.z > 0.0 {
                assert!(close(radiance.g, swapped.g), "{kind:?} {wo} {wi}");
                assert_eq!(radiance, importance);
            } else {
                // The adjoint BSDF: importance along wo -> wi is radiance along wi -> wo, and
                // radiance across the interface is scaled by (n_o / n_i)^2 (leaving glass, 1.5^2).
                assert!(close(importance.g, swapped.g), "{kind:?} {wo} {wi}");
                if radiance.g > 0.0 {
                    let eta2 = if wo.z > 0.0 { 1.5f32 * 1.5 } else { 1.0 / 2.25 };
                    assert!(close(radiance.g * eta2, importance.g), "{kind:?} {wo} {wi}");
                    transmitted += 1;
                }
            }
        }
    }
    assert!(transmitted > 200, "{transmitted} refracted pairs");
}

/// The albedo of a white Trowbridge-Reitz reflector (F = 1) of isotropic `alpha` seen from
/// `wo`, in f64, computed independently of the renderer: over microfacet normals, where
/// D(wm) cos(theta_m) dwm = ds dphi / (2 pi) with s = t / (1 + t), t = tan^2(theta_m) / alpha^2
/// (the distribution's CDF), and f cos_i dwi = D G |wo . wm| / cos_o dwm (Walter et al. 2007),
/// so the albedo is the mean over (s, phi) of G |wo . wm| / (cos_o cos_m) where wi is above.
/// The midpoint rule runs in v with s = 1 - (1 - v)^3, which crowds the nodes towards s = 1,
/// where wi leaves the hemisphere at small alphas.
fn white_albedo_quadrature(alpha: f64, wo: [f64; 3], n: usize) -> f64 {
    let lambda = |w: [f64; 3]| {
        let t2 = (w[0] * w[0] + w[1] * w[1]) / (w[2] * w[2]);
        ((1.0 + alpha * alpha * t2).sqrt() - 1.0) / 2.0
    };
    let lambda_o = lambda(wo);
    let mut sum = 0.0;
    for i in 0..n {
        let v = (i as f64 + 0.5) / n as f64;
        let s = 1.0 - (1.0 - v).powi(3);
        let ds = 3.0 * (1.0 - v).powi(2);
        let tan2 = alpha * alpha * s / (1.0 - s);
        let cos_m = 1.0 / (1.0 + tan2).sqrt();
        let sin_m = (1.0 - cos_m * cos_m).sqrt();
        for j in 0..2 * n {
            let phi = (j as f64 + 0.5) / (2 * n) as f64 * 2.0 * PI;
            let wm = [sin_m * phi.cos(), sin_m * phi.sin(), cos_m];
            let dot = wo[0] * wm[0] + wo[1] * wm[1] + wo[2] * wm[2];
            if dot <= 0.0 {
                continue;
            }
            let wi = [
                2.0 * dot * wm[0] - wo[0],
                2.0 * dot * wm[1] - wo[1],
                2.0 * dot * wm[2] - wo[2],
            ];
            if wi[2] <= 0.0 {
                continue;
            }
            let g = 1.0 / (1.0 + lambda_o + lambda(wi));
            sum += g * dot / (wo[2] * cos_m) * ds;
        }
    }
    sum / (2 * n * n) as f64
}

/// The albedo of `kind` seen from `wo` by sampling it: the mean of f |cos| / pdf, and its
/// standard error.
fn sampled_albedo(kind: &MaterialKind, wo: Vec3, samples: usize, seed: u64) -> (f64, f64) {
    let b = bsdf(kind, wo, TransportMode::Radiance);
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..samples {
        if let Some(s) = b.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()]) {
            let w = (s.f.g * s.wi.z.abs() / s.pdf_w) as f64;
            sum += w;
            sum2 += w * w;
        }
    }
    let n = samples as f64;
    let mean = sum / n;
    (mean, ((sum2 / n - mean * mean) / n).sqrt())
}

#[test]
fn white_rough_conductor_albedo_matches_quadrature() {
    for alpha in [0.05f32, 0.2, 0.5, 1.0] {
        for angle in [0.0f32, 40.0, 70.0, 85.0] {
            let wo = Vec3::new(angle.to_radians().sin(), 0.0, angle.to_radians().cos());
            let exact =
                white_albedo_quadrature(alpha as f64, [wo.x as f64, wo.y as f64, wo.z as f64], 600);
            let (mean, se) = sampled_albedo(&white_conductor(alpha, alpha), wo, 400_000, 5);
            // Four standard errors plus the quadrature's and f32's error: a 1% bias from a
            // wrong masking term or pdf is caught.
            assert!(4.0 * se < 0.01 * exact, "too noisy: se {se}");
            assert!(
                (mean - exact).abs() < 4.0 * se + 2e-4,
                "alpha {alpha}, {angle} deg: sampled {mean} +- {se}, quadrature {exact}"
            );
            assert!(exact <= 1.0 && exact > 0.3, "{exact}");
        }
    }
}

/// A scene file in a temporary directory: `body` after a `[render]` table with a uniform sky
/// of radiance 1 (the furnace) and the camera looking from `position` at `look_at`.
fn furnace_scene(
    body: &str,
    position: Vec3,
    look_at: Vec3,
    fov: f32,
) -> (tempfile::TempDir, Scene) {
    furnace_scene_in(tempfile::tempdir().unwrap(), body, position, look_at, fov)
}

/// [`furnace_scene`] in the directory `dir`, where the files the scene names are.
fn furnace_scene_in(
    dir: tempfile::TempDir,
    body: &str,
    position: Vec3,
    look_at: Vec3,
    fov: f32,
) -> (tempfile::TempDir, Scene) {
    let path = dir.path().join("scene.toml");
    let text = format!(
        "[render]\nresolution = [8, 8]\nmax_path_length = 32\n\
         sky = {{ horizon = [1.0, 1.0, 1.0], zenith = [1.0, 1.0, 1.0], up = [0.0, 1.0, 0.0] }}\n\
         [[camera]]\nname = \"front\"\nposition = [{}, {}, {}]\nlook_at = [{}, {}, {}]\n\
         up = [0.0, 1.0, 0.0]\nfov = {fov}\n{body}",
        position.x, position.y, position.z, look_at.x, look_at.y, look_at.z
    );
    std::fs::write(&path, text).unwrap();
    let scene = load_file(&path);
    (dir, scene)
}

/// A white rough conductor (F = 1) in a uniform environment of radiance 1: a convex reflector
/// sends every reflected ray to the sky, so a pixel sees exactly the directional albedo, and
/// what it loses (masking without multiple scattering) is what the quadrature says. A narrow
/// camera (0.2 degrees) sees one incidence on the unit sphere.
#[test]
fn white_conductor_furnace_loses_what_the_quadrature_says() {
    for alpha in [0.2f32, 0.6] {
        for angle in [0.0f32, 60.0] {
            let wo = Vec3::new(angle.to_radians().sin(), 0.0, angle.to_radians().cos());
            let body = format!(
                "[[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"white\"\n\
                 [material.white]\ntype = \"conductor\"\neta = [1.0, 1.0, 1.0]\n\
                 k = [10000.0, 10000.0, 10000.0]\nroughness = {alpha}\nremaproughness = false\n"
            );
            let (_dir, scene) = furnace_scene(&body, Vec3::Z + 3.0 * wo, Vec3::Z, 0.2);
            let options = common::options(Technique::Pt, 8);
            let stats = common::render_stats(&scene, &options, 1024);
            let exact =
                white_albedo_quadrature(alpha as f64, [wo.x as f64, wo.y as f64, wo.z as f64], 600);
            let (mean, se) = (stats.image_mean(), stats.image_se());
            assert!(4.0 * se <= 0.01 * exact, "too noisy: se {se}");
            assert!(
                (mean - exact).abs() <= 4.0 * se + 2e-4,
                "alpha {alpha}, {angle} deg: furnace {mean} (se {se}), quadrature {exact}, loss {}",
                1.0 - exact
            );
            assert_eq!(stats.dropped, 0);
        }
    }
}

/// A nearly smooth rough glass sphere in a uniform environment: radiance is compressed
/// entering and restored leaving, so every pixel sees 1 but for what single-scattering
/// microfacets lose, about 0.4 alpha here (measured: 0.4% at alpha 0.01, 5% at 0.1); at
/// alpha 0.003 that is 0.15% at most. A wrong 1/eta^2 would be off by half.
#[test]
fn rough_glass_sphere_in_the_furnace_is_invisible() {
    let body = "[[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"frosted\"\n\
                [material.frosted]\ntype = \"dielectric\"\neta = 1.5\nroughness = 0.003\n\
                remaproughness = false\n";
    let (_dir, scene) = furnace_scene(body, Vec3::new(0.0, 0.3, 3.5), Vec3::ZERO, 30.0);
    let options = common::options(Technique::Pt, 8);
    let stats = common::render_stats(&scene, &options, 1024);
    let (mean, se) = (stats.image_mean(), stats.image_se());
    assert!(4.0 * se <= 0.01, "too noisy: se {se}");
    assert!(
        (mean - 1.0).abs() <= 4.0 * se + 1.5e-3,
        "furnace {mean} (se {se})"
    );
}

/// pt, bpt, vcm (its radius shrinking), upg and upg-camera render the shipped scene with a
/// rough anisotropic conductor, a rough dielectric, a smooth conductor and a thin dielectric
/// alike: per pixel for the unbiased ones, in the image mean for vcm.
#[test]
fn every_technique_renders_the_microfacet_scene_alike() {
    let scene = common::load("microfacets");
    let size = 24;
    let pt = common::render_stats(&scene, &common::floor_view(Technique::Pt, size), 2048);
    assert_eq!(pt.dropped, 0);
    for technique in [
        Technique::Bpt,
        Technique::Vcm,
        Technique::Upg,
        Technique::UpgCamera,
    ] {
        let stats = common::render_stats(&scene, &common::floor_view(technique, size), 1024);
        let label = format!("microfacets: {technique:?} vs pt");
        assert_eq!(stats.dropped, 0, "{label}: dropped samples");
        if technique == Technique::Vcm {
            common::assert_means_agree(&label, &stats, &pt);
        } else {
            common::assert_agree(&label, &stats, &pt);
        }
    }
}

/// A `roughness_texture` drives the roughness where it is sampled: a conductor smooth by its
/// constant (a delta lobe) is rough where its texture says 0.3, on both axes.
#[test]
fn a_texture_gives_the_roughness() {
    let dir = tempfile::tempdir().unwrap();
    let mut pfm = b"Pf\n2 2\n-1.0\n".to_vec();
    for _ in 0..4 {
        pfm.extend_from_slice(&0.3f32.to_le_bytes());
    }
    std::fs::write(dir.path().join("rough.pfm"), pfm).unwrap();
    let body = "[[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"metal\"\n\
                [material.metal]\ntype = \"conductor\"\nreflectance = [0.9, 0.9, 0.9]\n\
                roughness_texture = \"rough.pfm\"\n";
    let (scene_dir, scene) =
        furnace_scene_in(dir, body, Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 30.0);
    let material = scene
        .materials
        .iter()
        .position(|m| m.name == "metal")
        .unwrap() as u32;
    assert!(scene.material(material).kind.is_delta());
    let albedo = scene.albedo(material, glam::Vec2::new(0.5, 0.5));
    assert_eq!(albedo.roughness, Some(0.3));
    let normals = vmerge::bsdf::Normals::flat(Vec3::Z);
    let b = scene
        .bsdf(
            material,
            normals,
            glam::Vec2::new(0.5, 0.5),
            Vec3::Z,
            TransportMode::Radiance,
        )
        .unwrap();
    assert!(!b.is_delta());
    let reference = MaterialKind::from_params(
        "conductor",
        &vmerge::bsdf::Params::new()
            .with_color("reflectance", Rgb::splat(0.9))
            .with_number("roughness", 0.3),
    )
    .unwrap();
    let wi = Vec3::new(0.3, 0.1, 0.9).normalize();
    let expected = bsdf(&reference, Vec3::Z, TransportMode::Radiance).eval(wi);
    assert_eq!(b.eval(wi), expected);
    drop(scene_dir);
}
