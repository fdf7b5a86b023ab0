//! The dielectric coating that `coateddiffuse` and `coatedconductor` put over their bases, as a
//! deterministic closed-form model of pbrt-v4's LayeredBxDF.
//!
//! pbrt-v4 evaluates a coated surface by a random walk between the two interfaces, so its
//! value and pdf are random; every weight function of bpt, vcm and upg needs pdfs it can
//! evaluate exactly, so here the walk is summed in closed form instead:
//! - the coating's top reflects as pbrt's DielectricBxDF does: a Trowbridge-Reitz microfacet
//!   lobe D G F / (4 cos_o cos_i), or a delta mirror of weight F when effectively smooth;
//! - light enters and leaves through the macro-surface: refracted by Snell's law, weighted by
//!   what the top transmits and by the medium's transmittance exp(-thickness (1 - albedo) /
//!   cos') along the refracted direction, with the 1 / eta^2 of the solid-angle compression;
//!   so the base is evaluated at the refracted pair and f = T(wo) T(wi) f_base(wo', wi') /
//!   eta^2, reciprocal as pbrt's walk is. A smooth top transmits 1 - F(cos); a rough one its
//!   own transmission albedo, tabulated per material over the cosine (24 cosines, each an
//!   expectation over a 24 x 24 grid of visible normals), so its single-scattering loss and
//!   its spread past the critical angle count as in pbrt's walk;
//! - the internal reflections under a diffuse base are a geometric series of the base's
//!   reflectance times the coating's cosine-weighted internal reflectance (the rough top's
//!   own where rough, with the medium's round trip), cut where pbrt's walk stops: `maxdepth`
//!   events make (maxdepth + 1) / 2 bottom bounces. A lambertian base makes the light it sends
//!   up uniform again at every bounce, so for it this sum is pbrt's walk itself, but for the
//!   slab's attenuation taken along the refracted directions. Under a smooth conductor the
//!   same series runs at the one angle there is.
//!
//! What it does not follow (measured against an f64 version of pbrt's walk in tests/layered.rs):
//! transmission through a rough coating spreads light that this model keeps on the refracted
//! direction (the energy is the rough top's, the direction the smooth one's), the medium's scattering (`albedo`) is taken as forward, whatever pbrt's `g` (only its
//! absorption attenuates), and light a rough conductor reflects past the critical angle is trapped and
//! lost rather than re-reflected. `nsamples` has no meaning for a deterministic model.

use super::fresnel;
use super::microfacet::{Roughness, Scatter, TrowbridgeReitz};
use super::params::{BsdfError, ParamReader};
use crate::color::Rgb;
use glam::Vec3;

/// Reads a roughness under the names `names` (`roughness`, `uroughness`, `vroughness` with
/// their prefixes) and `remaproughness`: an axis takes its own value where given, else the
/// common one.
pub fn read_roughness(p: &ParamReader, names: [&str; 3]) -> Result<Roughness, BsdfError> {
    let common = p.number(names[0])?;
    let axis = |name| -> Result<f32, BsdfError> {
        if p.is_given(name) {
            p.number(name)
        } else {
            Ok(common)
        }
    };
    Ok(Roughness {
        u: axis(names[1])?,
        v: axis(names[2])?,
        remap: p.number("remaproughness")? != 0.0,
    })
}

/// A count pbrt states as an integer (`maxdepth`), read as a number.
pub fn count(p: &ParamReader, name: &str) -> Result<u32, BsdfError> {
    Ok(p.number(name)?.clamp(0.0, 1e6) as u32)
}

/// The coating: a dielectric interface over a homogeneous slab.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coating {
    /// Index of the coating over the outside's.
    pub eta: f32,
    pub roughness: Roughness,
    /// Optical thickness of the slab (pbrt's unit extinction).
    pub thickness: f32,
    /// Single-scattering albedo of the slab's medium.
    pub albedo: Rgb,
    pub max_depth: u32,
    /// The cosine-weighted average over inside directions of the internal reflectance times
    /// the slab's transmittance down and up: what one diffuse round trip keeps.
    internal: Rgb,
    /// A rough top's transmission albedo for outside directions at cosines i / (TABLE - 1):
    /// what its single-scattering microfacet lobe (pbrt's rough DielectricBxDF) lets through,
    /// spread and all, in place of a smooth top's 1 - F.
    transmitted: [f32; TABLE],
}

/// Cosines at which a rough top's transmission is tabulated (linear between them).
const TABLE: usize = 24;

