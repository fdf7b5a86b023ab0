//! BSDFs: lambert, energy-conserving Phong (000 eq. 3.1), mirror and glass, and pbrt-v4's
//! conductor, dielectric and thin dielectric on Trowbridge-Reitz microfacets.
//!
//! A [`Bsdf`] is built at one path vertex for one fixed direction `wo` (pointing back along the
//! path the walk came from) and answers, for another direction `wi`, the value, the forward pdf
//! (of sampling `wi` from `wo`) and the reverse pdf (of sampling `wo` from `wi`), all per solid
//! angle: what the bidirectional integrators' MIS needs (001 sec. 3).
//!
//! Each BSDF type lives in its own file as a struct of its parameters implementing
//! [`BxdfType`] (its scene-file name and parameters) and [`Bxdf`] (value, pdfs, sampling and
//! sampling lobes in the local shading frame), and is registered by one line of the
//! `registry!` below, which declares its [`MaterialKind`] variant and dispatches to it. `Bsdf`
//! adds, once for every type, the shading frame, the shading-normal factor and world
//! directions. Scene front-ends build kinds by type name and [`Params`], never by variant.
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
//!   normal's orientation (outward) to tell entering from leaving.
//! - Shading normals (Veach's thesis sec. 5.3): lobes are evaluated and sampled in the frame of
//!   the shading normal `ns`, while callers keep multiplying by the geometric `|cos(ng, wi)|`
//!   ([`Bsdf::cos_theta`]) and convert pdfs between solid angle and area with geometric cosines.
//!   So `f` carries the factor that makes this right: |wi.ns| / |wi.ng| for radiance (`wi` points
//!   to the light), |wo.ns| / |wo.ng| for importance (`wo` points to the light). Both are the one
//!   function of the two directions f(l, c) |l.ns| / |l.ng|, `l` towards the light, so every
//!   technique evaluates the same path integrand; for importance the factor is Veach's adjoint
//!   correction |wo.ng| |wi.ns| / (|wo.ns| |wi.ng|) relative to using the shading cosine.
//!   The pdfs are those of the shading-frame lobes, the same in both modes, so forward and
//!   reverse pdfs of the two sides of a vertex still match.
//! - Anisotropic types (roughness differing along the two tangent axes) are evaluated in
//!   pbrt-v4's frame: x along the surface's dp/du made orthogonal to `ns` ([`Bsdf::oriented`]);
//!   isotropic ones in `Frame::from_z`, whose turn about the normal they do not see.
//! - Light leaks where `ns` and `ng` disagree are treated as pbrt-v4 treats them: not at all
//!   in the BSDF. Reflection and transmission are told apart by the shading hemisphere alone
//!   (no test against the geometric normal, which pbrt-v3 had), and a new ray's origin is
//!   offset along `ng` to the side its direction goes (`Ray::spawn`).

use crate::color::Rgb;
use crate::frame::{Azimuth, Frame};
use glam::{Vec3, Vec3A};

mod bxdf;
pub mod fresnel;
mod layer;
mod lobe;
pub mod microfacet;
mod params;
#[macro_use]
mod registry;

pub use bxdf::{Bxdf, BxdfType};
pub use layer::Coating;
pub use lobe::{
    Lobe, LobeKind, LobeShape, Lobes, MicrofacetLobe, PointRect, PolarBound, PolarInterval,
};
use microfacet::Roughness;
pub use params::{
    BsdfError, EnergyExcess, EnergyFix, ParamKind, ParamProblem, ParamRange, ParamReader,
    ParamSpec, ParamValue, Params,
};

