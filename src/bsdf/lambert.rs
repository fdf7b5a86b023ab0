//! Lambertian reflection, f = kd / pi, sampled by the cosine.

use super::params::{clamp_to_one, color, BsdfError, EnergyExcess, EnergyFix, ParamReader, ParamSpec, Params};
use super::{Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobe, LobeKind, LobeShape, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    pub kd: Rgb,
}

impl BxdfType for Lambert {
    const NAME: &'static str = "lambert";
    const PARAMS: &'static [ParamSpec] = &[color("kd", 0.8)];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Lambert { kd: p.color("kd")? })
    }
}

impl Bxdf for Lambert {
    fn params(&self) -> Params {
        Params::new().with_color("kd", self.kd)
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        (self.kd.max_component() > 1.0).then(|| EnergyExcess {
            what: "kd",
            total: self.kd,
            fix: EnergyFix::Clamped,
            conserving: Lambert {
                kd: clamp_to_one(self.kd),
            }
            .into(),
        })
    }

    fn albedo(&self) -> Albedo {
        Albedo {
            kd: self.kd,
            ks: Rgb::BLACK,
            roughness: None,
            vroughness: None,
        }
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        Lambert { kd: albedo.kd }
    }

    fn is_delta(&self) -> bool {
        false
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, _: TransportMode) -> BsdfEval {
        if wi.z <= 0.0 {
            return BsdfEval::ZERO;
        }
        BsdfEval {
            f: self.kd * FRAC_1_PI,
            pdf_w: cosine_hemisphere_pdf(wi.z),
            rev_pdf_w: cosine_hemisphere_pdf(wo.z),
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], mode: TransportMode) -> Option<BsdfSample> {
        let wi = cosine_hemisphere([u[1], u[2]]);
        self.eval(wo, wi, mode).sample_at(wi)
    }

    fn continuation_albedo(&self) -> Rgb {
        self.kd
    }

    #[inline]
    fn lobes(&self, _: Vec3, frame: &Frame) -> Lobes {
        let mut lobes = Lobes::NONE;
        lobes.push(LobeKind::Polar(Lobe {
            weight: 1.0,
            axis: frame.z,
            shape: LobeShape::Cosine,
        }));
        lobes
    }
}
