//! The acceptance estimator of UPG is unbiased: the mean of many estimates N/P matches 1/p_acc
//! integrated numerically (000 eqs. 2.57, 2.65) for lambert, Phong, Trowbridge-Reitz conductor
//! and dielectric lobes (reflected and refracted, from either side, isotropic and
//! anisotropic), the layered materials (rough and smooth coatings over diffuse and conductor
//! bases) and diffuse transmission, oblique and near-grazing targets, short distances, cones
//! as wide as the sphere allows and an occluder. Packets and single rays agree trial
//! for trial; the whole-lobe fallback is the BSDF's own sampling; the cap is reported; each lobe
//! shape's polar bound holds the probability of its interval.

use glam::{DVec3, Vec3};
use vmerge::accel::{Ray, PACKET};
use vmerge::bsdf::microfacet::Roughness;
use vmerge::bsdf::{Bsdf, LobeKind, MaterialKind, Params, TransportMode};
use vmerge::color::Rgb;
use vmerge::integrator::upg::acceptance::{
    AcceptanceError, AngularBound, Estimator, Outcome, PacketWidth, TentativeTracer,
};
use vmerge::sampling::{Rng, Stream};

const RADIUS: f64 = 0.05;

/// A scene of one (two-sided, infinite) target plane, the origin's own surface (the plane
/// z = 0, which a trial crossing it from an origin offset to the wrong side would hit), and
/// optionally a half-plane parallel to the target halfway to the origin,
/// `{q + s v + h u : h >= 0}`, shadowing the part of the disc with disc coordinate `u` beyond the
/// projection of its edge.
struct Planes {
    target: DVec3,
    normal: DVec3,
    occluder: Option<(DVec3, DVec3)>,
}

fn plane_t(ray: &Ray, point: DVec3, normal: DVec3) -> Option<f64> {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let denom = d.dot(normal);
    if denom == 0.0 {
        return None;
    }
    let t = (point - o).dot(normal) / denom;
    (t >= ray.tmin as f64 && t <= ray.tmax as f64).then_some(t)
}

impl TentativeTracer for Planes {
    fn closest(&self, ray: &Ray) -> Option<f32> {
        let target = plane_t(ray, self.target, self.normal);
        let occluder = self.occluder.and_then(|(q, u)| {
            let t = plane_t(ray, q, self.normal)?;
            let x = ray.origin.as_dvec3() + t * ray.dir.as_dvec3();
            ((x - q).dot(u) >= 0.0).then_some(t)
        });
        let own = plane_t(ray, DVec3::ZERO, DVec3::Z);
        [target, occluder, own]
            .into_iter()
            .flatten()
            .min_by(f64::total_cmp)
            .map(|t| t as f32)
    }

    fn closest8(&self, rays: &[Ray; PACKET], active: u8) -> [Option<f32>; PACKET] {
        std::array::from_fn(|i| {
            if active & (1 << i) != 0 {
                self.closest(&rays[i])
            } else {
                None
            }
        })
    }
}

#[derive(Clone)]
struct Config {
    name: &'static str,
    kind: MaterialKind,
    /// Polar angle of `wo` from the origin's normal (+z), azimuth 0.
    wo_deg: f64,
    /// Direction of the target from the origin: polar angle and azimuth.
    theta_deg: f64,
    phi_deg: f64,
    d_over_r: f64,
    /// Angle between the target plane's normal and the direction back to the origin.
    tilt_deg: f64,
    /// Disc coordinate (in radii) of the occluder's shadow edge; the disc beyond it is hidden.
    shadow_edge: Option<f64>,
}

fn lambert() -> MaterialKind {
    MaterialKind::Lambert {
        kd: Rgb::splat(0.8),
    }
}

fn phong(kd: f32, ks: f32, exponent: f32) -> MaterialKind {
    MaterialKind::Phong {
        kd: Rgb::splat(kd),
        ks: Rgb::splat(ks),
        exponent,
    }
}

fn conductor(alpha_x: f32, alpha_y: f32) -> MaterialKind {
    MaterialKind::Conductor {
        eta: Rgb::new(0.2, 0.9, 1.1),
        k: Rgb::new(3.9, 2.45, 2.14),
        roughness: Roughness {
            u: alpha_x,
            v: alpha_y,
            remap: false,
        },
    }
}

fn rough_dielectric(alpha: f32) -> MaterialKind {
    MaterialKind::Dielectric {
        eta: 1.5,
        roughness: Roughness {
            u: alpha,
            v: alpha,
            remap: false,
        },
    }
}

fn layered(type_name: &str, params: Params) -> MaterialKind {
    MaterialKind::from_params(type_name, &params).expect("valid parameters")
}

