//! Perfect mirror with reflectance `ks`: a single delta lobe.

use super::params::{clamp_to_one, color, BsdfError, EnergyExcess, EnergyFix, ParamReader, ParamSpec, Params};
use super::{reflect_local, Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    pub ks: Rgb,
}

impl BxdfType for Mirror {
    const NAME: &'static str = "mirror";
    const PARAMS: &'static [ParamSpec] = &[color("ks", 1.0)];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Mirror { ks: p.color("ks")? })
    }
}

impl Bxdf for Mirror {
    fn params(&self) -> Params {
        Params::new().with_color("ks", self.ks)
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        (self.ks.max_component() > 1.0).then(|| EnergyExcess {
            what: "ks",
            total: self.ks,
            fix: EnergyFix::Clamped,
            conserving: Mirror {
                ks: clamp_to_one(self.ks),
            }
            .into(),
        })
    }

    fn albedo(&self) -> Albedo {
        Albedo {
            kd: Rgb::BLACK,
            ks: self.ks,
            roughness: None,
            vroughness: None,
        }
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        Mirror { ks: albedo.ks }
    }

    fn is_delta(&self) -> bool {
        true
    }

    #[inline]
    fn eval(&self, _: Vec3, _: Vec3, _: TransportMode) -> BsdfEval {
        BsdfEval::ZERO
    }

    #[inline]
    fn sample(&self, wo: Vec3, _: [f32; 3], _: TransportMode) -> Option<BsdfSample> {
        let wi = reflect_local(wo);
        // Delta lobe chosen with probability 1: f * |cos| / pdf = ks.
        Some(BsdfSample {
            wi,
            f: self.ks / wi.z.abs(),
            pdf_w: 1.0,
            rev_pdf_w: 1.0,
            delta: true,
        })
    }

    fn continuation_albedo(&self) -> Rgb {
        self.ks
    }

    #[inline]
    fn lobes(&self, _: Vec3, _: &Frame) -> Lobes {
        Lobes::NONE
    }
}
