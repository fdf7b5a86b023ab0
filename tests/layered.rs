//! pbrt-v4's diffuse transmission, coated diffuse and coated conductor, and the mix material:
//! sampling follows the reported pdf (chi-square over the sphere), forward and reverse pdfs
//! agree, reflection is reciprocal, a white coated diffuse conserves energy, the deterministic
//! layered model stays within its stated distance of pbrt-v4's random walk (an f64 version of
//! it here), a white diffuse transmitter in a uniform environment gives 1, a mix shows its
//! two materials in proportion, and every technique agrees on a scene with all of them.

mod common;

use common::chi_square::{chi_square, direction};
use common::{
    assert_agree, assert_means_agree, load, load_file, options, render_stats, PixelStats,
};
use glam::{DVec3, Vec3};
use std::f64::consts::PI;
use vmerge::bsdf::{Bsdf, MaterialKind, Params, TransportMode};
use vmerge::color::Rgb;
use vmerge::options::{RenderOptions, Technique};
use vmerge::sampling::{Rng, Stream};
use vmerge::scene::Scene;
use vmerge::texture::{write_pfm, Texture};

fn kind(type_name: &str, params: Params) -> MaterialKind {
    MaterialKind::from_params(type_name, &params).unwrap_or_else(|e| panic!("{e}"))
}

fn coated_diffuse(r: f32, roughness: f32) -> MaterialKind {
    kind(
        "coateddiffuse",
        Params::new()
            .with_color("reflectance", Rgb::splat(r))
            .with_number("roughness", roughness),
    )
}

fn coated_conductor(interface: f32, conductor: f32) -> MaterialKind {
    kind(
        "coatedconductor",
        Params::new()
            .with_number("interface.roughness", interface)
            .with_number("conductor.roughness", conductor),
    )
}

fn diffuse_transmission(r: f32, t: f32) -> MaterialKind {
    kind(
        "diffusetransmission",
        Params::new()
            .with_color("reflectance", Rgb::splat(r))
            .with_color("transmittance", Rgb::splat(t)),
    )
}

fn wo_at(theta_deg: f64) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin() as f32, 0.0, t.cos() as f32)
}

#[test]
fn sampling_matches_the_pdf() {
    let kinds = [
        diffuse_transmission(0.6, 0.3),
        diffuse_transmission(0.1, 0.8),
        coated_diffuse(0.7, 0.0),
        coated_diffuse(0.7, 0.05),
        coated_diffuse(0.3, 0.4),
        coated_conductor(0.0, 0.1),
        coated_conductor(0.1, 0.0),
        coated_conductor(0.2, 0.3),
    ];
    for (i, kind) in kinds.iter().enumerate() {
        for (j, angle) in [0.0, 40.0, 70.0, 87.0].into_iter().enumerate() {
            chi_square(kind, wo_at(angle), 200_000, (i * 10 + j) as u64);
        }
    }
}

/// Directions spread over the sphere, none in the surface plane.
fn sphere_points(n: usize) -> impl Iterator<Item = Vec3> {
    (0..n).map(move |i| {
        let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
        let r = (1.0 - z * z).sqrt();
        let phi = i as f32 * 2.399_963;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    })
}

#[test]
fn pdfs_agree_both_ways_and_reflection_is_reciprocal() {
    let kinds = [
        diffuse_transmission(0.6, 0.3),
        coated_diffuse(0.7, 0.0),
        coated_diffuse(0.5, 0.3),
        coated_conductor(0.0, 0.2),
        coated_conductor(0.3, 0.1),
    ];
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-4 * a.abs().max(b.abs()) + 1e-7;
    for kind in &kinds {
        for wo in sphere_points(40).filter(|w| w.z.abs() > 0.02) {
            for wi in sphere_points(97).filter(|w| w.z.abs() > 0.02) {
                for mode in [TransportMode::Radiance, TransportMode::Importance] {
                    let forward = Bsdf::new(kind, Vec3::Z, wo, mode).unwrap().eval(wi);
                    let backward = Bsdf::new(kind, Vec3::Z, wi, mode).unwrap().eval(wo);
                    assert!(
                        close(forward.pdf_w, backward.rev_pdf_w)
                            && close(forward.rev_pdf_w, backward.pdf_w),
                        "{kind:?} {wo} {wi}: {forward:?} {backward:?}"
                    );
                    // No medium changes across these surfaces: f(wo, wi) = f(wi, wo).
                    assert!(
                        close(forward.f.g, backward.f.g),
                        "{kind:?} {wo} {wi}: f {} against {}",
                        forward.f.g,
                        backward.f.g
                    );
                }
            }
        }
    }
}