fn coated_diffuse(roughness: f32) -> MaterialKind {
    layered(
        "coateddiffuse",
        Params::new()
            .with_color("reflectance", Rgb::splat(0.6))
            .with_number("roughness", roughness),
    )
}

fn coated_conductor(interface: f32, conductor: f32) -> MaterialKind {
    layered(
        "coatedconductor",
        Params::new()
            .with_number("interface.roughness", interface)
            .with_number("conductor.roughness", conductor),
    )
}

fn cfg(
    name: &'static str,
    kind: MaterialKind,
    wo_deg: f64,
    (theta_deg, phi_deg): (f64, f64),
    d_over_r: f64,
    tilt_deg: f64,
) -> Config {
    Config {
        name,
        kind,
        wo_deg,
        theta_deg,
        phi_deg,
        d_over_r,
        tilt_deg,
        shadow_edge: None,
    }
}

fn spherical(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// The geometry of a configuration: origin at 0 on the plane z = 0; target point, target
/// plane normal, disc axes `(u, v)`.
struct Setup {
    target: DVec3,
    normal: DVec3,
    u: DVec3,
    v: DVec3,
}

fn setup(c: &Config) -> Setup {
    let dir = spherical(c.theta_deg, c.phi_deg);
    let target = dir * (c.d_over_r * RADIUS);
    let axis = dir.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
    let tilt = c.tilt_deg.to_radians();
    let back = -dir;
    let normal = back * tilt.cos() + axis.cross(back) * tilt.sin();
    let u = axis.cross(normal).normalize();
    let v = normal.cross(u);
    Setup {
        target,
        normal,
        u,
        v,
    }
}

fn planes(c: &Config, s: &Setup) -> Planes {
    let occluder = c.shadow_edge.map(|edge| {
        // Halfway between the origin and the shadow edge's point on the target plane, in a plane
        // parallel to it: its edge projects onto the line u = edge.
        let q = 0.5 * (s.target + s.u * (edge * RADIUS));
        (q, s.u)
    });
    Planes {
        target: s.target,
        normal: s.normal,
        occluder,
    }
}

fn bsdf(kind: &MaterialKind, wo_deg: f64) -> Bsdf<'_> {
    let wo = spherical(wo_deg, 0.0).as_vec3();
    Bsdf::new(kind, Vec3::Z, wo, TransportMode::Importance).expect("wo off the surface")
}

/// The scene of configuration `c` and the bound of its merge.
fn merge_of(c: &Config) -> (Planes, AngularBound<'_>) {
    let s = setup(c);
    let b = bsdf(&c.kind, c.wo_deg);
    let bound = AngularBound::new(Vec3::ZERO, Vec3::Z, &b, s.target.as_vec3(), RADIUS as f32)
        .expect("non-delta BSDF");
    (planes(c, &s), bound)
}

/// Single rays and packets of 8, both capped at `max_trials`.
fn both_widths(max_trials: u32) -> (Estimator, Estimator) {
    let single = Estimator {
        packet: PacketWidth::One,
        max_trials,
    };
    let eight = Estimator {
        packet: PacketWidth::Eight,
        ..single
    };
    (single, eight)
}

/// p_acc = integral over the visible disc of pdf_w(w) cos_disc / dist^2 dA (000 eq. 2.57), by
/// composite Gauss-Legendre in (s, w) with u = r sin s, v = r cos s w, which keeps the
/// integrand smooth up to the disc's rim and the shadow edge.
fn p_acc(c: &Config, s: &Setup, b: &Bsdf, panels: usize) -> f64 {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    // Nodes and weights of a composite 8-point rule on [a, b].
    let rule = |a: f64, b: f64| {
        let h = (b - a) / panels as f64;
        (0..panels).flat_map(move |p| {
            let mid = a + (p as f64 + 0.5) * h;
            (0..8).map(move |k| {
                let (x, w) = (X[k % 4] * if k < 4 { -1.0 } else { 1.0 }, W[k % 4]);
                (mid + 0.5 * h * x, 0.5 * h * w)
            })
        })
    };
    let s_max = c
        .shadow_edge
        .map_or(std::f64::consts::FRAC_PI_2, |e| e.clamp(-1.0, 1.0).asin());
    let mut sum = 0.0;
    for (sv, ws) in rule(-std::f64::consts::FRAC_PI_2, s_max) {
        let (sin_s, cos_s) = sv.sin_cos();
        for (w, ww) in rule(-1.0, 1.0) {
            let x = s.target + s.u * (RADIUS * sin_s) + s.v * (RADIUS * cos_s * w);
            let dist2 = x.length_squared();
            let dir = x / dist2.sqrt();
            let pdf = b.eval(dir.as_vec3()).pdf_w as f64;
            let cos_disc = dir.dot(s.normal).abs();
            sum += ws * ww * RADIUS * RADIUS * cos_s * cos_s * pdf * cos_disc / dist2;
        }
    }
    sum + delta_acceptance(s, b)
}

