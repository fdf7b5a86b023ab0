//! The registry of BSDF types: [`registry!`] turns one line per type into the module, the
//! [`MaterialKind`] variant (the type's fields, constructible like a struct) and every dispatch
//! from a kind to its type, so a kind is matched here alone and adding a type takes its file
//! plus its line. The construction API scene front-ends use is generic over the types.

use super::params::{BsdfError, EnergyExcess, Params};
use super::{Albedo, Bxdf};
use crate::color::Rgb;

/// Declares the BSDF types, each as `module::Type { field: Type, ... }` where `module.rs`
/// defines `Type`, a struct with exactly those (`Copy`) fields implementing
/// [`super::BxdfType`].
macro_rules! registry {
    ($($(#[$doc:meta])* $module:ident::$ty:ident { $($field:ident: $fty:ty),* $(,)? }),* $(,)?) => {
        $(mod $module; pub use $module::$ty;)*

        /// The scattering part of a material: one variant per BSDF type, with its parameters.
        #[derive(Clone, Debug, PartialEq)]
        pub enum MaterialKind {
            $($(#[$doc])* $ty { $($field: $fty),* },)*
        }

        $(impl From<$ty> for MaterialKind {
            fn from(b: $ty) -> Self {
                let $ty { $($field),* } = b;
                MaterialKind::$ty { $($field),* }
            }
        })*

        impl MaterialKind {
            /// The type names scene files use, in the order of the variants.
            pub const TYPE_NAMES: &'static [&'static str] =
                &[$(<$ty as $crate::bsdf::BxdfType>::NAME),*];

            /// The name scene files give this kind's type.
            pub fn type_name(&self) -> &'static str {
                match self {
                    $(MaterialKind::$ty { .. } => <$ty as $crate::bsdf::BxdfType>::NAME,)*
                }
            }

            /// The parameters the type `type_name` reads, with their defaults.
            pub fn param_specs(
                type_name: &str,
            ) -> Result<&'static [$crate::bsdf::ParamSpec], $crate::bsdf::BsdfError> {
                $(if type_name == <$ty as $crate::bsdf::BxdfType>::NAME {
                    return Ok(<$ty as $crate::bsdf::BxdfType>::PARAMS);
                })*
                Err($crate::bsdf::BsdfError::UnknownType {
                    name: type_name.to_string(),
                })
            }

            /// What a [`super::Bsdf`] needs to know of this kind with the albedos `albedo`
            /// before it builds its frame, from one dispatch.
            #[inline]
            fn traits_with(&self, albedo: $crate::bsdf::Albedo) -> $crate::bsdf::Traits {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $crate::bsdf::Traits::of(&$ty { $($field),* }.with_albedo(albedo))
                    })*
                }
            }

            /// [`Bxdf::eval`] of this kind with the albedos `albedo`. A BSDF keeps the kind by
            /// reference and its albedos beside it rather than a copy of the kind with them:
            /// a kind is up to some 200 bytes, copied at every vertex, while the albedos are
            /// put in place here at no cost a profile can see.
            #[inline]
            fn eval_with(
                &self,
                albedo: $crate::bsdf::Albedo,
                wo: glam::Vec3,
                wi: glam::Vec3,
                mode: $crate::bsdf::TransportMode,
            ) -> $crate::bsdf::BsdfEval {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.with_albedo(albedo).eval(wo, wi, mode)
                    })*
                }
            }

            /// [`Bxdf::sample`] of this kind with the albedos `albedo`.
            #[inline]
            fn sample_with(
                &self,
                albedo: $crate::bsdf::Albedo,
                wo: glam::Vec3,
                u: [f32; 3],
                mode: $crate::bsdf::TransportMode,
            ) -> Option<$crate::bsdf::BsdfSample> {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.with_albedo(albedo).sample(wo, u, mode)
                    })*
                }
            }

            /// [`Bxdf::continuation_albedo`] of this kind with the albedos `albedo`.
            #[inline]
            fn continuation_albedo_with(
                &self,
                albedo: $crate::bsdf::Albedo,
            ) -> $crate::color::Rgb {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.with_albedo(albedo).continuation_albedo()
                    })*
                }
            }

            /// [`Bxdf::lobes`] of this kind with the albedos `albedo`.
            #[inline]
            fn lobes_with(
                &self,
                albedo: $crate::bsdf::Albedo,
                wo: glam::Vec3,
                frame: &$crate::frame::Frame,
            ) -> $crate::bsdf::Lobes {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.with_albedo(albedo).lobes(wo, frame)
                    })*
                }
            }

            fn build(
                type_name: &str,
                params: &$crate::bsdf::Params,
            ) -> Result<MaterialKind, $crate::bsdf::BsdfError> {
                $(if type_name == <$ty as $crate::bsdf::BxdfType>::NAME {
                    let reader = $crate::bsdf::ParamReader::new(
                        <$ty as $crate::bsdf::BxdfType>::NAME,
                        <$ty as $crate::bsdf::BxdfType>::PARAMS,
                        params,
                    );
                    return <$ty as $crate::bsdf::BxdfType>::from_params(&reader).map(Into::into);
                })*
                Err($crate::bsdf::BsdfError::UnknownType {
                    name: type_name.to_string(),
                })
            }
        }

        impl $crate::bsdf::Bxdf for MaterialKind {
            #[inline]
            fn params(&self) -> $crate::bsdf::Params {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.params(),)*
                }
            }

            #[inline]
            fn energy_excess(&self) -> Option<$crate::bsdf::EnergyExcess> {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.energy_excess(),)*
                }
            }

            #[inline]
            fn albedo(&self) -> $crate::bsdf::Albedo {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.albedo(),)*
                }
            }

            #[inline]
            fn with_albedo(&self, albedo: $crate::bsdf::Albedo) -> Self {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.with_albedo(albedo).into()
                    })*
                }
            }

            #[inline]
            fn kd_limit(&self, ks: $crate::color::Rgb) -> $crate::color::Rgb {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.kd_limit(ks),)*
                }
            }

            #[inline]
            fn is_delta(&self) -> bool {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.is_delta(),)*
                }
            }

            #[inline]
            fn anisotropic(&self) -> bool {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.anisotropic(),)*
                }
            }

            #[inline]
            fn two_sided(&self) -> bool {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.two_sided(),)*
                }
            }

            #[inline]
            fn eval(
                &self,
                wo: glam::Vec3,
                wi: glam::Vec3,
                mode: $crate::bsdf::TransportMode,
            ) -> $crate::bsdf::BsdfEval {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.eval(wo, wi, mode),)*
                }
            }

            #[inline]
            fn sample(
                &self,
                wo: glam::Vec3,
                u: [f32; 3],
                mode: $crate::bsdf::TransportMode,
            ) -> Option<$crate::bsdf::BsdfSample> {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.sample(wo, u, mode),)*
                }
            }

            #[inline]
            fn continuation_albedo(&self) -> $crate::color::Rgb {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => {
                        $ty { $($field),* }.continuation_albedo()
                    })*
                }
            }

            #[inline]
            fn lobes(&self, wo: glam::Vec3, frame: &$crate::frame::Frame) -> $crate::bsdf::Lobes {
                match *self {
                    $(MaterialKind::$ty { $($field),* } => $ty { $($field),* }.lobes(wo, frame),)*
                }
            }
        }
    };
}