// The BSDF types: one line each (registry.rs).
registry! {
    lambert::Lambert { kd: Rgb },
    /// Lafortune's energy-conserving Phong, f = kd/pi + ks (n+2)/(2 pi) cos^n(alpha) (000 eq. 3.1).
    phong::Phong { kd: Rgb, ks: Rgb, exponent: f32 },
    mirror::Mirror { ks: Rgb },
    glass::Glass { ior: f32 },
    /// pbrt-v4's conductor: complex Fresnel on Trowbridge-Reitz microfacets.
    conductor::Conductor { eta: Rgb, k: Rgb, roughness: Roughness },
    /// pbrt-v4's dielectric: Walter et al. 2007 on Trowbridge-Reitz microfacets, glass when smooth.
    dielectric::Dielectric { eta: f32, roughness: Roughness },
    thin_dielectric::ThinDielectric { eta: f32 },
    /// pbrt-v4's lambertian reflection and transmission.
    diffuse_transmission::DiffuseTransmission { r: Rgb, t: Rgb },
    /// pbrt-v4's coateddiffuse by the deterministic layered model of layer.rs.
    coated_diffuse::CoatedDiffuse { r: Rgb, coating: Coating },
    /// pbrt-v4's coatedconductor by the deterministic layered model of layer.rs.
    coated_conductor::CoatedConductor { eta: Rgb, k: Rgb, reflectance: Rgb, roughness: Roughness, coating: Coating },
}

/// A named material: how it scatters and what it emits (radiance, one-sided, on the side the
/// geometric normal points to).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    pub emission: Rgb,
    /// Whether the emission leaves both sides of the surface, not only its normal's.
    pub two_sided: bool,
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

/// The albedos of a material at one surface point: the material's own colours, or what its
/// textures give there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Albedo {
    /// Lambert's and Phong's kd (unused by mirror and glass).
    pub kd: Rgb,
    /// Phong's ks, the mirror's reflectance (unused by lambert and glass).
    pub ks: Rgb,
    /// A microfacet type's roughness on both axes, where a texture gives it (in the type's
    /// own units: remapped to alpha when its `remaproughness` says so); `None` keeps the
    /// type's own.
    pub roughness: Option<f32>,
    /// The v axis's roughness where a texture of its own gives it (pbrt's `vroughness`):
    /// `roughness` then sets the u axis alone.
    pub vroughness: Option<f32>,
}

impl Albedo {
    /// No colour a texture could replace (glass and the conductors' Fresnel colours).
    pub const NONE: Albedo = Albedo {
        kd: Rgb::BLACK,
        ks: Rgb::BLACK,
        roughness: None,
        vroughness: None,
    };

    /// The constant colours of `kind`.
    pub fn of(kind: &MaterialKind) -> Self {
        kind.albedo()
    }

    /// `roughness` with the axes its textures give here replaced.
    pub fn roughness_of(&self, roughness: Roughness) -> Roughness {
        let mut r = roughness.textured(self.roughness);
        if let Some(v) = self.vroughness {
            r.v = v.max(0.0);
        }
        r
    }
}

/// The geometry a BSDF sits on: unit geometric normal `ng` and unit shading normal `ns`, on the
/// same side of the surface. `ns == ng` (bit for bit) is a flat surface, evaluated exactly as
/// without shading normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normals {
    pub ng: Vec3,
    pub ns: Vec3,
}

impl Normals {
    pub fn flat(ng: Vec3) -> Self {
        Normals { ng, ns: ng }
    }
}

/// What a BSDF type says of itself that shapes a [`Bsdf`]'s frame and its callers' choices.
#[derive(Clone, Copy, Debug)]
struct Traits {
    delta: bool,
    two_sided: bool,
    anisotropic: bool,
}

impl Traits {
    #[inline]
    fn of(bxdf: &impl Bxdf) -> Self {
        Traits {
            delta: bxdf.is_delta(),
            two_sided: bxdf.two_sided(),
            anisotropic: bxdf.anisotropic(),
        }
    }
}

/// Smallest |cos| to the geometric normal that the shading-normal factor divides by; below it
/// the factor is clamped, identically for every technique, so f stays finite.
const MIN_GEOMETRIC_COS: f32 = 1e-6;