/// The share of p_acc from delta components (a smooth coating's mirror): each adds its weight
/// where its one direction meets the disc (the configurations with one have no occluder).
fn delta_acceptance(s: &Setup, b: &Bsdf) -> f64 {
    let mut sum = 0.0;
    for kind in b.lobes().as_slice() {
        if let LobeKind::Delta { weight, direction } = *kind {
            let d = direction.as_dvec3();
            let t = s.target.dot(s.normal) / d.dot(s.normal);
            if t > 0.0 && (d * t - s.target).length() <= RADIUS {
                sum += weight as f64;
            }
        }
    }
    sum
}

fn configs() -> Vec<Config> {
    let occluded = |mut c: Config, edge| {
        c.shadow_edge = Some(edge);
        c
    };
    vec![
        cfg(
            "lambert, normal target",
            lambert(),
            30.0,
            (0.0, 0.0),
            20.0,
            0.0,
        ),
        cfg(
            "lambert, oblique",
            lambert(),
            30.0,
            (50.0, 40.0),
            20.0,
            60.0,
        ),
        cfg(
            "lambert, grazing disc",
            lambert(),
            30.0,
            (30.0, 0.0),
            10.0,
            85.0,
        ),
        cfg(
            "lambert, target at horizon",
            lambert(),
            30.0,
            (88.0, 90.0),
            10.0,
            20.0,
        ),
        cfg("lambert, d = 3r", lambert(), 60.0, (40.0, 0.0), 3.0, 30.0),
        cfg("lambert, d = 1.5r", lambert(), 30.0, (20.0, 0.0), 1.5, 10.0),
        cfg("lambert, d = 0.5r", lambert(), 30.0, (0.0, 0.0), 0.5, 0.0),
        cfg(
            "lambert, below horizon",
            lambert(),
            30.0,
            (125.0, 0.0),
            1.15,
            55.0,
        ),
        cfg(
            "phong 1",
            phong(0.0, 0.8, 1.0),
            45.0,
            (45.0, 180.0),
            20.0,
            30.0,
        ),
        cfg(
            "phong 10",
            phong(0.0, 0.8, 10.0),
            45.0,
            (45.0, 180.0),
            20.0,
            30.0,
        ),
        cfg(
            "phong 100",
            phong(0.0, 0.8, 100.0),
            45.0,
            (45.0, 180.0),
            20.0,
            30.0,
        ),
        cfg(
            "phong 1000",
            phong(0.0, 0.8, 1000.0),
            45.0,
            (45.0, 180.0),
            20.0,
            30.0,
        ),
        cfg(
            "phong 1, wo normal",
            phong(0.0, 0.8, 1.0),
            0.0,
            (30.0, 0.0),
            5.0,
            0.0,
        ),
        cfg(
            "phong 100, wo 10",
            phong(0.0, 0.8, 100.0),
            10.0,
            (12.0, 170.0),
            30.0,
            0.0,
        ),
        cfg(
            "phong 100, off peak",
            phong(0.0, 0.8, 100.0),
            45.0,
            (55.0, 180.0),
            20.0,
            0.0,
        ),
        cfg(
            "phong 1000, wo 70",
            phong(0.0, 0.8, 1000.0),
            70.0,
            (71.0, 180.0),
            50.0,
            45.0,
        ),
        cfg(
            "phong 10, grazing",
            phong(0.0, 0.8, 10.0),
            80.0,
            (84.0, 180.0),
            10.0,
            60.0,
        ),
        cfg(
            "phong 1000, d = 4r",
            phong(0.0, 0.8, 1000.0),
            30.0,
            (32.0, 180.0),
            4.0,
            75.0,
        ),
        cfg(
            "mixture 10",
            phong(0.3, 0.5, 10.0),
            30.0,
            (30.0, 180.0),
            20.0,
            20.0,
        ),
        cfg(
            "mixture 100",
            phong(0.3, 0.5, 100.0),
            60.0,
            (50.0, 170.0),
            10.0,
            40.0,
        ),
        cfg(
            "mixture 1000, d = 3r",
            phong(0.3, 0.5, 1000.0),
            45.0,
            (45.0, 180.0),
            3.0,
            10.0,
        ),
        // Trowbridge-Reitz lobes: bounded by a rectangle of the visible-normal sampler's plane
        // (or sampled whole where that holds most of the lobe), refracted trials crossing the
        // surface from an origin offset to their own side.
        cfg(
            "rough conductor 0.3",
            conductor(0.3, 0.3),
            30.0,
            (35.0, 170.0),
            20.0,
            10.0,
        ),
        cfg(
            "anisotropic conductor",
            conductor(0.1, 0.4),
            60.0,
            (55.0, 190.0),
            10.0,
            30.0,
        ),
        cfg(
            "rough dielectric, refracted",
            rough_dielectric(0.3),
            40.0,
            (160.0, 180.0),
            20.0,
            20.0,
        ),
        cfg(
            "rough dielectric, reflected",
            rough_dielectric(0.2),
            50.0,
            (50.0, 180.0),
            10.0,
            0.0,
        ),
        cfg(
            "rough conductor 0.02",
            conductor(0.02, 0.02),
            40.0,
            (40.0, 180.0),
            50.0,
            0.0,
        ),
        cfg(
            "rough conductor 0.05, off peak",
            conductor(0.05, 0.05),
            60.0,
            (52.0, 172.0),
            30.0,
            20.0,
        ),
        cfg(
            "rough conductor 0.1, grazing",
            conductor(0.1, 0.1),
            80.0,
            (78.0, 180.0),
            20.0,
            40.0,
        ),
        cfg(
            "rough conductor 0.2, d = 2r",
            conductor(0.2, 0.2),
            30.0,
            (30.0, 180.0),
            2.0,
            0.0,
        ),
        cfg(
            "anisotropic conductor 0.05 x 0.3",
            conductor(0.05, 0.3),
            45.0,
            (45.0, 185.0),
            20.0,
            10.0,
        ),
        cfg(
            "rough dielectric 0.05, refracted",
            rough_dielectric(0.05),
            30.0,
            (160.5, 180.0),
            30.0,
            0.0,
        ),
        cfg(
            "rough dielectric 0.1, leaving",
            rough_dielectric(0.1),
            150.0,
            (48.6, 180.0),
            20.0,
            10.0,
        ),
        cfg(
            "rough dielectric 0.1, inside",
            rough_dielectric(0.1),
            150.0,
            (150.0, 180.0),
            20.0,
            0.0,
        ),
        // Layered materials: a rough top (visible normals) or a smooth one (a delta, counted
        // where its mirror direction meets the disc) beside the base's cosine lobe or its
        // conductor seen through the coating; diffuse transmission's two cosine lobes.
        cfg(
            "coated diffuse, rough top",
            coated_diffuse(0.01),
            40.0,
            (40.0, 180.0),
            30.0,
            0.0,
        ),
        cfg(
            "coated diffuse, smooth top",
            coated_diffuse(0.0),
            40.0,
            (30.0, 150.0),
            20.0,
            10.0,
        ),
        cfg(
            "coated diffuse, at the mirror",
            coated_diffuse(0.0),
            40.0,
            (40.0, 180.0),
            20.0,
            0.0,
        ),
        cfg(
            "coated conductor, rough on rough",
            coated_conductor(0.01, 0.04),
            35.0,
            (35.0, 180.0),
            30.0,
            0.0,
        ),
        cfg(
            "coated conductor, smooth top",
            coated_conductor(0.0, 0.04),
            35.0,
            (32.0, 177.0),
            30.0,
            10.0,
        ),
        cfg(
            "coated conductor, at the mirror",
            coated_conductor(0.0, 0.04),
            35.0,
            (35.0, 180.0),
            30.0,
            0.0,
        ),
        cfg(
            "coated conductor, smooth base",
            coated_conductor(0.01, 0.0),
            35.0,
            (37.0, 182.0),
            30.0,
            0.0,
        ),
        cfg(
            "diffuse transmission, through",
            layered(
                "diffusetransmission",
                Params::new()
                    .with_color("reflectance", Rgb::splat(0.3))
                    .with_color("transmittance", Rgb::splat(0.6)),
            ),
            30.0,
            (150.0, 40.0),
            20.0,
            10.0,
        ),
        occluded(
            cfg(
                "lambert, occluded",
                lambert(),
                30.0,
                (30.0, 0.0),
                10.0,
                20.0,
            ),
            0.3,
        ),
        occluded(
            cfg(
                "phong 100, occluded",
                phong(0.0, 0.8, 100.0),
                45.0,
                (45.0, 180.0),
                20.0,
                30.0,
            ),
            -0.2,
        ),
        // Cones as wide as the sphere allows (r close to d): the bound spans most of the
        // hemisphere, holds the lobe's axis or crosses the horizon, where a bound a little too
        // narrow would bias 1/p_acc low by a share that grows with r.
        cfg(
            "lambert, d = 1.25r, wide cone",
            lambert(),
            30.0,
            (75.0, 30.0),
            1.25,
            45.0,
        ),
        cfg(
            "lambert, d = 1.05r, at horizon",
            lambert(),
            50.0,
            (80.0, 200.0),
            1.05,
            10.0,
        ),
        cfg(
            "phong 10, d = 1.3r",
            phong(0.0, 0.8, 10.0),
            45.0,
            (60.0, 60.0),
            1.3,
            20.0,
        ),
        cfg(
            "phong 100, d = 1.5r, off peak",
            phong(0.0, 0.8, 100.0),
            45.0,
            (45.0, 90.0),
            1.5,
            30.0,
        ),
        cfg(
            "mixture 10, d = 1.3r",
            phong(0.3, 0.5, 10.0),
            30.0,
            (70.0, 30.0),
            1.3,
            15.0,
        ),
        cfg(
            "lambert, d = 1.5r, cone by the normal",
            lambert(),
            30.0,
            (45.0, 0.0),
            1.5,
            70.0,
        ),
        cfg(
            "phong 100, d = 1.5r, cone by the peak",
            phong(0.0, 0.8, 100.0),
            45.0,
            (0.0, 0.0),
            1.5,
            70.0,
        ),
        cfg(
            "rough conductor 0.1, d = 1.3r",
            conductor(0.1, 0.1),
            30.0,
            (50.0, 120.0),
            1.3,
            10.0,
        ),
    ]
}

