//! The BSDF types a material can have, and the one place that turns a [`MaterialKind`] into
//! its type.

use super::params::{
    BsdfError, EnergyExcess, EnergyFix, ParamKind, ParamRange, ParamReader, ParamSpec, ParamValue,
    Params,
};
use super::Albedo;
use crate::color::Rgb;

/// The scattering part of a material.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialKind {
    Lambert {
        kd: Rgb,
    },
    /// Lafortune's energy-conserving Phong, f = kd/pi + ks (n+2)/(2 pi) cos^n(alpha) (000 eq. 3.1).
    Phong {
        kd: Rgb,
        ks: Rgb,
        exponent: f32,
    },
    Mirror {
        ks: Rgb,
    },
    Glass {
        ior: f32,
    },
}

const fn color(name: &'static str, default: f32) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamKind::Color,
        default: ParamValue::Color(Rgb::splat(default)),
        range: ParamRange::NonNegative,
    }
}

const fn number(name: &'static str, default: f32, range: ParamRange) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamKind::Number,
        default: ParamValue::Number(default),
        range,
    }
}

const LAMBERT: &[ParamSpec] = &[color("kd", 0.8)];
const PHONG: &[ParamSpec] = &[
    color("kd", 0.8),
    color("ks", 0.0),
    number("exponent", 1.0, ParamRange::NonNegative),
];
const MIRROR: &[ParamSpec] = &[color("ks", 1.0)];
const GLASS: &[ParamSpec] = &[number("ior", 1.5, ParamRange::Positive)];

impl MaterialKind {
    /// The type names scene files use, in the order of the variants.
    pub const TYPE_NAMES: &'static [&'static str] = &["lambert", "phong", "mirror", "glass"];

    /// The name scene files give this kind's type.
    pub fn type_name(&self) -> &'static str {
        match self {
            MaterialKind::Lambert { .. } => "lambert",
            MaterialKind::Phong { .. } => "phong",
            MaterialKind::Mirror { .. } => "mirror",
            MaterialKind::Glass { .. } => "glass",
        }
    }

    /// The parameters the type `type_name` reads, with their defaults.
    pub fn param_specs(type_name: &str) -> Result<&'static [ParamSpec], BsdfError> {
        match type_name {
            "lambert" => Ok(LAMBERT),
            "phong" => Ok(PHONG),
            "mirror" => Ok(MIRROR),
            "glass" => Ok(GLASS),
            _ => Err(BsdfError::UnknownType {
                name: type_name.to_string(),
            }),
        }
    }

    /// The kind of type `type_name` from `params`: an absent parameter takes its default
    /// ([`MaterialKind::param_specs`]); parameters the type does not read are ignored (a
    /// front-end that wants to flag them compares with the specs).
    pub fn from_params(type_name: &str, params: &Params) -> Result<MaterialKind, BsdfError> {
        let specs = MaterialKind::param_specs(type_name)?;
        let read = |type_name| ParamReader {
            type_name,
            specs,
            params,
        };
        Ok(match type_name {
            "lambert" => {
                let p = read("lambert");
                MaterialKind::Lambert { kd: p.color("kd")? }
            }
            "phong" => {
                let p = read("phong");
                MaterialKind::Phong {
                    kd: p.color("kd")?,
                    ks: p.color("ks")?,
                    exponent: p.number("exponent")?,
                }
            }
            "mirror" => {
                let p = read("mirror");
                MaterialKind::Mirror { ks: p.color("ks")? }
            }
            _ => {
                let p = read("glass");
                MaterialKind::Glass {
                    ior: p.number("ior")?,
                }
            }
        })
    }

    /// Every parameter of this kind's type with its value here: what
    /// [`MaterialKind::from_params`] rebuilds the kind from.
    pub fn params(&self) -> Params {
        match *self {
            MaterialKind::Lambert { kd } => Params::new().with_color("kd", kd),
            MaterialKind::Phong { kd, ks, exponent } => Params::new()
                .with_color("kd", kd)
                .with_color("ks", ks)
                .with_number("exponent", exponent),
            MaterialKind::Mirror { ks } => Params::new().with_color("ks", ks),
            MaterialKind::Glass { ior } => Params::new().with_number("ior", ior),
        }
    }

    /// Whether this kind reflects more than it receives in some channel, and the kind that
    /// does not: a single reflectance above 1 is clamped, Phong's kd + ks above 1 (000 eq.
    /// 3.1 conserves energy only up to 1) is scaled down per channel.
    pub fn energy_excess(&self) -> Option<EnergyExcess> {
        let clamped = |what, c: Rgb, kind: fn(Rgb) -> MaterialKind| {
            (c.max_component() > 1.0).then(|| EnergyExcess {
                what,
                total: c,
                fix: EnergyFix::Clamped,
                conserving: kind(Rgb::new(c.r.min(1.0), c.g.min(1.0), c.b.min(1.0))),
            })
        };
        match *self {
            MaterialKind::Lambert { kd } => clamped("kd", kd, |kd| MaterialKind::Lambert { kd }),
            MaterialKind::Mirror { ks } => clamped("ks", ks, |ks| MaterialKind::Mirror { ks }),
            MaterialKind::Phong { kd, ks, exponent } => {
                let total = kd + ks;
                if total.max_component() <= 1.0 + 1e-6 {
                    return None;
                }
                let f = |c: f32| if c > 1.0 { 1.0 / c } else { 1.0 };
                let scale = Rgb::new(f(total.r), f(total.g), f(total.b));
                Some(EnergyExcess {
                    what: "kd + ks",
                    total,
                    fix: EnergyFix::Scaled,
                    conserving: MaterialKind::Phong {
                        kd: kd * scale,
                        ks: ks * scale,
                        exponent,
                    },
                })
            }
            MaterialKind::Glass { .. } => None,
        }
    }

    /// The albedos at a surface point where textures give `kd` and/or `ks` (the kind's own
    /// colours elsewhere), limited so the point conserves energy: each texel to [0, 1], and
    /// Phong's kd to 1 - ks per channel.
    pub fn textured_albedo(&self, kd: Option<Rgb>, ks: Option<Rgb>) -> Albedo {
        let mut albedo = Albedo::of(self);
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
            let limit = match self {
                MaterialKind::Phong { .. } => Rgb::WHITE - albedo.ks,
                _ => Rgb::WHITE,
            };
            albedo.kd = clamp(kd, limit);
        }
        albedo
    }

    /// Mirror and glass scatter only into delta directions.
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            MaterialKind::Mirror { .. } | MaterialKind::Glass { .. }
        )
    }
}
