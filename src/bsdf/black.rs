//! A black body: absorbs everything it receives.

use super::params::{BsdfError, EnergyExcess, ParamReader, ParamSpec, Params};
use super::{Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Black {}

impl BxdfType for Black {
    const NAME: &'static str = "black";
    const PARAMS: &'static [ParamSpec] = &[];

    fn from_params(_: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Black {})
    }
}

impl Bxdf for Black {
    fn params(&self) -> Params {
        Params::new()
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        None
    }

    fn albedo(&self) -> Albedo {
        Albedo {
            kd: Rgb::BLACK,
            ks: Rgb::BLACK,
        }
    }

    fn with_albedo(&self, _: Albedo) -> Self {
        *self
    }

    fn is_delta(&self) -> bool {
        false
    }

    fn eval(&self, _: Vec3, _: Vec3, _: TransportMode) -> BsdfEval {
        BsdfEval::ZERO
    }

    fn sample(&self, _: Vec3, _: [f32; 3], _: TransportMode) -> Option<BsdfSample> {
        None
    }

    fn continuation_albedo(&self) -> Rgb {
        Rgb::BLACK
    }

    fn lobes(&self, _: Vec3, _: &Frame) -> Lobes {
        Lobes::UNBOUNDED
    }
}