#[test]
fn mean_estimate_is_the_reciprocal_acceptance_probability() {
    const ESTIMATES: usize = 20_000;
    let (estimator, _) = both_widths(1_000_000);
    let mut failures = Vec::new();
    for (index, c) in configs().iter().enumerate() {
        let s = setup(c);
        let b = bsdf(&c.kind, c.wo_deg);
        let coarse = p_acc(c, &s, &b, 32);
        let exact = p_acc(c, &s, &b, 64);
        assert!(
            (coarse - exact).abs() < 1e-4 * exact,
            "{}: quadrature not converged ({coarse} vs {exact})",
            c.name
        );
        let expected = 1.0 / exact;
        let (tracer, bound) = merge_of(c);
        let mut rng = Rng::for_sample(11, index as u64, 0, Stream::Tentative);
        let (mut sum, mut sum2, mut trials) = (0.0f64, 0.0f64, 0u64);
        for _ in 0..ESTIMATES {
            let e = estimator.estimate(&tracer, &bound, &mut rng);
            let value = e.inv_p_acc().expect("never capped") as f64;
            sum += value;
            sum2 += value * value;
            trials += e.trials as u64;
        }
        let n = ESTIMATES as f64;
        let mean = sum / n;
        let se = ((sum2 / n - mean * mean) * n / (n - 1.0) / n).sqrt();
        let z = (mean - expected) / se;
        println!(
            "{:28} P {:9.3e}  1/p_acc {:11.5e}  mean {:11.5e}  se {:5.2}%  z {:+5.2}  trials {:6.2}",
            c.name,
            bound.p_bound(),
            expected,
            mean,
            100.0 * se / expected,
            z,
            trials as f64 / n
        );
        if z.abs() > 3.0 || se > 0.01 * expected {
            failures.push(c.name);
        }
    }
    assert!(failures.is_empty(), "biased or too noisy: {failures:?}");
}

