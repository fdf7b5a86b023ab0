//! A thin dielectric sheet (pbrt-v4's `thindielectric`): two parallel interfaces so close
//! that light leaves where it entered, undeflected. Every inter-reflection inside is summed
//! in closed form: with F the Fresnel reflectance of one interface and T = 1 - F,
//! R = F + T^2 F / (1 - F^2) and the sheet transmits 1 - R along -wo. Both lobes are deltas,
//! chosen with probabilities R and 1 - R; the sheet is the same from either side and scales
//! nothing by eta (the ray leaves into the medium it came from).

use super::fresnel;
use super::params::{number, BsdfError, EnergyExcess, ParamRange, ParamReader, ParamSpec, Params};
use super::{reflect_local, Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinDielectric {
    /// Index of refraction of the sheet over that of its surroundings.
    pub eta: f32,
}

impl ThinDielectric {
    /// The sheet's reflectance for `wo` at `cos_o` to the normal.
    pub fn reflectance(&self, cos_o: f32) -> f32 {
        let f = fresnel::dielectric(cos_o.abs(), self.eta);
        if f < 1.0 {
            let t = 1.0 - f;
            f + t * t * f / (1.0 - f * f)
        } else {
            f
        }
    }
}

impl BxdfType for ThinDielectric {
    const NAME: &'static str = "thindielectric";
    const PARAMS: &'static [ParamSpec] = &[number("eta", 1.5, ParamRange::Positive)];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(ThinDielectric {
            eta: p.number("eta")?,
        })
    }
}

impl Bxdf for ThinDielectric {
    fn params(&self) -> Params {
        Params::new().with_number("eta", self.eta)
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

    #[inline]
    fn eval(&self, _: Vec3, _: Vec3, _: TransportMode) -> BsdfEval {
        BsdfEval::ZERO
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], _: TransportMode) -> Option<BsdfSample> {
        let r = self.reflectance(wo.z);
        // f |cos| / pdf = 1 for either lobe: each weight cancels its own choice probability.
        let (wi, p) = if u[0] < r {
            (reflect_local(wo), r)
        } else {
            (-wo, 1.0 - r)
        };
        Some(BsdfSample {
            wi,
            f: Rgb::splat(p / wi.z.abs()),
            pdf_w: p,
            rev_pdf_w: p,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sheet_reflects_more_than_one_interface_and_passes_straight() {
        let sheet = ThinDielectric { eta: 1.5 };
        let one = fresnel::dielectric(1.0, 1.5);
        // At normal incidence R = 2F / (1 + F).
        assert!((sheet.reflectance(1.0) - 2.0 * one / (1.0 + one)).abs() < 1e-6);
        let wo = Vec3::new(0.3, 0.0, 0.9539392);
        let s = sheet.sample(wo, [0.99, 0.5, 0.5], TransportMode::Radiance).unwrap();
        assert_eq!(s.wi, -wo);
        assert!((s.f.g * s.wi.z.abs() / s.pdf_w - 1.0).abs() < 1e-6);
    }
}