/// A BSDF at one vertex, for one fixed `wo`.
#[derive(Clone, Debug)]
pub struct Bsdf<'a> {
    kind: &'a MaterialKind,
    /// The albedos of `kind` at this point (its own, or its textures').
    albedo: Albedo,
    /// Every lobe of `kind` with `albedo` is a delta.
    delta: bool,
    /// Local frame around the shading normal (two-sided types: flipped to the side of `wo`).
    frame: Frame,
    /// The unit geometric normal, for [`Bsdf::cos_theta`].
    ng: Vec3,
    /// The shading normal differs from the geometric one: `f` carries the factor of the module
    /// doc, for importance the constant `importance_factor` = |wo.ns| / |wo.ng|.
    smooth: bool,
    importance_factor: f32,
    wo_local: Vec3,
    mode: TransportMode,
}

impl<'a> Bsdf<'a> {
    /// The BSDF of `kind` at a vertex with unit geometric normal `ng`, seen from unit `wo`.
    /// `None` when `wo` lies (numerically) in the surface plane, where nothing is defined.
    pub fn new(kind: &'a MaterialKind, ng: Vec3, wo: Vec3, mode: TransportMode) -> Option<Self> {
        Bsdf::shaded(kind, Albedo::of(kind), Normals::flat(ng), wo, mode)
    }