/// Without its delta components the bound stands for the other lobes alone (`upg` gathers no
/// light vertex reached through a mirror): at a smooth coating's mirror direction the mean
/// estimate is 1/p_acc of the lobes under it, the mirror's share left out.
#[test]
fn without_delta_leaves_the_mirror_out() {
    const ESTIMATES: usize = 20_000;
    let (estimator, _) = both_widths(1_000_000);
    let at_mirror: Vec<Config> = configs()
        .into_iter()
        .filter(|c| c.name.ends_with("at the mirror"))
        .collect();
    assert!(!at_mirror.is_empty());
    for (index, c) in at_mirror.iter().enumerate() {
        let s = setup(c);
        let b = bsdf(&c.kind, c.wo_deg);
        let (all, mirror) = (p_acc(c, &s, &b, 64), delta_acceptance(&s, &b));
        assert!(mirror > 0.1 * all, "{}: the mirror misses the disc", c.name);
        let expected = 1.0 / (all - mirror);
        let (tracer, bound) = merge_of(c);
        let bound = bound.without_delta();
        let mut rng = Rng::for_sample(12, index as u64, 0, Stream::Tentative);
        let values: Vec<f64> = (0..ESTIMATES)
            .map(|_| {
                let e = estimator.estimate(&tracer, &bound, &mut rng);
                e.inv_p_acc().expect("never capped") as f64
            })
            .collect();
        let n = ESTIMATES as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let se = (var / n).sqrt();
        println!(
            "{:28} 1/p_acc without the mirror {expected:11.5e}  mean {mean:11.5e}  se {:5.2}%",
            c.name,
            100.0 * se / expected
        );
        assert!(se < 0.01 * expected, "{}: too noisy (se {se})", c.name);
        assert!(
            (mean - expected).abs() <= 3.0 * se,
            "{}: mean {mean}, expected {expected} (se {se})",
            c.name
        );
    }
}