/// The directional albedo of `kind` from `wo` by quadrature of f cos over the sphere
/// (Simpson in cos theta and phi, f64), plus the weight of its delta lobe, which a sample of
/// the delta lobe reports as f cos / pdf times the probability of choosing it.
fn albedo_by_quadrature(kind: &MaterialKind, wo: Vec3) -> f64 {
    let bsdf = Bsdf::new(kind, Vec3::Z, wo, TransportMode::Radiance).unwrap();
    let (nt, np) = (512, 128);
    let mut sum = 0.0;
    for i in 0..=nt {
        // Upper and lower hemispheres apart, so the jump at the horizon is no node's problem.
        for side in [1.0, -1.0] {
            let c = side * (1e-9 + (1.0 - 2e-9) * i as f64 / nt as f64);
            let wt = if i == 0 || i == nt {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            for j in 0..np {
                let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                let e = bsdf.eval(direction(c, phi));
                sum += wt * e.f.g as f64 * c.abs();
            }
        }
    }
    let quadrature = sum * (1.0 / nt as f64 / 3.0) * (2.0 * PI / np as f64);
    quadrature + delta_lobes(&bsdf).iter().map(|&(_, a)| a).sum::<f64>()
}

/// The delta lobes of `bsdf` (at most one chosen by a low `u[0]`, one by a high one; a wholly
/// delta BSDF has one): each one's direction and what it reflects, f cos (its sample's
/// weight f cos / pdf times the probability pdf of choosing it).
fn delta_lobes(bsdf: &Bsdf) -> Vec<(Vec3, f64)> {
    let picks: &[f32] = if bsdf.is_delta() {
        &[0.0]
    } else {
        &[0.0, 0.999_999]
    };
    picks
        .iter()
        .filter_map(|&u| bsdf.sample([u, 0.5, 0.5]))
        .filter(|s| s.delta)
        .map(|s| (s.wi, (s.f.g * bsdf.cos_theta(s.wi)) as f64))
        .collect()
}

#[test]
fn a_white_coated_diffuse_reflects_no_more_than_it_receives() {
    for roughness in [0.0, 0.05, 0.2, 0.6] {
        for eta in [1.2, 1.5, 2.5] {
            let kind = kind(
                "coateddiffuse",
                Params::new()
                    .with_color("reflectance", Rgb::WHITE)
                    .with_number("roughness", roughness)
                    .with_number("eta", eta)
                    .with_number("thickness", 0.0)
                    .with_number("maxdepth", 1000.0),
            );
            for angle in [0.0, 30.0, 60.0, 80.0, 88.0] {
                let a = albedo_by_quadrature(&kind, wo_at(angle));
                // The quadrature's own error is below 1e-3 on these smooth lobes.
                assert!(
                    a <= 1.0 + 2e-3,
                    "roughness {roughness} eta {eta} at {angle} deg: albedo {a}"
                );
                if roughness == 0.0 {
                    // A smooth coat over a white base without absorption loses nothing.
                    assert!(
                        (a - 1.0).abs() < 2e-3,
                        "eta {eta} at {angle} deg: albedo {a}"
                    );
                }
            }
        }
    }
}

/// An f64 version of pbrt-v4's LayeredBxDF random walk (bxdfs.h, Sample_f) for the reference:
/// a dielectric top of index `eta` and Trowbridge-Reitz `alpha` (0: smooth), a slab of
/// optical thickness `thickness` without scattering, and a base that reflects a direction
/// arriving from above.
mod walk {
    use super::*;

    #[derive(Clone, Copy)]
    pub enum Base {
        Diffuse(f64),
        /// Conductor index relative to the coating, and its alpha (0: smooth).
        Conductor {
            eta: f64,
            k: f64,
            alpha: f64,
        },
    }

    pub struct Layers {
        pub eta: f64,
        pub alpha: f64,
        pub thickness: f64,
        pub max_depth: usize,
        pub base: Base,
    }

    fn lambda(alpha: f64, w: DVec3) -> f64 {
        let t2 = (w.x * w.x + w.y * w.y) / (w.z * w.z);
        ((1.0 + alpha * alpha * t2).sqrt() - 1.0) / 2.0
    }

    /// Heitz's visible-normal sampler (pbrt-v4's Sample_wm), isotropic alpha.
    fn sample_wm(alpha: f64, w: DVec3, u: [f64; 2]) -> DVec3 {
        let mut wh = DVec3::new(alpha * w.x, alpha * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            DVec3::Z.cross(wh).normalize()
        } else {
            DVec3::X
        };
        let t2 = wh.cross(t1);
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let (px, mut py) = (r * phi.cos(), r * phi.sin());
        let h = (1.0 - px * px).sqrt();
        let s = (1.0 + wh.z) / 2.0;
        py = (1.0 - s) * h + s * py;
        let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
        let nh = px * t1 + py * t2 + pz * wh;
        DVec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize()
    }

    pub fn fresnel(cos_i: f64, eta: f64) -> f64 {
        let (cos_i, eta) = if cos_i < 0.0 {
            (-cos_i, 1.0 / eta)
        } else {
            (cos_i, eta)
        };
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        if sin2_t >= 1.0 {
            return 1.0;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let a = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
        let b = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
        (a * a + b * b) / 2.0
    }

    /// pbrt-v4's FrComplex for one channel.
    fn fresnel_complex(cos_i: f64, eta: f64, k: f64) -> f64 {
        type C = (f64, f64);
        let mul = |a: C, b: C| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
        let div = |a: C, b: C| {
            let d = b.0 * b.0 + b.1 * b.1;
            ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
        };
        let sqrt = |a: C| {
            let n = (a.0 * a.0 + a.1 * a.1).sqrt();
            let re = ((n + a.0) / 2.0).max(0.0).sqrt();
            let im = ((n - a.0) / 2.0).max(0.0).sqrt().copysign(a.1);
            (re, im)
        };
        let c = cos_i.clamp(0.0, 1.0);
        let e = (eta, k);
        let sin2_t = div((1.0 - c * c, 0.0), mul(e, e));
        let cos_t = sqrt((1.0 - sin2_t.0, -sin2_t.1));
        let ec = (e.0 * c, e.1 * c);
        let r_parl = div(
            (ec.0 - cos_t.0, ec.1 - cos_t.1),
            (ec.0 + cos_t.0, ec.1 + cos_t.1),
        );
        let ect = mul(e, cos_t);
        let r_perp = div((c - ect.0, -ect.1), (c + ect.0, ect.1));
        (r_parl.0 * r_parl.0 + r_parl.1 * r_parl.1 + r_perp.0 * r_perp.0 + r_perp.1 * r_perp.1)
            / 2.0
    }

    fn refract(w: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
        let (mut cos_i, mut eta, mut n) = (n.dot(w), eta, n);
        if cos_i < 0.0 {
            eta = 1.0 / eta;
            cos_i = -cos_i;
            n = -n;
        }
        let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
        if sin2_t >= 1.0 {
            return None;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        Some(-w / eta + (cos_i / eta - cos_t) * n)
    }

    /// pbrt-v4's DielectricBxDF::Sample_f from `wo` (either side) in importance mode (the
    /// radiance scaling in and out cancels): the new direction and f cos / pdf.
    fn dielectric(l: &Layers, wo: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
        let uc = rng.next_f64();
        if l.alpha == 0.0 {
            let r = fresnel(wo.z, l.eta);
            return if uc < r {
                Some((DVec3::new(-wo.x, -wo.y, wo.z), 1.0))
            } else {
                refract(wo, DVec3::Z, l.eta).map(|wi| (wi, 1.0))
            };
        }
        let wm = sample_wm(l.alpha, wo, [rng.next_f64(), rng.next_f64()]);
        let r = fresnel(wo.dot(wm), l.eta);
        let wi = if uc < r {
            let wi = 2.0 * wo.dot(wm) * wm - wo;
            (wi.z * wo.z > 0.0).then_some(wi)?
        } else {
            let wi = refract(wo, wm, l.eta)?;
            (wi.z * wo.z < 0.0).then_some(wi)?
        };
        // D G F / pdf with the visible-normal pdf: G / G1(wo) either way.
        let (lo, li) = (lambda(l.alpha, wo), lambda(l.alpha, wi));
        Some((wi, (1.0 + lo) / (1.0 + lo + li)))
    }

    /// The base's Sample_f for `wo` above it: the new direction and f cos / pdf.
    fn base(b: Base, wo: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
        match b {
            Base::Diffuse(r) => {
                let (u1, u2) = (rng.next_f64(), rng.next_f64());
                let s = u1.sqrt();
                let phi = 2.0 * PI * u2;
                let wi = DVec3::new(s * phi.cos(), s * phi.sin(), (1.0 - u1).sqrt());
                Some((wi, r))
            }
            Base::Conductor { eta, k, alpha } => {
                if alpha == 0.0 {
                    let wi = DVec3::new(-wo.x, -wo.y, wo.z);
                    return Some((wi, fresnel_complex(wo.z, eta, k)));
                }
                let wm = sample_wm(alpha, wo, [rng.next_f64(), rng.next_f64()]);
                let wi = 2.0 * wo.dot(wm) * wm - wo;
                if wi.z <= 0.0 {
                    return None;
                }
                let (lo, li) = (lambda(alpha, wo), lambda(alpha, wi));
                Some((
                    wi,
                    fresnel_complex(wo.dot(wm), eta, k) * (1.0 + lo) / (1.0 + lo + li),
                ))
            }
        }
    }

    /// One walk from `wo` (above): the direction it leaves by and its weight f cos / pdf, or
    /// `None` where it ends inside.
    pub fn sample(l: &Layers, wo: DVec3, rng: &mut Rng) -> Option<(DVec3, f64)> {
        let (mut w, mut beta) = dielectric(l, wo, rng)?;
        if w.z > 0.0 {
            return Some((w, beta));
        }
        let mut at_top = true;
        for _ in 0..l.max_depth {
            beta *= (-l.thickness / w.z.abs()).exp();
            at_top = !at_top;
            let (wi, weight) = if at_top {
                dielectric(l, -w, rng)?
            } else {
                base(l.base, -w, rng)?
            };
            beta *= weight;
            if at_top && wi.z > 0.0 {
                return Some((wi, beta));
            }
            w = wi;
        }
        None
    }
}

/// The model's albedo and pbrt's walk's, with the walk's standard error, from `wo`, and the
/// largest difference over 6 polar bins of the outgoing cosine of what each reflects there
/// (the model by quadrature, the walk by its exits).
fn against_the_walk(
    model: &MaterialKind,
    layers: &walk::Layers,
    wo: Vec3,
    n: usize,
) -> (f64, f64, f64, f64) {
    const BINS: usize = 6;
    let mut rng = Rng::for_sample(17, 0, 0, Stream::Light);
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    let mut walk_bins = [0f64; BINS];
    let bin = |c: f64| ((c * BINS as f64) as usize).min(BINS - 1);
    for _ in 0..n {
        let v = walk::sample(layers, wo.as_dvec3(), &mut rng);
        let w = v.map_or(0.0, |(_, b)| b);
        if let Some((d, b)) = v {
            walk_bins[bin(d.z)] += b / n as f64;
        }
        sum += w;
        sum_sq += w * w;
    }
    let mean = sum / n as f64;
    let se = ((sum_sq / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
    let bsdf = Bsdf::new(model, Vec3::Z, wo, TransportMode::Radiance).unwrap();
    let mut model_bins = [0f64; BINS];
    let (nt, np) = (600, 96);
    for i in 0..nt {
        let c = (i as f64 + 0.5) / nt as f64;
        for j in 0..np {
            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let f = bsdf.eval(direction(c, phi)).f.g as f64;
            model_bins[bin(c)] += f * c * (1.0 / nt as f64) * (2.0 * PI / np as f64);
        }
    }
    for (wi, a) in delta_lobes(&bsdf) {
        model_bins[bin(wi.z as f64)] += a;
    }
    let albedo: f64 = model_bins.iter().sum();
    let worst = model_bins
        .iter()
        .zip(&walk_bins)
        .map(|(m, w)| (m - w).abs())
        .fold(0.0, f64::max);
    (albedo, mean, se, worst)
}

#[test]
fn the_layered_model_is_close_to_pbrt_v4s_random_walk() {
    // pbrt-v4's defaults: eta 1.5, thickness 0.01, maxdepth 10; roughness remapped.
    let n = 200_000;
    let mut worst_albedo: f64 = 0.0;
    // The bounds are the distances measured (the module docs of bsdf/coated_diffuse.rs and
    // bsdf/coated_conductor.rs state them) with a little room.
    for (roughness, r, bound) in [(0.0, 0.8, 0.002), (0.1, 0.8, 0.006), (0.5, 0.5, 0.004)] {
        let model = kind(
            "coateddiffuse",
            Params::new()
                .with_color("reflectance", Rgb::splat(r))
                .with_number("roughness", roughness),
        );
        let layers = walk::Layers {
            eta: 1.5,
            alpha: (roughness as f64).sqrt(),
            thickness: 0.01,
            max_depth: 10,
            base: walk::Base::Diffuse(r as f64),
        };
        for angle in [0.0, 45.0, 75.0] {
            let (a, walk, se, bins) = against_the_walk(&model, &layers, wo_at(angle), n);
            eprintln!(
                "coateddiffuse roughness {roughness} r {r} at {angle} deg: model {a:.4}, walk \
                 {walk:.4} +- {se:.4}, largest bin difference {bins:.4}"
            );
            worst_albedo = worst_albedo.max((a - walk).abs());
            assert!(
                (a - walk).abs() < bound + 4.0 * se,
                "coateddiffuse roughness {roughness} at {angle} deg: model {a}, walk {walk} +- {se}"
            );
        }
    }
    for (interface, conductor, bound) in [(0.0, 0.0, 0.002), (0.0, 0.1, 0.045), (0.2, 0.2, 0.013)] {
        let model = coated_conductor(interface, conductor);
        // Copper's green channel, relative to the coating (pbrt divides by its eta).
        let layers = walk::Layers {
            eta: 1.5,
            alpha: (interface as f64).sqrt(),
            thickness: 0.01,
            max_depth: 10,
            base: walk::Base::Conductor {
                eta: 0.924_033 / 1.5,
                k: 2.452_848 / 1.5,
                alpha: (conductor as f64).sqrt(),
            },
        };
        for angle in [0.0, 45.0, 75.0] {
            let (a, walk, se, bins) = against_the_walk(&model, &layers, wo_at(angle), n);
            eprintln!(
                "coatedconductor interface {interface} conductor {conductor} at {angle} deg: \
                 model {a:.4}, walk {walk:.4} +- {se:.4}, largest bin difference {bins:.4}"
            );
            assert!(
                (a - walk).abs() < bound + 4.0 * se,
                "coatedconductor {interface}/{conductor} at {angle} deg: model {a}, walk {walk} +- {se}"
            );
        }
    }
    eprintln!("largest coateddiffuse albedo difference {worst_albedo:.4}");
}

fn load_scene(name: &str, text: &str) -> Scene {
    let dir = std::env::temp_dir().join(format!("vmerge-layered-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let scene = load_file(&path);
    std::fs::remove_dir_all(&dir).unwrap();
    scene
}

/// One sphere of `material` (a TOML table body) seen whole by the camera, in a uniform sky
/// of radiance 1.
fn sphere_in_the_sky(name: &str, material: &str) -> Scene {
    load_scene(
        name,
        &format!(
            r#"
[render]
resolution = [16, 16]
max_path_length = 0
sky = {{ horizon = [1.0, 1.0, 1.0], zenith = [1.0, 1.0, 1.0], up = [0.0, 1.0, 0.0] }}

[[camera]]
name = "front"
position = [0.0, 0.0, 3.0]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 30.0

[[sphere]]
center = [0.0, 0.0, 0.0]
radius = 0.7
material = "m"

{material}
"#
        ),
    )
}

#[test]
fn a_white_diffuse_transmitter_in_a_uniform_sky_gives_one() {
    let scene = sphere_in_the_sky(
        "furnace",
        "[material.m]\ntype = \"diffusetransmission\"\nreflectance = [0.4, 0.4, 0.4]\n\
         transmittance = [0.6, 0.6, 0.6]\n",
    );
    for technique in [Technique::Pt, Technique::Bpt] {
        let stats = render_stats(&scene, &options(technique, 16), 64);
        for (i, (&m, &v)) in stats.mean.iter().zip(&stats.var_of_mean).enumerate() {
            assert!(
                (m - 1.0).abs() <= 4.0 * v.sqrt() + 1e-4,
                "{technique:?} pixel {i}: {m} (se {})",
                v.sqrt()
            );
        }
        assert!((stats.image_mean() - 1.0).abs() < 4.0 * stats.image_se() + 1e-4);
    }
}

#[test]
fn a_mix_shows_its_materials_in_proportion() {
    let mix = sphere_in_the_sky(
        "mix",
        "[material.black]\nkd = [0.0, 0.0, 0.0]\n[material.white]\nkd = [1.0, 1.0, 1.0]\n\
         [material.m]\ntype = \"mix\"\nmaterials = [\"black\", \"white\"]\namount = 0.3\n",
    );
    let grey = sphere_in_the_sky("grey", "[material.m]\nkd = [0.3, 0.3, 0.3]\n");
    let o = RenderOptions {
        max_path_length: Some(2),
        ..options(Technique::Pt, 16)
    };
    let a = render_stats(&mix, &o, 256);
    let b = render_stats(&grey, &o, 256);
    // Direct light only: the grey sphere reflects 0.3 everywhere, the mix 0 or 1 per point.
    assert_means_agree("mix of black and white against grey", &a, &b);
    // The amount from a texture (one texel of 0.3): the same image as the constant's.
    let dir = std::env::temp_dir().join(format!("vmerge-layered-amount-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let texel = Texture::new(1, 1, vec![Rgb::splat(0.3)]).unwrap();
    let image = dir.join("amount.pfm");
    std::fs::write(&image, write_pfm(&texel)).unwrap();
    let textured = sphere_in_the_sky(
        "mix-texture",
        &format!(
            "[material.black]\nkd = [0.0, 0.0, 0.0]\n[material.white]\nkd = [1.0, 1.0, 1.0]\n\
             [material.m]\ntype = \"mix\"\nmaterials = [\"black\", \"white\"]\n\
             amount_texture = {:?}\n",
            image.display().to_string()
        ),
    );
    std::fs::remove_dir_all(&dir).unwrap();
    let t = render_stats(&textured, &o, 256);
    assert_means_agree("mix with a textured amount against grey", &t, &b);
    // Deterministic: the same render twice is the same image.
    let again = render_stats(&mix, &o, 64);
    let first = render_stats(&mix, &o, 64);
    assert_eq!(again.mean, first.mean);
}

fn agree_with_bpt(scene: &Scene, camera: &str) {
    let view = |technique| RenderOptions {
        camera: Some(camera.into()),
        ..options(technique, 24)
    };
    let bpt = render_stats(scene, &view(Technique::Bpt), 2048);
    for (technique, iterations) in [
        (Technique::Pt, 2048),
        (Technique::Vcm, 1024),
        (Technique::Upg, 1024),
        (Technique::UpgCamera, 1024),
    ] {
        let stats: PixelStats = render_stats(scene, &view(technique), iterations);
        assert_eq!(stats.dropped, 0, "{technique:?} dropped samples");
        assert_agree(&format!("layered: {technique:?}"), &stats, &bpt);
    }
}

#[test]
fn techniques_agree_on_layered_and_mixed_materials() {
    agree_with_bpt(&load("layered"), "floor");
}
