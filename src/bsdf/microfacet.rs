//! The Trowbridge-Reitz (GGX) microfacet distribution, isotropic or anisotropic, as pbrt-v4
//! uses it: the normal distribution D, Smith's height-correlated masking-shadowing G, and the
//! distribution of visible normals with Heitz's (2018) sampler. Everything is in the local
//! shading frame, z up.

use super::fresnel;
use super::params::{number, BsdfError, ParamRange, ParamReader, ParamSpec, Params};
use crate::sampling;
use glam::{DVec3, Vec3};
use std::f32::consts::PI;

/// Below this alpha on both axes a surface is a delta (pbrt-v4's threshold): the lobe is far
/// narrower than any pixel sees, and f32 no longer represents D.
const SMOOTH_ALPHA: f32 = 1e-3;

/// The Trowbridge-Reitz distribution of microfacet normals, with roughness `alpha_x` along
/// the frame's x axis and `alpha_y` along y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrowbridgeReitz {
    pub alpha_x: f32,
    pub alpha_y: f32,
}

impl TrowbridgeReitz {
    /// A distribution with these alphas; alphas below 1e-4 are raised to it (pbrt-v4's
    /// floor), where D and its sampler stay finite.
    pub fn new(alpha_x: f32, alpha_y: f32) -> Self {
        TrowbridgeReitz {
            alpha_x: alpha_x.max(1e-4),
            alpha_y: alpha_y.max(1e-4),
        }
    }

    /// pbrt-v4's `remaproughness`: a user's perceptually linear roughness to alpha.
    pub fn roughness_to_alpha(roughness: f32) -> f32 {
        roughness.max(0.0).sqrt()
    }

    /// So narrow that the surface is treated as perfectly smooth (a delta lobe).
    pub fn effectively_smooth(&self) -> bool {
        self.alpha_x.max(self.alpha_y) < SMOOTH_ALPHA
    }

    /// The density of microfacet normals `wm` (unit) per projected solid angle: D(wm) with
    /// the integral of D(wm) cos(theta_m) over the hemisphere equal to 1. Symmetric in the
    /// sign of `wm.z`.
    pub fn d(&self, wm: Vec3) -> f32 {
        // 1 / (pi ax ay cos^4 (1 + tan^2 (cos^2 phi / ax^2 + sin^2 phi / ay^2))^2), written
        // without angles: the denominator is (z^2 + x^2/ax^2 + y^2/ay^2)^2 for a unit wm.
        if wm.z == 0.0 {
            return 0.0;
        }
        let x = wm.x / self.alpha_x;
        let y = wm.y / self.alpha_y;
        let s = x * x + y * y + wm.z * wm.z;
        1.0 / (PI * self.alpha_x * self.alpha_y * s * s)
    }

    /// Smith's auxiliary function Lambda(w): G1(w) = 1 / (1 + Lambda(w)).
    pub fn lambda(&self, w: Vec3) -> f32 {
        let z2 = w.z * w.z;
        if z2 == 0.0 {
            return f32::INFINITY;
        }
        // alpha^2(phi) tan^2(theta) = (ax^2 x^2 + ay^2 y^2) / z^2.
        let a2t2 = ((self.alpha_x * w.x).powi(2) + (self.alpha_y * w.y).powi(2)) / z2;
        // (sqrt(1 + a) - 1) / 2 = a / (2 (sqrt(1 + a) + 1)), which keeps its digits at small a.
        a2t2 / (2.0 * ((1.0 + a2t2).sqrt() + 1.0))
    }