#[test]
fn packets_and_single_rays_give_the_same_estimates() {
    for (index, c) in configs().iter().enumerate() {
        let (tracer, bound) = merge_of(c);
        // A small cap not a multiple of 8 exercises the last, partial packet.
        for max_trials in [1_000_000, 13] {
            let (single, eight) = both_widths(max_trials);
            for seed in 0..200 {
                let mut a = Rng::for_sample(seed, index as u64, 1, Stream::Tentative);
                let mut b = a.clone();
                let one = single.estimate(&tracer, &bound, &mut a);
                let many = eight.estimate(&tracer, &bound, &mut b);
                assert_eq!(one.outcome, many.outcome, "{}, seed {seed}", c.name);
                assert_eq!(one.trials, many.trials, "{}, seed {seed}", c.name);
                assert!(one.rays <= many.rays && many.rays <= one.trials.next_multiple_of(8));
            }
        }
    }
}

/// Packets over several merges at once (lanes filled from all of them, as a gather does) give
/// each merge the estimate it gets alone; an unreachable merge in the batch is reported as such.
#[test]
fn packets_over_many_merges_give_each_its_own_estimate() {
    let lambert = lambert();
    let lambert = bsdf(&lambert, 30.0);
    let unreachable = AngularBound::new(
        Vec3::ZERO,
        Vec3::Z,
        &lambert,
        Vec3::new(0.3, 0.0, -1.0),
        RADIUS as f32,
    )
    .expect("lambert");
    assert_eq!(unreachable.p_bound(), 0.0);
    for (index, c) in configs().iter().enumerate() {
        let (tracer, bound) = merge_of(c);
        for size in [2, 5, 19] {
            let bounds: Vec<_> = (0..size)
                .map(|i| if i == 1 { &unreachable } else { &bound }.clone())
                .collect();
            for max_trials in [1_000_000, 13] {
                let (single, eight) = both_widths(max_trials);
                let rngs = |seed: u64| -> Vec<Rng> {
                    (0..size)
                        .map(|i| Rng::for_sample(seed, index as u64, i as u64, Stream::Tentative))
                        .collect()
                };
                for seed in 0..20 {
                    let mut alone = rngs(seed);
                    let expected: Vec<_> = bounds
                        .iter()
                        .zip(&mut alone)
                        .map(|(bound, rng)| single.estimate(&tracer, bound, rng))
                        .collect();
                    let mut got = vec![None; size];
                    eight.estimate_all(&tracer, &bounds, &mut rngs(seed), |i, e| {
                        assert!(got[i].replace(e).is_none(), "merge {i} estimated twice");
                    });
                    for (i, (e, g)) in expected.iter().zip(&got).enumerate() {
                        let g = g.unwrap_or_else(|| panic!("{}: merge {i} not estimated", c.name));
                        assert_eq!(e.outcome, g.outcome, "{}, seed {seed}, merge {i}", c.name);
                        assert_eq!(e.trials, g.trials, "{}, seed {seed}, merge {i}", c.name);
                        assert!(e.rays <= g.rays, "{}, seed {seed}, merge {i}", c.name);
                    }
                    assert_eq!(got[1].map(|e| e.outcome), Some(Outcome::Unreachable));
                }
            }
        }
    }
}

#[test]
fn whole_lobe_fallback_is_the_bsdf_sampling() {
    let kinds = [lambert(), phong(0.0, 0.8, 20.0), phong(0.3, 0.5, 100.0)];
    for kind in &kinds {
        for wo_deg in [0.0, 40.0, 85.0] {
            let b = bsdf(kind, wo_deg);
            // The origin inside the r-sphere, and a sphere covering most of the hemisphere.
            for (target, radius) in [(Vec3::new(0.0, 0.0, 0.02), 0.05), (Vec3::Z, 0.999)] {
                let bound = AngularBound::new(Vec3::ZERO, Vec3::Z, &b, target, radius)
                    .expect("non-delta BSDF");
                assert!(bound.is_whole());
                assert_eq!(bound.p_bound(), 1.0);
                let mut rng = Rng::for_sample(3, 0, 0, Stream::Tentative);
                for _ in 0..10_000 {
                    let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                    assert_eq!(bound.sample_direction(u), b.sample(u).map(|s| s.wi));
                }
            }
        }
    }
}

