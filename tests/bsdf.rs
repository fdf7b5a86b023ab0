//! BSDFs: sampling follows the reported pdf (chi-square over a direction grid), albedos integrate
//! to the declared values, Phong conserves energy, glass is reciprocal in the adjoint sense.

use glam::Vec3;
use std::f64::consts::PI;
use vmerge::bsdf::{Bsdf, MaterialKind, TransportMode};
use vmerge::color::Rgb;
use vmerge::sampling::{Rng, Stream};

const THETA_BINS: usize = 16;
const PHI_BINS: usize = 32;

fn direction(theta: f64, phi: f64) -> Vec3 {
    Vec3::new(
        (theta.sin() * phi.cos()) as f32,
        (theta.sin() * phi.sin()) as f32,
        theta.cos() as f32,
    )
}

fn wo_at(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// Chi-square test of `sample` against `eval().pdf_w` on a (cos theta, phi) grid over the
/// sphere, with expected counts from integrating the pdf over each bin.
/// Bins expected to hold fewer than 5 samples are pooled. The threshold is the 1e-6 upper
/// quantile (Wilson-Hilferty), so a correct BSDF fails one run in a million per case while a
/// pdf off by 1% in a region of many bins is caught.
fn chi_square(kind: &MaterialKind, wo: Vec3, samples: usize, seed: u64) {
    let n = Vec3::Z;
    let bsdf = Bsdf::new(kind, n, wo, TransportMode::Radiance).unwrap();
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let mut observed = vec![0f64; 2 * THETA_BINS * PHI_BINS];
    let bin = |w: Vec3| {
        let c = (w.z as f64).clamp(-1.0, 1.0);
        let t = (((1.0 - c) / 2.0) * (2 * THETA_BINS) as f64) as usize;
        let p = ((w.y as f64).atan2(w.x as f64) + PI) / (2.0 * PI) * PHI_BINS as f64;
        t.min(2 * THETA_BINS - 1) * PHI_BINS + (p as usize).min(PHI_BINS - 1)
    };
    let mut accepted = 0usize;
    for _ in 0..samples {
        if let Some(s) = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()]) {
            let e = bsdf.eval(s.wi);
            assert!(
                (e.pdf_w - s.pdf_w).abs() <= 1e-3 * s.pdf_w,
                "{kind:?}: sample pdf {} eval pdf {}",
                s.pdf_w,
                e.pdf_w
            );
            for (a, b) in [(e.f.r, s.f.r), (e.f.g, s.f.g), (e.f.b, s.f.b)] {
                assert!((a - b).abs() <= 1e-4 * b.abs().max(1e-3));
            }
            observed[bin(s.wi)] += 1.0;
            accepted += 1;
        }
    }
    let mut expected = vec![0f64; observed.len()];
    // Simpson's rule in cos theta (the lobes are smooth in it, and exponent 1000 needs the
    // fourth-order rule: the midpoint rule is off by 4e-4 of the mass at exponent 100),
    // and in phi.
    const SUB_T: usize = 128;
    const SUB_P: usize = 16;
    for t in 0..2 * THETA_BINS {
        for p in 0..PHI_BINS {
            let c0 = 1.0 - 2.0 * t as f64 / (2 * THETA_BINS) as f64;
            let dc = -2.0 / (2 * THETA_BINS) as f64 / SUB_T as f64;
            let mut integral = 0.0;
            let simpson = |i: usize, n: usize| {
                if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                }
            };
            let d_phi = 2.0 * PI / PHI_BINS as f64 / SUB_P as f64;
            for j in 0..=SUB_P {
                let phi = -PI + 2.0 * PI * p as f64 / PHI_BINS as f64 + j as f64 * d_phi;
                for i in 0..=SUB_T {
                    // Nodes stay a hair inside the bin, so the horizon's jump in the pdf is not
                    // sampled on the boundary of the bin below it.
                    let c = (c0 + i as f64 * dc).clamp(c0 + SUB_T as f64 * dc + 1e-9, c0 - 1e-9);
                    let weight = simpson(i, SUB_T) * simpson(j, SUB_P);
                    integral += weight * bsdf.eval(direction(c.acos(), phi)).pdf_w as f64;
                }
            }
            expected[t * PHI_BINS + p] =
                integral * (dc.abs() / 3.0) * (d_phi / 3.0) * samples as f64;
        }
    }
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
    for (o, e) in observed.iter().zip(&expected) {
        if *e < 5.0 {
            pooled_o += o;
            pooled_e += e;
        } else {
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    // Samples rejected below the surface fall in no bin; the pooled cell takes the pdf mass
    // outside the bins and the remainder.
    pooled_o += (samples - accepted) as f64;
    pooled_e += samples as f64 - expected.iter().sum::<f64>();
    if pooled_e > 5.0 {
        chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        dof += 1;
    }
    let k = (dof - 1) as f64;
    let z = 4.753; // upper 1e-6 quantile of the standard normal
    let threshold = k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
    assert!(
        chi2 < threshold,
        "{kind:?} wo={wo}: chi2 {chi2} over {dof} bins (threshold {threshold})"
    );
}

fn phong(kd: f32, ks: f32, exponent: f32) -> MaterialKind {
    MaterialKind::Phong {
        kd: Rgb::splat(kd),
        ks: Rgb::splat(ks),
        exponent,
    }
}

#[test]
fn sampling_matches_the_pdf() {
    let kinds = [
        MaterialKind::Lambert {
            kd: Rgb::splat(0.7),
        },
        phong(0.0, 0.9, 1.0),
        phong(0.0, 0.9, 10.0),
        phong(0.0, 0.9, 100.0),
        phong(0.0, 0.9, 1000.0),
        phong(0.45, 0.3, 30.0),
        phong(0.3, 0.6, 50.0),
        // Taken as 40, as an exporter's decimal of a whole exponent is.
        phong(0.3, 0.6, 39.999996),
        phong(0.3, 0.6, 12.5),
    ];
    for (i, kind) in kinds.iter().enumerate() {
        for (j, angle) in [0.0f32, 30.0, 60.0, 85.0].into_iter().enumerate() {
            chi_square(kind, wo_at(angle), 400_000, (i * 10 + j) as u64);
        }
    }
}

#[test]
fn exponents_within_rounding_of_a_whole_number_are_whole() {
    let wo = wo_at(30.0);
    let near_mirror = Vec3::new(-wo.x + 0.2, -wo.y, wo.z).normalize();
    let at = |exponent| {
        let kind = phong(0.3, 0.6, exponent);
        let bsdf = Bsdf::new(&kind, Vec3::Z, wo, TransportMode::Radiance).unwrap();
        let e = bsdf.eval(near_mirror);
        (e.f, e.pdf_w)
    };
    assert_eq!(at(39.999996), at(40.0));
    assert_ne!(at(39.99), at(40.0));
}

/// Mean of f cos / pdf over samples: the directional albedo.
fn albedo(kind: &MaterialKind, wo: Vec3, mode: TransportMode, n: usize) -> (f64, f64) {
    let bsdf = Bsdf::new(kind, Vec3::Z, wo, mode).unwrap();
    let mut rng = Rng::for_sample(99, 0, 0, Stream::Eye);
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    for _ in 0..n {
        let v = bsdf
            .sample([rng.next_f32(), rng.next_f32(), rng.next_f32()])
            .map_or(0.0, |s| (s.f.g * bsdf.cos_theta(s.wi) / s.pdf_w) as f64);
        sum += v;
        sum_sq += v * v;
    }
    let mean = sum / n as f64;
    (
        mean,
        ((sum_sq / n as f64 - mean * mean).max(0.0) / n as f64).sqrt(),
    )
}

#[test]
fn albedos_integrate_to_the_declared_values() {
    let n = 200_000;
    // Lambert: every sample weighs exactly kd.
    let (a, se) = albedo(
        &MaterialKind::Lambert {
            kd: Rgb::splat(0.6),
        },
        wo_at(40.0),
        TransportMode::Radiance,
        n,
    );
    assert!((a - 0.6).abs() < 1e-5 && se < 1e-5, "{a} {se}");
    // Phong at normal incidence: kd + ks exactly (the lobe of 000 eq. 3.1 integrates to ks
    // around the normal); 4 standard errors.
    for exponent in [1.0, 10.0, 100.0, 1000.0] {
        let (a, se) = albedo(
            &phong(0.3, 0.6, exponent),
            wo_at(0.0),
            TransportMode::Radiance,
            n,
        );
        assert!(
            (a - 0.9).abs() < 4.0 * se + 1e-6,
            "exponent {exponent}: albedo {a} (se {se})"
        );
    }
}

#[test]
fn phong_conserves_energy() {
    for exponent in [1.0, 10.0, 100.0, 1000.0] {
        for (kd, ks) in [(0.0, 1.0), (0.5, 0.5), (1.0, 0.0)] {
            for angle in [0.0, 30.0, 60.0, 80.0, 89.0] {
                let (a, se) = albedo(
                    &phong(kd, ks, exponent),
                    wo_at(angle),
                    TransportMode::Radiance,
                    100_000,
                );
                assert!(
                    a <= 1.0 + 4.0 * se + 1e-6,
                    "kd {kd} ks {ks} n {exponent} at {angle} deg: albedo {a}"
                );
            }
        }
    }
}

/// Glass: reflection and refraction weights average to 1 in importance mode (no absorption);
/// refraction obeys Snell's law; beyond the critical angle everything reflects; and the
/// adjoint relation: a radiance-mode refraction weight from medium i into t is the importance
/// weight scaled by (n_i / n_t)^2.
#[test]
fn glass_is_lossless_snell_and_adjoint() {
    let glass = MaterialKind::Glass { ior: 1.5 };
    for angle in [0.0f32, 20.0, 45.0, 70.0] {
        let (a, se) = albedo(&glass, wo_at(angle), TransportMode::Importance, 50_000);
        assert!((a - 1.0).abs() < 1e-5, "{angle}: {a} {se}");
        let bsdf = Bsdf::new(&glass, Vec3::Z, wo_at(angle), TransportMode::Radiance).unwrap();
        let importance =
            Bsdf::new(&glass, Vec3::Z, wo_at(angle), TransportMode::Importance).unwrap();
        // u = 0.999...: refraction whenever it is possible.
        let s = bsdf.sample([0.9999, 0.5, 0.5]).unwrap();
        let si = importance.sample([0.9999, 0.5, 0.5]).unwrap();
        assert!(s.wi.z < 0.0);
        let sin_i = angle.to_radians().sin();
        let sin_t = (s.wi.x * s.wi.x + s.wi.y * s.wi.y).sqrt();
        assert!(
            (sin_i - 1.5 * sin_t).abs() < 1e-5,
            "Snell: {sin_i} vs 1.5 x {sin_t}"
        );
        let weight = |x: &vmerge::bsdf::BsdfSample| x.f.g * x.wi.z.abs() / x.pdf_w;
        assert!((weight(&s) * 1.5 * 1.5 - weight(&si)).abs() < 1e-5);
    }
    // From inside, beyond the critical angle asin(1/1.5) = 41.8 degrees.
    let inside = Vec3::new(50f32.to_radians().sin(), 0.0, -50f32.to_radians().cos());
    let bsdf = Bsdf::new(&glass, Vec3::Z, inside, TransportMode::Radiance).unwrap();
    for u in [0.0, 0.5, 0.9999] {
        let s = bsdf.sample([u, 0.5, 0.5]).unwrap();
        assert!(s.wi.z < 0.0 && (s.f.g * s.wi.z.abs() / s.pdf_w - 1.0).abs() < 1e-5);
    }
}

#[test]
fn mirror_reflects_exactly() {
    let m = MaterialKind::Mirror {
        ks: Rgb::splat(0.8),
    };
    let wo = Vec3::new(0.3, -0.4, 0.866).normalize();
    let b = Bsdf::new(&m, Vec3::Z, wo, TransportMode::Radiance).unwrap();
    let s = b.sample([0.1, 0.2, 0.3]).unwrap();
    assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6 && s.delta);
    assert!((s.f.g * s.wi.z / s.pdf_w - 0.8).abs() < 1e-6);
    assert!(b.eval(s.wi).f.is_black());
}