impl super::MaterialKind {
    /// The kind of type `type_name` from `params`: an absent parameter takes its default
    /// ([`super::MaterialKind::param_specs`]); parameters the type does not read are ignored (a
    /// front-end that wants to flag them compares with the specs).
    pub fn from_params(type_name: &str, params: &Params) -> Result<Self, BsdfError> {
        Self::build(type_name, params)
    }

    /// Every parameter of this kind's type with its value here: what
    /// [`super::MaterialKind::from_params`] rebuilds the kind from.
    pub fn params(&self) -> Params {
        Bxdf::params(self)
    }

    /// Whether this kind reflects more than it receives in some channel, and the kind that
    /// does not: a single reflectance above 1 is clamped, Phong's kd + ks above 1 (000 eq.
    /// 3.1 conserves energy only up to 1) is scaled down per channel.
    pub fn energy_excess(&self) -> Option<EnergyExcess> {
        Bxdf::energy_excess(self)
    }

    /// The albedos at a surface point where textures give `kd` and/or `ks` (the kind's own
    /// colours elsewhere), limited so the point conserves energy: each texel to [0, 1], and
    /// kd further where the type needs it (Phong: to 1 - ks per channel).
    pub fn textured_albedo(&self, kd: Option<Rgb>, ks: Option<Rgb>) -> Albedo {
        let mut albedo = Bxdf::albedo(self);
        let clamp = |c: Rgb, limit: Rgb| {
            Rgb::new(
                c.r.clamp(0.0, limit.r.max(0.0)),
                c.g.clamp(0.0, limit.g.max(0.0)),
                c.b.clamp(0.0, limit.b.max(0.0)),
            )
        };
        if let Some(ks) = ks {
            albedo.ks = clamp(ks, Rgb::WHITE);
        }
        if let Some(kd) = kd {
            albedo.kd = clamp(kd, self.kd_limit(albedo.ks));
        }
        albedo
    }

    /// Its roughness differs along the two tangent axes: the BSDF needs the surface's tangent
    /// (see [`super::Bsdf::oriented`]).
    pub fn is_anisotropic(&self) -> bool {
        Bxdf::anisotropic(self)
    }

    /// Mirror and glass scatter only into delta directions.
    pub fn is_delta(&self) -> bool {
        Bxdf::is_delta(self)
    }
}
