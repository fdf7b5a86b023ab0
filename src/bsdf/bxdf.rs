//! The one interface every BSDF type implements, in the local shading frame (z the shading
//! normal, on the side of `wo` for two-sided types): [`super::Bsdf`] adds the frame, the
//! shading-normal factor and the world directions once for all of them.

use super::params::{BsdfError, EnergyExcess, ParamReader, ParamSpec, Params};
use super::{Albedo, BsdfEval, BsdfSample, Lobes, TransportMode};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

/// A BSDF type: how scene files name it and build it.
pub trait BxdfType: Bxdf + Sized {
    /// The name scene files give the type.
    const NAME: &'static str;
    /// The parameters it reads, with their defaults.
    const PARAMS: &'static [ParamSpec];

    fn from_params(params: &ParamReader) -> Result<Self, BsdfError>;
}

/// What a BSDF answers at one vertex, in local coordinates (see the conventions of
/// [`super`]). `wo` and `wi` are unit; for a two-sided type `wo.z > 0`.
pub trait Bxdf {
    /// Every parameter with its value: what [`BxdfType::from_params`] rebuilds it from.
    fn params(&self) -> Params;

    /// Whether it reflects more than it receives in some channel, and the kind that does not.
    fn energy_excess(&self) -> Option<EnergyExcess>;

    /// Its colours that textures may replace.
    fn albedo(&self) -> Albedo;

    /// The same BSDF with the colours of `albedo` (from textures at one point).
    fn with_albedo(&self, albedo: Albedo) -> Self
    where
        Self: Sized;

    /// The largest kd a texture may give where ks is `ks`, for energy conservation.
    fn kd_limit(&self, _ks: Rgb) -> Rgb {
        Rgb::WHITE
    }

    /// Every lobe is a delta: no connection or merge can use it.
    fn is_delta(&self) -> bool;

    /// Its lobes change with the azimuth about the normal (roughness differing along the two
    /// axes): only then does the frame's first tangent matter.
    fn anisotropic(&self) -> bool {
        false
    }

    /// The local frame flips to the side of `wo` (otherwise the normal's orientation tells
    /// entering from leaving).
    fn two_sided(&self) -> bool {
        true
    }

    /// Value and both pdfs for `wi`, non-delta lobes only.
    fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> BsdfEval;

    /// Samples `wi` with `u` (`u[0]` picks the lobe).
    fn sample(&self, wo: Vec3, u: [f32; 3], mode: TransportMode) -> Option<BsdfSample>;

    /// The albedo Russian roulette continues by (its largest channel, capped at 1).
    fn continuation_albedo(&self) -> Rgb;

    /// Its sampling mixture for `wo`, with axes in world space through `frame` (the normal is
    /// `frame.z` itself, unrounded); [`Lobes::NONE`] for a delta BSDF, [`Lobes::UNBOUNDED`]
    /// where its lobes have no closed-form bound.
    fn lobes(&self, wo: Vec3, frame: &Frame) -> Lobes;
}