/// With a shading normal the BSDF is one function of the two directions whichever side
/// builds it: the radiance BSDF seen from `c` (towards the camera) evaluated towards `l`
/// (towards the light) equals the importance BSDF seen from `l` evaluated towards `c`, pdfs
/// swapped, so eye and light sub-paths weigh a connection alike. Relative to the flat BSDF of
/// the shading frame, the radiance side carries |l.ns| / |l.ng|, the importance side Veach's
/// adjoint factor |wo.ng| |wi.ns| / (|wo.ns| |wi.ng|) once multiplied by |cos(ng, wi)|.
#[test]
fn shading_normals_keep_one_bsdf_for_both_sides() {
    use vmerge::bsdf::{Albedo, Normals};
    let ng = Vec3::Z;
    let ns = Vec3::new(0.3, -0.2, 0.9).normalize();
    let normals = Normals { ng, ns };
    let kinds = [
        MaterialKind::Lambert {
            kd: Rgb::splat(0.7),
        },
        phong(0.3, 0.4, 12.0),
    ];
    let dirs = [
        direction(0.3, 0.5),
        direction(1.1, 2.0),
        direction(0.8, 4.0),
        direction(1.45, 5.5),
    ];
    for kind in &kinds {
        let albedo = Albedo::of(kind);
        for &c in &dirs {
            for &l in &dirs {
                let eye = Bsdf::shaded(kind, albedo, normals, c, TransportMode::Radiance).unwrap();
                let light =
                    Bsdf::shaded(kind, albedo, normals, l, TransportMode::Importance).unwrap();
                let (e, i) = (eye.eval(l), light.eval(c));
                let tol = 1e-5 * e.f.max_component().max(1e-3);
                assert!(
                    (e.f - i.f).max_component().abs() <= tol,
                    "{kind:?}: {e:?} vs {i:?}"
                );
                assert!(
                    (i.f - e.f).max_component().abs() <= tol,
                    "{kind:?}: {e:?} vs {i:?}"
                );
                assert!((e.pdf_w - i.rev_pdf_w).abs() <= 1e-5 * e.pdf_w.max(1e-3));
                assert!((e.rev_pdf_w - i.pdf_w).abs() <= 1e-5 * e.pdf_w.max(1e-3));
                // The radiance side against the flat BSDF of the shading frame.
                let flat = Bsdf::new(kind, ns, c, TransportMode::Radiance)
                    .unwrap()
                    .eval(l);
                let factor = l.dot(ns).abs() / l.dot(ng).abs();
                let expected = flat.f * factor;
                assert!((e.f - expected).max_component().abs() <= tol.max(1e-6));
                assert!((expected - e.f).max_component().abs() <= tol.max(1e-6));
                assert_eq!(eye.cos_theta(l), l.dot(ng).abs());
            }
        }
    }
}