    /// The fraction of microfacets visible from `w`.
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing of `wo` and `wi` (pbrt-v4; Heitz 2014).
    pub fn g(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// The density of visible normals from `w` per solid angle of `wm` (upper hemisphere):
    /// D_w(wm) = G1(w) / |cos theta| D(wm) max(0, w . wm), what [`Self::sample_wm`] samples.
    /// A `w` below the surface is taken as flipped up, as the sampler takes it.
    pub fn pdf(&self, w: Vec3, wm: Vec3) -> f32 {
        let cos = w.z.abs();
        let visible = w.dot(wm) * w.z.signum();
        if cos == 0.0 || visible <= 0.0 {
            return 0.0;
        }
        self.g1(w) / cos * self.d(wm) * visible
    }

    /// A microfacet normal visible from `w` (either hemisphere; the result is in the upper
    /// one, on the side `w` sees when `w` is flipped up), drawn from D_w by Heitz's (2018)
    /// sampler: stretch to the unit-roughness configuration, sample the projected hemisphere,
    /// unstretch.
    pub fn sample_wm(&self, w: Vec3, u: [f32; 2]) -> Vec3 {
        let normals = VisibleNormals::new(self, w);
        normals.lift(normals.point(u))
    }
}

/// Heitz's (2018) sampler of the normals visible from one direction, in its two steps: a
/// point uniform on the hemisphere of unit roughness projected along the stretched direction
/// `wh` (a half disk and half an ellipse), and the normal that point lifts to. Uniform density
/// on that region is what makes the normals follow D_w; a sampler confined to part of them
/// (UPG's tentative rays) draws its points uniformly from a smaller region instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VisibleNormals {
    alpha_x: f32,
    alpha_y: f32,
    wh: Vec3,
    t1: Vec3,
    t2: Vec3,
}

impl VisibleNormals {
    /// The normals of `m` visible from `w` (flipped up when below the surface).
    pub fn new(m: &TrowbridgeReitz, w: Vec3) -> Self {
        let mut wh = Vec3::new(m.alpha_x * w.x, m.alpha_y * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            Vec3::Z.cross(wh).normalize()
        } else {
            Vec3::X
        };
        VisibleNormals {
            alpha_x: m.alpha_x,
            alpha_y: m.alpha_y,
            wh,
            t1,
            t2: wh.cross(t1),
        }
    }

    /// The sampler's point for `u`: a uniform point on the unit disk, its lower half squeezed
    /// onto the visible part.
    pub fn point(&self, u: [f32; 2]) -> [f32; 2] {
        let r = u[0].sqrt();
        let (sin_phi, cos_phi) = sampling::sin_cos_turn(u[1]);
        let px = r * cos_phi;
        let h = (1.0 - px * px).max(0.0).sqrt();
        let s = 0.5 * (1.0 + self.wh.z);
        [px, (1.0 - s) * h + s * (r * sin_phi)]
    }

    /// Whether `p` lies in the region [`Self::point`] covers: the unit disk above
    /// y = -wh.z sqrt(1 - x^2).
    pub fn contains(&self, p: [f32; 2]) -> bool {
        let rest = 1.0 - p[0] * p[0];
        rest >= 0.0 && p[1] * p[1] <= rest && p[1] >= -self.wh.z * rest.sqrt()
    }

    /// The area of that region, pi (1 + wh.z) / 2: the points' density is its inverse.
    pub fn area(&self) -> f64 {
        std::f64::consts::FRAC_PI_2 * (1.0 + self.wh.z as f64)
    }

    /// The microfacet normal of the point `p`.
    pub fn lift(&self, p: [f32; 2]) -> Vec3 {
        let [px, py] = p;
        let pz = (1.0 - px * px - py * py).max(0.0).sqrt();
        let nh = self.t1 * px + self.t2 * py + self.wh * pz;
        Vec3::new(self.alpha_x * nh.x, self.alpha_y * nh.y, nh.z.max(1e-6)).normalize()
    }

    /// The point a normal `wm` lifts from (the inverse of [`Self::lift`]), in f64, with the
    /// stretched normal it passes through.
    pub fn project(&self, wm: DVec3) -> ([f64; 2], DVec3) {
        let nh =
            DVec3::new(wm.x / self.alpha_x as f64, wm.y / self.alpha_y as f64, wm.z).normalize();
        ([nh.dot(self.t1.as_dvec3()), nh.dot(self.t2.as_dvec3())], nh)
    }

    /// A bound on how far the stretched normal moves per radian that `wm` moves, for every
    /// unit `wm` at least `min_polar_sin` away from the z axis (by the sine of its polar angle
    /// from +z or -z). The stretch is normalize(A wm) with A = diag(1 / alpha_x,
    /// 1 / alpha_y, 1): its derivative is at most |A| / |A wm|, and |A wm|^2 is at least
    /// cos^2 + s sin^2 with s the smaller of 1 / alpha^2.
    pub fn stretch_lipschitz(&self, min_polar_sin: f64) -> f64 {
        let inv = |a: f32| 1.0 / a as f64;
        let largest = inv(self.alpha_x).max(inv(self.alpha_y)).max(1.0);
        let s = inv(self.alpha_x).min(inv(self.alpha_y)).powi(2);
        let sin2 = min_polar_sin * min_polar_sin;
        let least2 = if s >= 1.0 { 1.0 + sin2 * (s - 1.0) } else { s };
        largest / least2.sqrt()
    }
}