#[test]
fn capped_estimates_are_reported() {
    // The occluder hides the whole disc: p_acc = 0 while P > 0.
    let mut c = cfg("hidden", lambert(), 30.0, (30.0, 0.0), 10.0, 20.0);
    c.shadow_edge = Some(-2.0);
    let s = setup(&c);
    let b = bsdf(&c.kind, c.wo_deg);
    let tracer = planes(&c, &s);
    let bound = AngularBound::new(Vec3::ZERO, Vec3::Z, &b, s.target.as_vec3(), RADIUS as f32)
        .expect("non-delta BSDF");
    assert!(bound.p_bound() > 0.0);
    for packet in [PacketWidth::One, PacketWidth::Eight] {
        for max_trials in [13, 10_000] {
            let estimator = Estimator { packet, max_trials };
            let mut rng = Rng::for_sample(5, 0, 0, Stream::Tentative);
            let e = estimator.estimate(&tracer, &bound, &mut rng);
            assert_eq!(e.outcome, Outcome::Capped);
            assert!(e.capped() && e.inv_p_acc().is_none());
            assert_eq!(e.trials, max_trials);
            assert!(e.rays > 0 && e.rays <= max_trials);
        }
    }
}

#[test]
fn unreachable_targets_and_invalid_inputs() {
    let kind = lambert();
    let b = bsdf(&kind, 30.0);
    let below = Vec3::new(0.3, 0.0, -1.0);
    let bound = AngularBound::new(Vec3::ZERO, Vec3::Z, &b, below, 0.05).expect("lambert");
    assert_eq!(bound.p_bound(), 0.0);
    let tracer = Planes {
        target: below.as_dvec3(),
        normal: DVec3::Z,
        occluder: None,
    };
    let e = Estimator::default().estimate(&tracer, &bound, &mut Rng::from_seed(1, 1));
    assert_eq!((e.outcome, e.trials, e.rays), (Outcome::Unreachable, 0, 0));

    for radius in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(
            AngularBound::new(Vec3::ZERO, Vec3::Z, &b, Vec3::Z, radius),
            Err(AcceptanceError::InvalidRadius(_))
        ));
    }
    for delta in [
        MaterialKind::Mirror { ks: Rgb::WHITE },
        MaterialKind::Glass { ior: 1.5 },
    ] {
        let d = bsdf(&delta, 30.0);
        assert_eq!(
            AngularBound::new(Vec3::ZERO, Vec3::Z, &d, Vec3::Z, 0.05).err(),
            Some(AcceptanceError::DeltaBsdf)
        );
    }
    assert_eq!(PacketWidth::try_from(8), Ok(PacketWidth::Eight));
    assert_eq!(
        PacketWidth::try_from(4),
        Err(AcceptanceError::PacketWidth(4))
    );
}

/// The bound depends on the shape of the lobes alone, never on the albedo that scales them: a
/// textured lambert surface has the same bound, P and trial directions at every albedo, and so
/// does Phong wherever kd and ks keep their ratio (the lobes' weights). Textures therefore need
/// nothing of UPG: the albedo only scales the merge's value.
#[test]
fn the_bound_depends_on_the_lobe_shape_only() {
    use vmerge::bsdf::{Albedo, Normals};
    let target = Vec3::new(0.3, 0.1, 0.8);
    let wo = spherical(35.0, 0.0).as_vec3();
    let ns = Vec3::new(0.2, -0.1, 1.0).normalize();
    let cases = [
        (lambert(), [(0.05, 0.0), (0.5, 0.0), (0.95, 0.0)]),
        (
            phong(0.3, 0.2, 20.0),
            [(0.06, 0.04), (0.3, 0.2), (0.54, 0.36)],
        ),
    ];
    for (kind, albedos) in &cases {
        for normals in [Normals::flat(Vec3::Z), Normals { ng: Vec3::Z, ns }] {
            let trials = |(kd, ks): (f32, f32)| {
                let albedo = Albedo {
                    kd: Rgb::splat(kd),
                    ks: Rgb::splat(ks),
                    roughness: None,
                    vroughness: None,
                };
                let b = Bsdf::shaded(kind, albedo, normals, wo, TransportMode::Importance).unwrap();
                let bound = AngularBound::new(Vec3::ZERO, Vec3::Z, &b, target, 0.05).unwrap();
                let mut rng = Rng::for_sample(3, 0, 0, Stream::Light);
                let dirs: Vec<Option<Vec3>> = (0..64)
                    .map(|_| {
                        bound.sample_direction([rng.next_f32(), rng.next_f32(), rng.next_f32()])
                    })
                    .collect();
                (bound.p_bound(), dirs)
            };
            let first = trials(albedos[0]);
            assert!(first.0 > 0.0 && first.0 < 1.0, "{kind:?}: P = {}", first.0);
            for &a in &albedos[1..] {
                assert_eq!(trials(a), first, "{kind:?} {normals:?}: albedo {a:?}");
            }
        }
    }
}

