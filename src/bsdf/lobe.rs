//! The components of a BSDF's sampling mixture, and what a sampler that bounds the directions
//! it may draw (UPG's tentative rays, 000 sec. 2.4.3) needs to know of each shape: how to
//! sample the whole lobe, and the closed-form probability of a polar interval around its axis
//! with an exact sampler inside it (000 eqs. 2.63-2.64).

use crate::sampling::{cosine_hemisphere, power_cosine};
use glam::Vec3;

/// The density of a non-delta lobe around its axis, on the hemisphere the axis points to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LobeShape {
    /// cos(theta) / pi (lambert, Phong's diffuse part).
    Cosine,
    /// (n + 1) / (2 pi) cos^n(alpha) (Phong's glossy part).
    PowerCosine { exponent: f32 },
}

/// Polar angles [theta0, theta1] around a lobe's axis, within its hemisphere, by their
/// cosines and sines.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolarInterval {
    pub cos0: f64,
    pub sin0: f64,
    pub cos1: f64,
    pub sin1: f64,
    /// sin(theta1 - theta0) where the caller knows it to more digits than the ends give (a
    /// narrow interval); `None` computes it from the ends.
    pub sin_width: Option<f64>,
}

/// The polar part of a lobe's bound: the probability the lobe gives its interval (its polar
/// CDF across it) and an exact sampler inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PolarBound {
    /// Cosine lobe: its polar CDF sin^2(theta) is uniform in `[lo, lo + span]`.
    SinSquared { lo: f64, span: f64 },
    /// Power-cosine lobe: 1 - cos^(n+1)(alpha) is its polar CDF, so cos^(n+1)(alpha) is uniform
    /// in `[hi - span, hi]`.
    PowerCosine { hi: f64, span: f64, inv_n1: f64 },
}

impl LobeShape {
    /// A direction from the whole lobe around +z, with the warp the BSDF itself samples by.
    pub fn sample(&self, u: [f32; 2]) -> Vec3 {
        match *self {
            LobeShape::Cosine => cosine_hemisphere(u),
            LobeShape::PowerCosine { exponent } => power_cosine(u, exponent),
        }
    }

    /// The bound of the polar interval `interval`.
    pub fn polar_bound(&self, interval: &PolarInterval) -> PolarBound {
        let PolarInterval {
            cos0,
            sin0,
            cos1,
            sin1,
            sin_width,
        } = *interval;
        match *self {
            LobeShape::Cosine => {
                // sin^2(theta1) - sin^2(theta0) = sin(theta1 + theta0) sin(theta1 - theta0).
                let sin_difference = sin_width.unwrap_or(sin1 * cos0 - cos1 * sin0);
                PolarBound::SinSquared {
                    lo: sin0 * sin0,
                    span: (sin1 * cos0 + cos1 * sin0) * sin_difference,
                }
            }
            LobeShape::PowerCosine { exponent } => {
                let n1 = exponent as f64 + 1.0;
                let hi = cos0.powf(n1);
                PolarBound::PowerCosine {
                    hi,
                    span: hi - cos1.powf(n1),
                    inv_n1: 1.0 / n1,
                }
            }
        }
    }
}

impl PolarBound {
    /// The lobe's probability of the interval, over all azimuths.
    pub fn mass(&self) -> f64 {
        match *self {
            PolarBound::SinSquared { span, .. } | PolarBound::PowerCosine { span, .. } => span,
        }
    }

    /// The cosine and sine of a polar angle from the lobe's density restricted to the
    /// interval, `u` uniform.
    pub fn sample(&self, u: f32) -> (f64, f64) {
        match *self {
            PolarBound::SinSquared { lo, span } => {
                let sin2 = (lo + u as f64 * span).clamp(0.0, 1.0);
                ((1.0 - sin2).sqrt(), sin2.sqrt())
            }
            PolarBound::PowerCosine { hi, span, inv_n1 } => {
                let c = (hi - u as f64 * span).max(0.0).powf(inv_n1).min(1.0);
                (c, (1.0 - c * c).sqrt())
            }
        }
    }
}

/// One component of a BSDF's sampling mixture, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    /// Probability that [`super::Bsdf::sample`] draws from this component.
    pub weight: f32,
    /// Unit axis: the shading frame's `z` for [`LobeShape::Cosine`], the mirror direction of
    /// `wo` for [`LobeShape::PowerCosine`].
    pub axis: Vec3,
    pub shape: LobeShape,
}

/// The components of a BSDF's sampling mixture with positive weight (at most two, none for a
/// delta BSDF), or the word that its lobes have no closed-form bound, so a bounding sampler
/// must sample the whole BSDF.
#[derive(Clone, Copy, Debug)]
pub struct Lobes {
    items: [Lobe; 2],
    len: usize,
    bounded: bool,
}

impl Lobes {
    const UNUSED: Lobe = Lobe {
        weight: 0.0,
        axis: Vec3::Z,
        shape: LobeShape::Cosine,
    };

    /// No component: a delta BSDF.
    pub const NONE: Lobes = Lobes {
        items: [Lobes::UNUSED; 2],
        len: 0,
        bounded: true,
    };

    /// No closed-form bound: sample the whole BSDF.
    pub const UNBOUNDED: Lobes = Lobes {
        bounded: false,
        ..Lobes::NONE
    };

    /// The components, each with a closed-form bound; empty when [`Lobes::is_bounded`] is
    /// false.
    pub fn as_slice(&self) -> &[Lobe] {
        &self.items[..self.len]
    }

    pub fn is_bounded(&self) -> bool {
        self.bounded
    }

    /// Adds a component (at most two).
    pub fn push(&mut self, lobe: Lobe) {
        self.items[self.len] = lobe;
        self.len += 1;
    }
}