mod construction {
    use vmerge::bsdf::{BsdfError, EnergyFix, MaterialKind, ParamProblem, Params};
    use vmerge::color::Rgb;

    fn every_kind() -> [MaterialKind; 4] {
        [
            MaterialKind::Lambert {
                kd: Rgb::new(0.1, 0.2, 0.3),
            },
            MaterialKind::Phong {
                kd: Rgb::splat(0.4),
                ks: Rgb::new(0.5, 0.2, 0.1),
                exponent: 30.0,
            },
            MaterialKind::Mirror {
                ks: Rgb::splat(0.9),
            },
            MaterialKind::Glass { ior: 1.33 },
        ]
    }

    #[test]
    fn kinds_rebuild_from_their_name_and_parameters() {
        for kind in every_kind() {
            let name = kind.type_name();
            assert!(MaterialKind::TYPE_NAMES.contains(&name));
            assert_eq!(MaterialKind::from_params(name, &kind.params()), Ok(kind));
        }
    }

    #[test]
    fn absent_parameters_take_the_defaults() {
        let none = Params::new();
        for name in MaterialKind::TYPE_NAMES {
            let kind = MaterialKind::from_params(name, &none).unwrap();
            assert_eq!(kind.type_name(), *name);
            let expected = match *name {
                "lambert" => MaterialKind::Lambert {
                    kd: Rgb::splat(0.8),
                },
                "phong" => MaterialKind::Phong {
                    kd: Rgb::splat(0.8),
                    ks: Rgb::BLACK,
                    exponent: 1.0,
                },
                "mirror" => MaterialKind::Mirror { ks: Rgb::WHITE },
                "glass" => MaterialKind::Glass { ior: 1.5 },
                _ => continue,
            };
            assert_eq!(kind, expected);
        }
        // A number is a grey; parameters the type does not read are ignored.
        let p = Params::new()
            .with_number("kd", 0.25)
            .with_number("ior", 2.0);
        assert_eq!(
            MaterialKind::from_params("lambert", &p),
            Ok(MaterialKind::Lambert {
                kd: Rgb::splat(0.25)
            })
        );
    }

