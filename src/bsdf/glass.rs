//! Smooth dielectric: Fresnel reflection and refraction, each a delta lobe chosen with the
//! probability of its Fresnel weight (pbrt-v4's DielectricBxDF).
//!
//! Each hit decides on its own, with no medium stack and no memory of earlier hits, the rule
//! of pbrt-v4 and Mitsuba 3:
//! - Entering or leaving: `wo` (back along the path) on the side the geometric normal points
//!   to (`wo . ng > 0`) means arriving from outside, so entering; otherwise leaving. The normal
//!   of a triangle is its counter-clockwise side, of a sphere the outward one.
//! - Relative index n_t / n_i: `ior` entering, `1 / ior` leaving; the Fresnel weight and the
//!   refracted direction use it, and refracted radiance is scaled by its inverse square.
//! - Total internal reflection (sin^2 theta_t >= 1) makes the Fresnel weight 1: the hit
//!   reflects with weight 1; inside a thin wall a path may do so until its length runs out.
//! - The next ray's origin is offset along the geometric normal to the side of `wi`
//!   ([`crate::accel::Ray::spawn`]): a reflected ray stays on `wo`'s side, a refracted one
//!   crosses.
//!
//! So a face wound into the glass swaps entering and leaving at that face alone (an outer
//! face wound inward is taken as glass to air). A wall is two interfaces wherever it is
//! thicker than the origin offset (about 2e-6 of the largest coordinate plus 1e-6: 5e-6 at
//! coordinates of 2, a tenth of the 58 um walls of the lamp bulbs in tests/glass.rs). A
//! renderer with a larger offset sees a thinner wall as one face and renders it otherwise:
//! Mitsuba 3 offsets by (1 + max |p_i|) 1500 2^-24, 2.9e-4 there, so to it every crossing of a
//! bulb's wall (outer face wound outward, inner face towards the hollow) looks like entering.

use super::fresnel;
use super::params::{number, BsdfError, EnergyExcess, ParamRange, ParamReader, ParamSpec, Params};
use super::{reflect_local, Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glass {
    /// Index of refraction inside (the side the normal points away from) over outside.
    pub ior: f32,
}

/// Refraction of local `w` through the interface; `eta` = n_inside / n_outside. Returns the
/// transmitted direction and the relative index n_t / n_i across the crossing, or `None` under
/// total internal reflection.
pub fn refract_local(w: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let (cos_i, eta, sign) = if w.z < 0.0 {
        (-w.z, 1.0 / eta, -1.0)
    } else {
        (w.z, eta, 1.0)
    };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let t = -w / eta + Vec3::new(0.0, 0.0, sign * (cos_i / eta - cos_t));
    Some((t.normalize(), eta))
}

impl BxdfType for Glass {
    const NAME: &'static str = "glass";
    const PARAMS: &'static [ParamSpec] = &[number("ior", 1.5, ParamRange::Positive)];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Glass {
            ior: p.number("ior")?,
        })
    }
}

impl Bxdf for Glass {
    fn params(&self) -> Params {
        Params::new().with_number("ior", self.ior)
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        None
    }

    fn albedo(&self) -> Albedo {
        Albedo::NONE
    }

    fn with_albedo(&self, _: Albedo) -> Self {
        *self
    }

    fn is_delta(&self) -> bool {
        true
    }

    fn two_sided(&self) -> bool {
        false
    }

    #[inline]
    fn eval(&self, _: Vec3, _: Vec3, _: TransportMode) -> BsdfEval {
        BsdfEval::ZERO
    }

    /// `wo` local to the outward normal (negative z when leaving the glass).
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], mode: TransportMode) -> Option<BsdfSample> {
        let ior = self.ior;
        let reflectance = fresnel::dielectric(wo.z, ior);
        if u[0] < reflectance {
            let wi = reflect_local(wo);
            // f * |cos| / pdf = 1: the Fresnel weight cancels its own choice probability.
            return Some(BsdfSample {
                wi,
                f: Rgb::splat(reflectance / wi.z.abs()),
                pdf_w: reflectance,
                rev_pdf_w: reflectance,
                delta: true,
            });
        }
        let (wi, eta) = refract_local(wo, ior)?;
        let transmittance = 1.0 - reflectance;
        // Radiance is compressed into the narrower solid angle of the denser medium: looking from
        // the side of `wo` (index n_i) into the side of `wi` (index n_t), radiance scales by
        // (n_i / n_t)^2. Importance does not (the adjoint BSDF, Veach's thesis sec. 5.2).
        let scale = match mode {
            TransportMode::Radiance => 1.0 / (eta * eta),
            TransportMode::Importance => 1.0,
        };
        Some(BsdfSample {
            wi,
            f: Rgb::splat(transmittance * scale / wi.z.abs()),
            pdf_w: transmittance,
            rev_pdf_w: transmittance,
            delta: true,
        })
    }

    fn continuation_albedo(&self) -> Rgb {
        Rgb::WHITE
    }

    #[inline]
    fn lobes(&self, _: Vec3, _: &Frame) -> Lobes {
        Lobes::NONE
    }
}