/// Microfacet normals a side of the grid that integrates a rough top's lobes: midpoints of the
/// visible-normal sampler's unit square, so each is an expectation over the lobe.
const GRID: usize = 24;

/// Reflection of local `w` about the microfacet normal `wm`.
fn reflect(w: Vec3, wm: Vec3) -> Vec3 {
    2.0 * w.dot(wm) * wm - w
}

/// Points of the midpoint rule for the internal reflectance. A smooth top's Fresnel term
/// rises like a square root into total internal reflection at the critical angle, where the
/// rule converges as h^1.5: this many points keep its error below 1e-5 (a white base
/// multiplies it by up to eta^2). A rough top's is smooth and costs a grid per point.
const INTERNAL_POINTS_SMOOTH: usize = 16384;
const INTERNAL_POINTS_ROUGH: usize = 256;

/// What a rough dielectric `top` of index `eta` sends from direction `w` (local, either
/// side) into the other hemisphere (`transmit`) or back into its own, as pbrt's sampler does it:
/// the expectation over visible normals of the Fresnel share times G / G1.
fn rough_albedo(top: &TrowbridgeReitz, eta: f32, w: Vec3, transmit: bool) -> f32 {
    let mut sum = 0.0f64;
    for i in 0..GRID * GRID {
        let u = [
            ((i % GRID) as f32 + 0.5) / GRID as f32,
            ((i / GRID) as f32 + 0.5) / GRID as f32,
        ];
        let wm = top.sample_wm(w, u);
        let f = fresnel::dielectric(w.dot(wm), eta);
        let (wi, share) = if transmit {
            match fresnel::refract(w, wm, eta) {
                Some((wi, _)) => (wi, 1.0 - f),
                None => continue,
            }
        } else {
            (reflect(w, wm), f)
        };
        if (wi.z * w.z > 0.0) == transmit {
            continue;
        }
        let g1 = top.g1(w);
        sum += (share * top.g(w, wi) / g1) as f64;
    }
    (sum / (GRID * GRID) as f64) as f32
}

/// The mean of `f` over the two axes of an anisotropic `top` (one where it is isotropic): the
/// tables keep the lobes' mean over azimuths.
fn over_azimuths(top: &TrowbridgeReitz, f: impl Fn(f32, f32) -> f32) -> f32 {
    if top.alpha_x == top.alpha_y {
        f(1.0, 0.0)
    } else {
        0.5 * (f(1.0, 0.0) + f(0.0, 1.0))
    }
}

impl Coating {
    pub fn new(
        eta: f32,
        roughness: Roughness,
        thickness: f32,
        albedo: Rgb,
        max_depth: u32,
    ) -> Self {
        let mut coating = Coating {
            eta,
            roughness,
            thickness,
            albedo,
            max_depth,
            internal: Rgb::BLACK,
            transmitted: [0.0; TABLE],
        };
        let top = coating.top();
        let smooth = coating.is_smooth();
        // The internal reflectance of an inside direction going up at cosine mu.
        let reflected = |mu: f32| {
            if smooth {
                return fresnel::dielectric(-mu, eta);
            }
            let s = (1.0 - mu * mu).max(0.0).sqrt();
            over_azimuths(&top, |x, y| {
                rough_albedo(&top, eta, Vec3::new(x * s, y * s, -mu), false)
            })
        };
        let points = if smooth {
            INTERNAL_POINTS_SMOOTH
        } else {
            INTERNAL_POINTS_ROUGH
        };
        let reflectances: Vec<f32> = (0..points)
            .map(|i| reflected(((i as f64 + 0.5) / points as f64) as f32))
            .collect();
        let channel = |sigma: f32| {
            let mut sum = 0.0f64;
            for (i, &r) in reflectances.iter().enumerate() {
                let mu = (i as f64 + 0.5) / points as f64;
                let kept = (-2.0 * (thickness * sigma) as f64 / mu).exp();
                sum += 2.0 * mu * r as f64 * kept;
            }
            (sum / points as f64) as f32
        };
        let sigma = coating.absorption();
        coating.internal = Rgb::new(channel(sigma.r), channel(sigma.g), channel(sigma.b));
        if !smooth {
            for (i, t) in coating.transmitted.iter_mut().enumerate() {
                let mu = i as f32 / (TABLE - 1) as f32;
                let s = (1.0 - mu * mu).max(0.0).sqrt();
                *t = if mu == 0.0 {
                    0.0
                } else {
                    over_azimuths(&top, |x, y| {
                        rough_albedo(&top, eta, Vec3::new(x * s, y * s, mu), true)
                    })
                };
            }
        }
        coating
    }