    /// The BSDF of `kind` with the albedos `albedo` (from its textures) on a surface with
    /// `normals` and no parameterisation (an anisotropic type's x axis is then that of
    /// `Frame::from_z(ns)`). `None` when `wo` lies (numerically) in the geometric or the shading
    /// plane.
    pub fn shaded(
        kind: &'a MaterialKind,
        albedo: Albedo,
        normals: Normals,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<Self> {
        Bsdf::oriented(kind, albedo, normals, Azimuth::default(), wo, mode)
    }

    /// [`Bsdf::shaded`] on a surface whose tangent, at `azimuth` about the shading normal (the
    /// surface's dp/du made orthogonal to it: [`Azimuth::of`]), orients anisotropic types as
    /// pbrt-v4 does: their x axis, `uroughness`'s, is the tangent ([`Frame::turned`]).
    #[inline]
    pub fn oriented(
        kind: &'a MaterialKind,
        albedo: Albedo,
        normals: Normals,
        azimuth: Azimuth,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<Self> {
        let Normals { ng, ns } = normals;
        let cos_o = ng.dot(wo);
        if cos_o.abs() < 1e-6 {
            return None;
        }
        let smooth = ns != ng;
        let cos_so = if smooth { ns.dot(wo) } else { cos_o };
        if cos_so.abs() < 1e-6 {
            return None;
        }
        let traits = kind.traits_with(albedo);
        let z = if traits.two_sided && cos_so < 0.0 {
            -ns
        } else {
            ns
        };
        // A rotation of the frame about z changes how the random numbers map to directions:
        // isotropic types, whose values do not depend on it, keep the frame they always had
        // (their images unchanged bit for bit), and only anisotropic ones take the tangent.
        let frame = if traits.anisotropic {
            Frame::turned(ns, z, azimuth)
        } else {
            Frame::from_z(z)
        };
        Some(Bsdf {
            kind,
            albedo,
            delta: traits.delta,
            frame,
            ng,
            smooth,
            importance_factor: if smooth {
                cos_so.abs() / cos_o.abs()
            } else {
                1.0
            },
            wo_local: frame.to_local(wo),
            mode,
        })
    }

    /// What `f` is multiplied by on a smooth surface for the direction `wi` (local `wi_local`).
    fn shading_factor(&self, wi: Vec3, wi_local: Vec3) -> f32 {
        match self.mode {
            TransportMode::Radiance => {
                wi_local.z.abs() / self.ng.dot(wi).abs().max(MIN_GEOMETRIC_COS)
            }
            TransportMode::Importance => self.importance_factor,
        }
    }

    /// Value and pdfs for `wi` (unit), non-delta lobes only.
    #[inline]
    pub fn eval(&self, wi: Vec3) -> BsdfEval {
        self.eval_packed(wi.into())
    }

    /// [`Self::eval`] with `wi` in one 16-byte vector. A 12-byte argument goes to the callee
    /// through memory as two stores (8 and 4 bytes) that its loads straddle, which stalls every
    /// call until the stores retire; one 16-byte store is forwarded to any load within it.
    fn eval_packed(&self, wi: Vec3A) -> BsdfEval {
        let wi = Vec3::from(wi);
        let local = self.frame.to_local(wi);
        let e = self
            .kind
            .eval_with(self.albedo, self.wo_local, local, self.mode);
        if self.smooth {
            BsdfEval {
                f: e.f * self.shading_factor(wi, local),
                ..e
            }
        } else {
            e
        }
    }

    /// Samples `wi` with the random numbers `u` (`u[0]` picks the lobe).
    #[inline]
    pub fn sample(&self, u: [f32; 3]) -> Option<BsdfSample> {
        self.sample_packed(Vec3A::from_array(u))
    }

    /// [`Self::sample`] with `u` in one 16-byte vector, as [`Self::eval_packed`] has its
    /// direction.
    fn sample_packed(&self, u: Vec3A) -> Option<BsdfSample> {
        let u = u.to_array();
        let local = self
            .kind
            .sample_with(self.albedo, self.wo_local, u, self.mode)?;
        let wi = self.frame.to_world(local.wi);
        let f = if self.smooth {
            local.f * self.shading_factor(wi, local.wi)
        } else {
            local.f
        };
        Some(BsdfSample { wi, f, ..local })
    }

    /// The sampling mixture: [`Bsdf::sample`] picks a component by its weight and draws from
    /// its density; a direction below the surface (`frame().z`) is rejected (`None`). Empty
    /// for mirror and glass; [`Lobes::UNBOUNDED`] for a type whose lobes have no closed-form
    /// bound.
    pub fn lobes(&self) -> Lobes {
        self.kind
            .lobes_with(self.albedo, self.wo_local, &self.frame)
    }

    /// True when every lobe is a delta (mirror, glass): no connection or merge can use it.
    pub fn is_delta(&self) -> bool {
        self.delta
    }

    /// `|cos|` between the geometric normal and `w`.
    pub fn cos_theta(&self, w: Vec3) -> f32 {
        if self.smooth {
            self.ng.dot(w).abs()
        } else {
            self.frame.z.dot(w).abs()
        }
    }

    /// Probability of continuing the path at this vertex under Russian roulette: the
    /// largest albedo channel at this point, capped at 1.
    pub fn continuation_probability(&self) -> f32 {
        self.kind
            .continuation_albedo_with(self.albedo)
            .max_component()
            .min(1.0)
    }

    /// The material's kind, with its constant colours (the albedos here may come from
    /// textures).
    pub fn kind(&self) -> &MaterialKind {
        self.kind
    }

    /// The shading frame: `z` is the shading normal (the geometric one on flat surfaces), on
    /// the side of `wo` for two-sided materials.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The shading normal differs from the geometric one here.
    pub fn is_smooth(&self) -> bool {
        self.smooth
    }

    pub fn mode(&self) -> TransportMode {
        self.mode
    }

    pub fn wo_local(&self) -> Vec3 {
        self.wo_local
    }
}

impl BsdfEval {
    pub const ZERO: BsdfEval = BsdfEval {
        f: Rgb::BLACK,
        pdf_w: 0.0,
        rev_pdf_w: 0.0,
    };

    /// The sample of a non-delta lobe at `wi` with these values; `None` where `wi` cannot be
    /// drawn (below the surface, or outside the lobe).
    pub fn sample_at(self, wi: Vec3) -> Option<BsdfSample> {
        (self.pdf_w > 0.0).then_some(BsdfSample {
            wi,
            f: self.f,
            pdf_w: self.pdf_w,
            rev_pdf_w: self.rev_pdf_w,
            delta: false,
        })
    }
}

/// Mirror reflection of a local direction about the normal.
fn reflect_local(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}
