//! BSDFs: lambert, energy-conserving Phong (000 eq. 3.1), mirror and glass.
//!
//! A [`Bsdf`] is built at one path vertex for one fixed direction `wo` (pointing back along the
//! path the walk came from) and answers, for another direction `wi`, the value, the forward pdf
//! (of sampling `wi` from `wo`) and the reverse pdf (of sampling `wo` from `wi`), all per solid
//! angle: what the bidirectional integrators' MIS needs (001 sec. 3).
//!
//! Conventions:
//! - `f` never includes the cosine; callers multiply by `|cos(n, wi)|`.
//! - A delta (specular) lobe reports `pdf_w` = the discrete probability of choosing it, and `f`
//!   such that `f * |cos wi| / pdf_w` is the throughput weight of the sample (SmallVCM's habit).
//!   `eval` ignores delta lobes (they have measure zero).
//! - `mode` says which quantity flows along `wo`: [`TransportMode::Radiance`] on eye sub-paths,
//!   [`TransportMode::Importance`] on light sub-paths. Only refraction differs: radiance is
//!   scaled by 1/eta^2 across the interface, importance is not.
//! - Lambert and Phong are two-sided (the frame flips to the side of `wo`); glass uses the
//!   geometric normal's orientation (outward) to tell entering from leaving.

use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

mod glass;
mod lambert;
mod mirror;
mod phong;

/// The scattering part of a material.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialKind {
    Lambert { kd: Rgb },
    /// Lafortune's energy-conserving Phong, f = kd/pi + ks (n+2)/(2 pi) cos^n(alpha) (000 eq. 3.1).
    Phong { kd: Rgb, ks: Rgb, exponent: f32 },
    Mirror { ks: Rgb },
    Glass { ior: f32 },
}

/// A named material: how it scatters and what it emits (radiance, one-sided, on the side the
/// geometric normal points to).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    pub emission: Rgb,
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        !self.emission.is_black()
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransportMode {
    /// Eye sub-paths: radiance flows towards `wo`.
    Radiance,
    /// Light sub-paths: importance flows towards `wo`.
    Importance,
}

/// Value and pdfs of a BSDF for a given `wi` (non-delta lobes only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfEval {
    pub f: Rgb,
    /// pdf of sampling `wi` given `wo`, per solid angle.
    pub pdf_w: f32,
    /// pdf of sampling `wo` given `wi`, per solid angle.
    pub rev_pdf_w: f32,
}

/// A sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Rgb,
    pub pdf_w: f32,
    pub rev_pdf_w: f32,
    /// Sampled from a delta lobe.
    pub delta: bool,
}

/// A BSDF at one vertex, for one fixed `wo`.
#[derive(Clone, Debug)]
pub struct Bsdf<'a> {
    kind: &'a MaterialKind,
    /// Local frame around the geometric normal (Lambert/Phong: flipped to the side of `wo`).
    frame: Frame,
    wo_local: Vec3,
    mode: TransportMode,
}

impl<'a> Bsdf<'a> {
    /// The BSDF of `kind` at a vertex with unit geometric normal `ng`, seen from unit `wo`.
    /// `None` when `wo` lies (numerically) in the surface plane, where nothing is defined.
    pub fn new(kind: &'a MaterialKind, ng: Vec3, wo: Vec3, mode: TransportMode) -> Option<Self> {
        let _ = (kind, ng, wo, mode);
        todo!("bsdf")
    }

    /// Value and pdfs for `wi` (unit), non-delta lobes only.
    pub fn eval(&self, wi: Vec3) -> BsdfEval {
        let _ = wi;
        todo!("bsdf")
    }

    /// Samples `wi` with the random numbers `u` (`u[0]` picks the lobe).
    pub fn sample(&self, u: [f32; 3]) -> Option<BsdfSample> {
        let _ = u;
        todo!("bsdf")
    }

    /// True when every lobe is a delta (mirror, glass): no connection or merge can use it.
    pub fn is_delta(&self) -> bool {
        todo!("bsdf")
    }

    /// `|cos|` between the geometric normal and `w`.
    pub fn cos_theta(&self, w: Vec3) -> f32 {
        self.frame.z.dot(w).abs()
    }

    /// Probability of continuing the path at this vertex under Russian roulette: the
    /// material's largest albedo channel, capped at 1.
    pub fn continuation_probability(&self) -> f32 {
        todo!("bsdf")
    }

    pub fn kind(&self) -> &MaterialKind {
        self.kind
    }

    pub fn mode(&self) -> TransportMode {
        self.mode
    }

    pub fn wo_local(&self) -> Vec3 {
        self.wo_local
    }
}