/// Each lobe shape's polar bound holds the probability its pdf integrates to over the interval,
/// and its sampler stays inside and follows the polar CDF.
#[test]
fn polar_bounds_hold_the_lobe_probability() {
    use vmerge::bsdf::{LobeShape, PolarInterval};
    let (theta0, theta1) = (0.3f64, 0.7f64);
    let interval = PolarInterval {
        cos0: theta0.cos(),
        sin0: theta0.sin(),
        cos1: theta1.cos(),
        sin1: theta1.sin(),
        sin_width: None,
    };
    let narrow = PolarInterval {
        sin_width: Some((theta1 - theta0).sin()),
        ..interval
    };
    for (shape, pdf) in [
        (
            LobeShape::Cosine,
            Box::new(|c: f64| c / std::f64::consts::PI) as Box<dyn Fn(f64) -> f64>,
        ),
        (
            LobeShape::PowerCosine { exponent: 10.0 },
            Box::new(|c: f64| 11.0 / (2.0 * std::f64::consts::PI) * c.powi(10)),
        ),
    ] {
        // Midpoint rule over theta of pdf(theta) sin(theta) 2 pi.
        let steps = 100_000;
        let h = (theta1 - theta0) / steps as f64;
        let integral: f64 = (0..steps)
            .map(|i| {
                let t = theta0 + (i as f64 + 0.5) * h;
                pdf(t.cos()) * t.sin() * 2.0 * std::f64::consts::PI * h
            })
            .sum();
        let bound = shape.polar_bound(&interval);
        assert!(
            (bound.mass() - integral).abs() < 1e-9,
            "{shape:?}: {} vs {integral}",
            bound.mass()
        );
        let narrow_mass = shape.polar_bound(&narrow).mass();
        assert!((narrow_mass - integral).abs() < 1e-9, "{shape:?}");
        // The CDF at the middle angle, against the share of a grid of u below it.
        let mid = 0.5 * (theta0 + theta1);
        let below: f64 = (0..steps / 2)
            .map(|i| {
                let t = theta0 + (i as f64 + 0.5) * h;
                pdf(t.cos()) * t.sin() * 2.0 * std::f64::consts::PI * h
            })
            .sum::<f64>()
            / integral;
        let n = 10_000;
        let mut count = 0;
        for i in 0..n {
            let (c, s) = bound.sample((i as f32 + 0.5) / n as f32);
            assert!((c * c + s * s - 1.0).abs() < 1e-9);
            let t = s.atan2(c);
            assert!(t >= theta0 - 1e-6 && t <= theta1 + 1e-6, "{shape:?}: {t}");
            count += (t < mid) as u32;
        }
        let share = count as f64 / n as f64;
        assert!(
            (share - below).abs() < 2e-3,
            "{shape:?}: {share} vs {below}"
        );
    }
}

/// A merge across a corner connects the vertex before the photon with an eye vertex in its
/// own plane: on the bumpy floor of tests/fixtures/bumpy-floor (an axis-aligned plane whose
/// vertex normals lean 20 degrees) both BSDFs can see that in-plane direction while the
/// geometric cosines are exactly 0. Such a connection carries nothing; UPG from either side
/// must render the floor without a single non-finite sample (it dropped 16 and 38 in 16
/// iterations when the zero cosines reached the MIS quantities).
#[test]
fn merges_in_a_shaded_plane_give_finite_samples() {
    use vmerge::accel::AccelKind;
    use vmerge::integrator::RenderContext;
    use vmerge::options::{RenderOptions, SamplerKind, Technique};
    use vmerge::render::create_integrator;
    use vmerge::scene::{self, Camera, LoadOptions};
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/bumpy-floor/scene.toml"
    );
    let options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    };
    let scene = scene::load(path.as_ref(), &options).unwrap_or_else(|e| panic!("{e}"));
    for technique in [Technique::Upg, Technique::UpgCamera] {
        let options = RenderOptions {
            technique,
            resolution: Some([32, 32]),
            radius: Some(0.05),
            max_path_length: Some(6),
            sampler: SamplerKind::Independent,
            ..Default::default()
        };
        let camera = Camera::new(scene.camera(None).unwrap(), 32, 32);
        let mut integrator = create_integrator(RenderContext {
            scene: &scene,
            camera,
            options: &options,
        });
        let mut frame = vec![Rgb::BLACK; 32 * 32];
        let mut dropped = 0;
        let mut sum = 0.0;
        for iteration in 0..32 {
            frame.fill(Rgb::BLACK);
            dropped += integrator
                .render_iteration(iteration, &mut frame)
                .dropped_samples;
            sum += frame.iter().map(|c| c.average() as f64).sum::<f64>();
        }
        assert!(sum > 0.0, "{technique:?}: a black image");
        assert_eq!(dropped, 0, "{technique:?}: non-finite samples dropped");
    }
}