/// What a microfacet BSDF's sampler makes of the normal it drew: the sampler of the BSDF and
/// the bounded sampler of UPG's tentative rays call the same rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scatter {
    /// Mirror reflection about `wm` (a conductor), both directions above the surface.
    Reflect,
    /// Reflection with probability F(wo . wm), else refraction into the other side, `eta`
    /// being the index inside over outside.
    Dielectric { eta: f32 },
    /// Reflection about `wm` under a flat coating of index `eta`: `wo` refracts in, reflects,
    /// and refracts out (a coated conductor's base; the normals are those visible from the
    /// refracted `wo`).
    UnderCoating { eta: f32 },
}

impl Scatter {
    /// The direction `wi` from `wo` through the normal `wm`, `u` uniform choosing reflection
    /// or refraction; `None` where the sample falls on the wrong side (or refraction is
    /// total internal reflection).
    pub fn apply(&self, wo: Vec3, wm: Vec3, u: f32) -> Option<Vec3> {
        match *self {
            Scatter::Reflect => {
                let wi = reflect(wo, wm);
                (wo.z > 0.0 && wi.z > 0.0).then_some(wi)
            }
            Scatter::Dielectric { eta } => {
                let r = fresnel::dielectric(wo.dot(wm), eta);
                if u < r {
                    let wi = reflect(wo, wm);
                    (wi.z * wo.z > 0.0).then_some(wi)
                } else {
                    let (wi, _) = fresnel::refract(wo, wm, eta)?;
                    (wi.z * wo.z < 0.0).then_some(wi)
                }
            }
            Scatter::UnderCoating { eta } => {
                let inner = fresnel::into_layer(wo, eta);
                let reflected = 2.0 * inner.dot(wm) * wm - inner;
                if reflected.z <= 0.0 {
                    return None;
                }
                fresnel::out_of_layer(reflected, eta)
            }
        }
    }

    /// The direction the normals are drawn as seen from: `wo`, or under a coating its
    /// refraction into it.
    pub fn seen_from(&self, wo: Vec3) -> Vec3 {
        match *self {
            Scatter::UnderCoating { eta } => fresnel::into_layer(wo, eta),
            Scatter::Reflect | Scatter::Dielectric { .. } => wo,
        }
    }

    /// Whether it can refract: sampled directions may lie on either side.
    pub fn transmits(&self) -> bool {
        matches!(self, Scatter::Dielectric { .. })
    }
}

/// A surface's roughness as scene files give it (pbrt-v4's parameters): `u` along the shading
/// frame's x axis, `v` along y, each remapped to alpha by [`TrowbridgeReitz::roughness_to_alpha`]
/// when `remap` (`remaproughness`) is set, taken as alpha otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roughness {
    pub u: f32,
    pub v: f32,
    pub remap: bool,
}

impl Roughness {
    /// The parameters [`Roughness::read`] reads: `roughness` for both axes, `uroughness` and
    /// `vroughness` in its place where given, `remaproughness` 1 (true) or 0.
    pub const PARAMS: [ParamSpec; 4] = [
        number("roughness", 0.0, ParamRange::NonNegative),
        number("uroughness", 0.0, ParamRange::NonNegative),
        number("vroughness", 0.0, ParamRange::NonNegative),
        number("remaproughness", 1.0, ParamRange::NonNegative),
    ];

    pub(super) fn read(p: &ParamReader) -> Result<Self, BsdfError> {
        let r = p.number("roughness")?;
        let axis = |name| -> Result<f32, BsdfError> {
            if p.is_given(name) {
                p.number(name)
            } else {
                Ok(r)
            }
        };
        Ok(Roughness {
            u: axis("uroughness")?,
            v: axis("vroughness")?,
            remap: p.number("remaproughness")? != 0.0,
        })
    }

