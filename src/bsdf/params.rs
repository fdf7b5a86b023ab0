//! The generic description of a BSDF that scene front-ends read and write: a type name and a
//! small set of named colours and numbers, so a front-end builds and inspects materials
//! without knowing the BSDF types.

use crate::color::Rgb;
use std::fmt;
use thiserror::Error;

/// One parameter's value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamValue {
    Color(Rgb),
    Number(f32),
}

/// What a parameter holds; a colour parameter also takes a number (a grey).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    Color,
    Number,
}

/// A parameter a BSDF type reads: its name, what it holds, its value when absent, and the
/// values it accepts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    pub default: ParamValue,
    pub range: ParamRange,
}

/// The values a parameter accepts (every channel of a colour); all must be finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamRange {
    /// >= 0.
    NonNegative,
    /// > 0.
    Positive,
}

/// Named parameters, each name at most once, in the order they were first set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Params {
    entries: Vec<(String, ParamValue)>,
}

impl Params {
    pub fn new() -> Self {
        Params::default()
    }

    pub fn with_color(mut self, name: &str, value: Rgb) -> Self {
        self.set(name, ParamValue::Color(value));
        self
    }

    pub fn with_number(mut self, name: &str, value: f32) -> Self {
        self.set(name, ParamValue::Number(value));
        self
    }

    /// Sets `name`, replacing an earlier value.
    pub fn set(&mut self, name: &str, value: ParamValue) {
        match self.entries.iter_mut().find(|(n, _)| n == name) {
            Some(entry) => entry.1 = value,
            None => self.entries.push((name.to_string(), value)),
        }
    }

    pub fn get(&self, name: &str) -> Option<ParamValue> {
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }

    /// `name` as a colour (a number is a grey); `None` when absent or a colour is not allowed.
    pub fn color(&self, name: &str) -> Option<Rgb> {
        match self.get(name)? {
            ParamValue::Color(c) => Some(c),
            ParamValue::Number(x) => Some(Rgb::splat(x)),
        }
    }

    /// `name` as a number; `None` when absent or a colour.
    pub fn number(&self, name: &str) -> Option<f32> {
        match self.get(name)? {
            ParamValue::Number(x) => Some(x),
            ParamValue::Color(_) => None,
        }
    }

    /// Sets every parameter of `other`, which win over the ones here.
    pub fn overlay(&mut self, other: &Params) {
        for (name, value) in &other.entries {
            self.set(name, *value);
        }
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, ParamValue)> {
        self.entries.iter().map(|(n, v)| (n.as_str(), *v))
    }
}

/// Why a parameter was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamProblem {
    /// A colour where a number is needed.
    NotANumber,
    NotFinite,
    Negative,
    NotPositive,
}

impl fmt::Display for ParamProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParamProblem::NotANumber => "must be a number, not a colour",
            ParamProblem::NotFinite => "must be finite",
            ParamProblem::Negative => "must not be negative",
            ParamProblem::NotPositive => "must be positive",
        })
    }
}

#[derive(Clone, Debug, PartialEq, Error)]
pub enum BsdfError {
    #[error("unknown material type '{name}' ({known})", known = super::MaterialKind::TYPE_NAMES.join(", "))]
    UnknownType { name: String },
    #[error("{type_name} parameter '{param}' {problem}")]
    BadParameter {
        type_name: &'static str,
        param: &'static str,
        problem: ParamProblem,
    },
}

/// How [`EnergyExcess::conserving`] was made from the kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnergyFix {
    /// Each channel above 1 set to 1 (a single reflectance).
    Clamped,
    /// Each channel whose sum exceeds 1 scaled by 1 / sum (several lobes sharing the energy).
    Scaled,
}

/// A kind that reflects more than it receives.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyExcess {
    /// The quantity above 1, as parameters are named: "kd", "ks" or "kd + ks".
    pub what: &'static str,
    /// Its value per channel.
    pub total: Rgb,
    pub fix: EnergyFix,
    /// The kind brought down to 1 per channel.
    pub conserving: super::MaterialKind,
}

/// A colour parameter in `[0, inf)`.
pub(super) const fn color(name: &'static str, default: f32) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamKind::Color,
        default: ParamValue::Color(Rgb::splat(default)),
        range: ParamRange::NonNegative,
    }
}

/// A number parameter.
pub(super) const fn number(name: &'static str, default: f32, range: ParamRange) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamKind::Number,
        default: ParamValue::Number(default),
        range,
    }
}

/// Each channel above 1 set to 1.
pub(super) fn clamp_to_one(c: Rgb) -> Rgb {
    Rgb::new(c.r.min(1.0), c.g.min(1.0), c.b.min(1.0))
}

/// The parameters of one BSDF type as it reads them: each value checked against its spec,
/// absent ones at their defaults.
pub struct ParamReader<'a> {
    type_name: &'static str,
    specs: &'static [ParamSpec],
    params: &'a Params,
}

impl<'a> ParamReader<'a> {
    pub(super) fn new(
        type_name: &'static str,
        specs: &'static [ParamSpec],
        params: &'a Params,
    ) -> Self {
        ParamReader {
            type_name,
            specs,
            params,
        }
    }

    fn value(&self, name: &str) -> Result<ParamValue, BsdfError> {
        let spec = self
            .specs
            .iter()
            .find(|s| s.name == name)
            .expect("a BSDF type reads only the parameters it declares");
        check(
            self.type_name,
            spec,
            self.params.get(name).unwrap_or(spec.default),
        )
    }

    /// Whether the scene gave `name` (otherwise its default applies).
    pub fn is_given(&self, name: &str) -> bool {
        self.params.get(name).is_some()
    }

    pub fn color(&self, name: &str) -> Result<Rgb, BsdfError> {
        match self.value(name)? {
            ParamValue::Color(c) => Ok(c),
            ParamValue::Number(x) => Ok(Rgb::splat(x)),
        }
    }

    pub fn number(&self, name: &str) -> Result<f32, BsdfError> {
        match self.value(name)? {
            ParamValue::Number(x) => Ok(x),
            ParamValue::Color(c) => Ok(c.r),
        }
    }
}

/// Checks `value` of `spec` for the type `type_name`.
fn check(
    type_name: &'static str,
    spec: &ParamSpec,
    value: ParamValue,
) -> Result<ParamValue, BsdfError> {
    let bad = |problem| BsdfError::BadParameter {
        type_name,
        param: spec.name,
        problem,
    };
    let value = match (spec.kind, value) {
        (ParamKind::Color, ParamValue::Number(x)) => ParamValue::Color(Rgb::splat(x)),
        (ParamKind::Number, ParamValue::Color(_)) => return Err(bad(ParamProblem::NotANumber)),
        (_, v) => v,
    };
    let (lowest, finite) = match value {
        ParamValue::Color(c) => (c.min_component(), c.is_finite()),
        ParamValue::Number(x) => (x, x.is_finite()),
    };
    if !finite {
        return Err(bad(ParamProblem::NotFinite));
    }
    match spec.range {
        ParamRange::NonNegative if lowest < 0.0 => Err(bad(ParamProblem::Negative)),
        ParamRange::Positive if lowest <= 0.0 => Err(bad(ParamProblem::NotPositive)),
        _ => Ok(value),
    }
}