    /// The slab's absorption per unit thickness: its extinction (1) less what it scatters.
    fn absorption(&self) -> Rgb {
        Rgb::WHITE - self.albedo
    }

    pub fn top(&self) -> TrowbridgeReitz {
        self.roughness.distribution()
    }

    /// The top reflects as a mirror (a delta lobe).
    pub fn is_smooth(&self) -> bool {
        self.eta == 1.0 || self.top().effectively_smooth()
    }

    /// Fresnel reflectance of the macro-surface for an outside direction at `cos`.
    pub fn fresnel(&self, cos: f32) -> f32 {
        fresnel::dielectric(cos, self.eta)
    }

    /// The coating's internal diffuse round trip (see the field).
    pub fn internal(&self) -> Rgb {
        self.internal
    }

    /// Bottom bounces pbrt's walk reaches within `max_depth` events.
    pub fn bottom_bounces(&self) -> i32 {
        self.max_depth.div_ceil(2).min(i32::MAX as u32) as i32
    }

    /// The rough top's reflection value and its sampling pdf from `wo` (both above).
    pub fn reflection(&self, wo: Vec3, wi: Vec3) -> (f32, f32) {
        let wm = wo + wi;
        if wm.length_squared() == 0.0 || wo.z <= 0.0 || wi.z <= 0.0 {
            return (0.0, 0.0);
        }
        let wm = wm.normalize();
        let top = self.top();
        let cos_om = wo.dot(wm);
        let f =
            top.d(wm) * top.g(wo, wi) * fresnel::dielectric(cos_om, self.eta) / (4.0 * wo.z * wi.z);
        (f, top.pdf(wo, wm) / (4.0 * cos_om))
    }

    /// A direction from the rough top's reflection lobe; `None` below the surface.
    pub fn sample_reflection(&self, wo: Vec3, u: [f32; 2]) -> Option<Vec3> {
        Scatter::Reflect.apply(wo, self.top().sample_wm(wo, u), 0.0)
    }

    /// The inside direction (above the base) that refracts into the outside direction `w`.
    pub fn inner(&self, w: Vec3) -> Vec3 {
        fresnel::into_layer(w, self.eta)
    }

    /// The outside direction an inside one `w` (going up) refracts into; `None` under total
    /// internal reflection.
    pub fn outer(&self, w: Vec3) -> Option<Vec3> {
        fresnel::out_of_layer(w, self.eta)
    }

    /// What crosses the coating once for the outside direction `w` (inside direction `inner`):
    /// the top's transmitted fraction times the slab's transmittance.
    pub fn transmittance(&self, w: Vec3, inner: Vec3) -> Rgb {
        self.slab(inner) * self.transmitted_fraction(w.z)
    }

    /// The slab's transmittance along the inside direction `inner`, top to base.
    pub fn slab(&self, inner: Vec3) -> Rgb {
        let sigma = self.absorption() * (self.thickness / inner.z.max(1e-6));
        Rgb::new((-sigma.r).exp(), (-sigma.g).exp(), (-sigma.b).exp())
    }

    /// The top's transmission albedo for an outside direction at `cos`: 1 - F when smooth,
    /// the table's interpolation when rough.
    fn transmitted_fraction(&self, cos: f32) -> f32 {
        if self.is_smooth() {
            return 1.0 - self.fresnel(cos);
        }
        let x = cos.clamp(0.0, 1.0) * (TABLE - 1) as f32;
        let i = (x as usize).min(TABLE - 2);
        let t = x - i as f32;
        self.transmitted[i] * (1.0 - t) + self.transmitted[i + 1] * t
    }

    /// The solid-angle factor of a pdf on the inside direction `inner` as a pdf on its
    /// outside direction `w`: d(omega') / d(omega) = cos / (eta^2 cos').
    pub fn pdf_to_outside(&self, w: Vec3, inner: Vec3) -> f32 {
        w.z / (self.eta * self.eta * inner.z.max(1e-6))
    }

    /// The probability of sampling the top's reflection from `wo` rather than the base, by
    /// their shares of the energy: F(wo) against (1 - F(wo)) `base`.
    pub fn top_probability(&self, wo: Vec3, base: f32) -> f32 {
        let f = self.fresnel(wo.z);
        let total = f + (1.0 - f) * base;
        if total > 0.0 {
            f / total
        } else {
            1.0
        }
    }
}