    pub(super) fn write(&self, params: Params) -> Params {
        params
            .with_number("uroughness", self.u)
            .with_number("vroughness", self.v)
            .with_number("remaproughness", if self.remap { 1.0 } else { 0.0 })
    }

    /// The same roughness on both axes where a texture gives `texel`.
    pub fn textured(self, texel: Option<f32>) -> Self {
        match texel {
            Some(r) => Roughness {
                u: r.max(0.0),
                v: r.max(0.0),
                ..self
            },
            None => self,
        }
    }

    pub fn distribution(&self) -> TrowbridgeReitz {
        let alpha = |r: f32| {
            if self.remap {
                TrowbridgeReitz::roughness_to_alpha(r)
            } else {
                r
            }
        };
        TrowbridgeReitz::new(alpha(self.u), alpha(self.v))
    }
}

/// Mirror reflection of `w` about the unit normal `n`.
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_points(n: usize) -> impl Iterator<Item = Vec3> {
        // A Fibonacci sphere: even coverage without a random stream.
        (0..n).map(move |i| {
            let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f32 * 2.399_963;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
    }

    /// Midpoint quadrature over the upper hemisphere in (cos theta, phi), f64.
    fn hemisphere_integral(f: impl Fn(Vec3) -> f64, n: usize) -> f64 {
        let mut sum = 0.0;
        for i in 0..n {
            let z = (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            for j in 0..2 * n {
                let phi = (j as f64 + 0.5) / (2 * n) as f64 * std::f64::consts::TAU;
                let w = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                sum += f(w);
            }
        }
        sum * std::f64::consts::TAU / (2 * n * n) as f64
    }

    #[test]
    fn projected_area_of_the_normals_is_one() {
        for (ax, ay) in [(0.3, 0.3), (0.6, 0.15), (1.0, 1.0)] {
            let m = TrowbridgeReitz::new(ax, ay);
            let total = hemisphere_integral(|wm| m.d(wm) as f64 * wm.z as f64, 800);
            assert!((total - 1.0).abs() < 2e-3, "{ax} {ay}: {total}");
        }
    }

    #[test]
    fn visible_normal_pdf_integrates_to_one() {
        let m = TrowbridgeReitz::new(0.4, 0.2);
        for w in [
            Vec3::Z,
            Vec3::new(0.6, 0.0, 0.8),
            Vec3::new(-0.3, 0.9, 0.3).normalize(),
        ] {
            let total = hemisphere_integral(|wm| m.pdf(w, wm) as f64, 800);
            assert!((total - 1.0).abs() < 2e-3, "{w}: {total}");
        }
    }

    #[test]
    fn sampled_normals_face_up_and_follow_the_visible_density() {
        let m = TrowbridgeReitz::new(0.5, 0.25);
        let w = Vec3::new(0.5, -0.4, 0.3).normalize();
        // The mean of wm.z under D_w, sampled against quadrature.
        let n = 200;
        let mut mean = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32];
                let wm = m.sample_wm(w, u);
                assert!(wm.z > 0.0 && (wm.length() - 1.0).abs() < 1e-4);
                mean += wm.z as f64;
            }
        }
        mean /= (n * n) as f64;
        let expected = hemisphere_integral(|wm| m.pdf(w, wm) as f64 * wm.z as f64, 800);
        assert!((mean - expected).abs() < 2e-3, "{mean} vs {expected}");
    }

    #[test]
    fn masking_is_symmetric_and_bounded() {
        let m = TrowbridgeReitz::new(0.3, 0.7);
        for w in sphere_points(64) {
            let g1 = m.g1(w);
            assert!((0.0..=1.0).contains(&g1));
            assert_eq!(m.lambda(w), m.lambda(-w));
            assert!(m.g(w, Vec3::Z) <= g1 + 1e-6);
        }
        assert_eq!(m.g1(Vec3::Z), 1.0);
        assert_eq!(m.g1(Vec3::X), 0.0);
    }

    #[test]
    fn smoothness_and_remapping() {
        assert!(TrowbridgeReitz::new(0.0, 0.0).effectively_smooth());
        assert!(!TrowbridgeReitz::new(0.0, 0.01).effectively_smooth());
        assert_eq!(TrowbridgeReitz::roughness_to_alpha(0.25), 0.5);
    }
}