    #[test]
    fn errors_name_the_type_or_the_parameter() {
        let e = MaterialKind::from_params("velvet", &Params::new()).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "unknown material type 'velvet' ({})",
                MaterialKind::TYPE_NAMES.join(", ")
            )
        );
        assert!(e.to_string().contains("lambert, phong, mirror, glass"));
        let e = MaterialKind::from_params("glass", &Params::new().with_number("ior", 0.0));
        assert_eq!(
            e,
            Err(BsdfError::BadParameter {
                type_name: "glass",
                param: "ior",
                problem: ParamProblem::NotPositive
            })
        );
        let p = Params::new().with_color("exponent", Rgb::WHITE);
        assert!(matches!(
            MaterialKind::from_params("phong", &p),
            Err(BsdfError::BadParameter {
                problem: ParamProblem::NotANumber,
                ..
            })
        ));
        let p = Params::new().with_color("ks", Rgb::new(0.5, -0.1, 0.5));
        assert!(MaterialKind::from_params("mirror", &p).is_err());
        let p = Params::new().with_number("kd", f32::NAN);
        assert!(MaterialKind::from_params("lambert", &p).is_err());
    }

    #[test]
    fn energy_excess_scales_phong_and_clamps_single_reflectances() {
        for kind in every_kind() {
            assert_eq!(kind.energy_excess(), None);
        }
        let phong = MaterialKind::Phong {
            kd: Rgb::new(0.8, 0.5, 0.2),
            ks: Rgb::new(0.4, 0.2, 0.2),
            exponent: 10.0,
        };
        let e = phong.energy_excess().unwrap();
        assert_eq!((e.what, e.fix), ("kd + ks", EnergyFix::Scaled));
        let MaterialKind::Phong { kd, ks, exponent } = e.conserving else {
            panic!("{:?}", e.conserving)
        };
        assert_eq!(exponent, 10.0);
        let scale = 1.0 / (0.8f32 + 0.4);
        assert_eq!(kd, Rgb::new(0.8 * scale, 0.5, 0.2));
        assert_eq!(ks, Rgb::new(0.4 * scale, 0.2, 0.2));
        assert!(e.conserving.energy_excess().is_none());
        let lambert = MaterialKind::Lambert {
            kd: Rgb::new(1.5, 0.5, 1.0),
        };
        let e = lambert.energy_excess().unwrap();
        assert_eq!((e.what, e.fix), ("kd", EnergyFix::Clamped));
        assert_eq!(
            e.conserving,
            MaterialKind::Lambert {
                kd: Rgb::new(1.0, 0.5, 1.0)
            }
        );
    }

    #[test]
    fn textured_phong_keeps_kd_below_one_minus_ks() {
        let phong = MaterialKind::Phong {
            kd: Rgb::splat(0.5),
            ks: Rgb::splat(0.3),
            exponent: 10.0,
        };
        let a = phong.textured_albedo(Some(Rgb::splat(0.9)), None);
        assert_eq!((a.kd, a.ks), (Rgb::splat(0.7), Rgb::splat(0.3)));
        let a = phong.textured_albedo(Some(Rgb::splat(0.9)), Some(Rgb::splat(2.0)));
        assert_eq!((a.kd, a.ks), (Rgb::BLACK, Rgb::WHITE));
        let lambert = MaterialKind::Lambert { kd: Rgb::BLACK };
        let a = lambert.textured_albedo(Some(Rgb::new(0.9, 1.5, -1.0)), None);
        assert_eq!(a.kd, Rgb::new(0.9, 1.0, 0.0));
    }
}
