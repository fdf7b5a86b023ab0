//! Lambertian reflection and transmission (pbrt-v4's DiffuseTransmissionBxDF): f = r / pi on
//! the side of `wo`, t / pi on the other side, each half sampled by the cosine around its own
//! side with the probability of its largest channel.
//!
//! Two-sided as pbrt-v4: the local frame flips to the side of `wo`, so reflection is `wi.z > 0`
//! and transmission `wi.z < 0` from whichever side the surface is seen. Transmission changes no
//! medium, so radiance and importance are scaled alike.

use super::params::{color, BsdfError, EnergyExcess, EnergyFix, ParamReader, ParamSpec, Params};
use super::{Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobe, LobeKind, LobeShape, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseTransmission {
    /// Reflectance.
    pub r: Rgb,
    /// Transmittance.
    pub t: Rgb,
}

impl DiffuseTransmission {
    /// The probability of sampling reflection (pbrt-v4: by the largest channels of r and t);
    /// `None` for a black surface.
    fn reflection_probability(&self) -> Option<f32> {
        let (pr, pt) = (self.r.max_component(), self.t.max_component());
        (pr + pt > 0.0).then(|| pr / (pr + pt))
    }
}

impl BxdfType for DiffuseTransmission {
    const NAME: &'static str = "diffusetransmission";
    const PARAMS: &'static [ParamSpec] = &[color("reflectance", 0.25), color("transmittance", 0.25)];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(DiffuseTransmission {
            r: p.color("reflectance")?,
            t: p.color("transmittance")?,
        })
    }
}

impl Bxdf for DiffuseTransmission {
    fn params(&self) -> Params {
        Params::new()
            .with_color("reflectance", self.r)
            .with_color("transmittance", self.t)
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        let total = self.r + self.t;
        (total.max_component() > 1.0).then(|| {
            let scale = |c: f32| if c > 1.0 { 1.0 / c } else { 1.0 };
            let s = Rgb::new(scale(total.r), scale(total.g), scale(total.b));
            EnergyExcess {
                what: "reflectance + transmittance",
                total,
                fix: EnergyFix::Scaled,
                conserving: DiffuseTransmission {
                    r: self.r * s,
                    t: self.t * s,
                }
                .into(),
            }
        })
    }

    fn albedo(&self) -> Albedo {
        Albedo {
            kd: self.r,
            ks: self.t,
            roughness: None,
            vroughness: None,
        }
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        DiffuseTransmission {
            r: albedo.kd,
            t: albedo.ks,
        }
    }

    fn kd_limit(&self, ks: Rgb) -> Rgb {
        Rgb::WHITE - ks
    }

    fn is_delta(&self) -> bool {
        false
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, _: TransportMode) -> BsdfEval {
        let Some(pr) = self.reflection_probability() else {
            return BsdfEval::ZERO;
        };
        if wi.z == 0.0 {
            return BsdfEval::ZERO;
        }
        let (f, p) = if wi.z > 0.0 {
            (self.r, pr)
        } else {
            (self.t, 1.0 - pr)
        };
        // Each side is a cosine lobe around its own normal, so the reverse pdf is the same
        // choice (reflection stays reflection seen from `wi`) times the cosine at `wo`.
        BsdfEval {
            f: f * FRAC_1_PI,
            pdf_w: p * cosine_hemisphere_pdf(wi.z.abs()),
            rev_pdf_w: p * cosine_hemisphere_pdf(wo.z.abs()),
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], mode: TransportMode) -> Option<BsdfSample> {
        let pr = self.reflection_probability()?;
        let w = cosine_hemisphere([u[1], u[2]]);
        let wi = if u[0] < pr { w } else { Vec3::new(w.x, w.y, -w.z) };
        self.eval(wo, wi, mode).sample_at(wi)
    }

    fn continuation_albedo(&self) -> Rgb {
        self.r + self.t
    }

    /// A cosine lobe on each side, chosen as [`Bxdf::sample`] chooses.
    fn lobes(&self, _: Vec3, frame: &Frame) -> Lobes {
        let Some(pr) = self.reflection_probability() else {
            return Lobes::UNBOUNDED;
        };
        let side = |weight, axis| {
            LobeKind::Polar(Lobe {
                weight,
                axis,
                shape: LobeShape::Cosine,
            })
        };
        Lobes::NONE
            .with(side(pr, frame.z))
            .with(side(1.0 - pr, -frame.z))
    }
}
