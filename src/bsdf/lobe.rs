//! The components of a BSDF's sampling mixture, and what a sampler that bounds the directions
//! it may draw (UPG's tentative rays, 000 sec. 2.4.3) needs to know of each shape: how to
//! sample the whole lobe, and the closed-form probability of a polar interval around its axis
//! with an exact sampler inside it (000 eqs. 2.63-2.64); for a microfacet lobe sampled by
//! visible normals, a rectangle of Heitz's sampling plane that holds every normal a direction
//! in the cone can come from.

use super::microfacet::{Scatter, TrowbridgeReitz, VisibleNormals};
use crate::sampling::{cosine_hemisphere, power_cosine};
use glam::{DVec3, Vec3};

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

/// A lobe sampled through Trowbridge-Reitz visible normals (conductors, rough dielectrics):
/// the BSDF draws `wm` from D_wo and makes `wi` of it by `scatter`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicrofacetLobe {
    pub distribution: TrowbridgeReitz,
    pub scatter: Scatter,
}

/// A rectangle `[x0, x1] x [y0, y1]` of the visible-normal sampler's plane
/// ([`VisibleNormals::point`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointRect {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
}

impl PointRect {
    pub fn area(&self) -> f64 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }

    /// The point at `u` (uniform in the rectangle).
    pub fn sample(&self, u: [f32; 2]) -> [f32; 2] {
        [
            (self.x0 + u[0] as f64 * (self.x1 - self.x0)) as f32,
            (self.y0 + u[1] as f64 * (self.y1 - self.y0)) as f32,
        ]
    }
}

/// The normals a cone of `wi` can come from are no further than `angle` from `center`.
#[derive(Clone, Copy, Debug)]
struct Cap {
    center: DVec3,
    angle: f64,
}

impl MicrofacetLobe {
    /// The rectangle of sampling points whose normals can scatter `wo` (local, unit) into the
    /// cone of directions within `gamma` of the unit `axis` (local; gamma < 90 degrees), or
    /// `None` where no useful rectangle follows (the whole lobe is sampled then).
    ///
    /// A direction reached through `wm` gives `wm` back as the half vector of the pair: wo +
    /// wi for a reflection, etap wi + wo for a refraction (Walter et al. 2007; etap the index
    /// on the far side over the near one), normalised and turned up. Over the cone,
    /// |d normalize(k wi + wo)| <= k |d wi| / |k wi + wo|, and |k wi + wo|^2 = k^2 + 1 +
    /// 2 k (wo . wi) is least where wo . wi is, at angle(wo, axis) + gamma; the cone is convex,
    /// so every wm lies within gamma times that bound of the axis's half vector (a cap, also
    /// taken mirrored where it crosses the horizon). The stretch to unit roughness moves
    /// normals by at most [`VisibleNormals::stretch_lipschitz`] times as much, and the
    /// projection onto the sampling plane does not lengthen distances: a square around the
    /// cap's centre holds all its points.
    ///
    /// Under a coating (index eta >= 1) the outside cone first refracts into the layer: the
    /// refraction turns polar angles by at most cos / (eta cos') <= 1 / eta and azimuths by
    /// 1 / eta, so the inside cone has at most gamma / eta around the refracted axis, and the
    /// base reflects inside as a conductor does.
    pub fn bound(&self, wo: Vec3, axis: DVec3, gamma: f64) -> Option<PointRect> {
        let normals = self.normals(wo);
        let (wo, axis, gamma) = match self.scatter {
            Scatter::UnderCoating { eta } => {
                if eta < 1.0 || axis.z <= 0.0 {
                    return None;
                }
                let eta = eta as f64;
                let into = |w: DVec3| {
                    let sin2 = (1.0 - w.z * w.z).max(0.0) / (eta * eta);
                    DVec3::new(w.x / eta, w.y / eta, (1.0 - sin2).sqrt()).normalize()
                };
                (
                    self.scatter.seen_from(wo).as_dvec3().normalize(),
                    into(axis),
                    gamma / eta,
                )
            }
            Scatter::Reflect | Scatter::Dielectric { .. } => {
                (wo.as_dvec3().normalize(), axis, gamma)
            }
        };
        let psi = wo.dot(axis).clamp(-1.0, 1.0).acos();
        let least_dot = (psi + gamma).min(std::f64::consts::PI).cos();
        let side = wo.z.signum();
        let mut caps = [None, None];
        // Reflections stay on the side of wo, refractions cross: a cone wholly on one side
        // needs only that one.
        let sin_gamma = gamma.sin();
        if side * axis.z > -sin_gamma {
            caps[0] = Some(Self::cap(1.0, wo, axis, gamma, least_dot)?);
        }
        if let Scatter::Dielectric { eta } = self.scatter {
            if side * axis.z < sin_gamma {
                let etap = if wo.z > 0.0 { eta } else { 1.0 / eta } as f64;
                caps[1] = Some(Self::cap(etap, wo, axis, gamma, least_dot)?);
            }
        }
        let mut rect: Option<PointRect> = None;
        for cap in caps.into_iter().flatten() {
            if cap.angle >= std::f64::consts::FRAC_PI_2 {
                return None;
            }
            // The sampled normal is the cap's or the mirrored cap's, whichever faces up.
            let polar_sin = |c: DVec3| (1.0 - c.z * c.z).max(0.0).sqrt();
            let theta_c = polar_sin(cap.center).asin();
            let min_sin = (theta_c - cap.angle).max(0.0).sin();
            let half = (cap.angle * normals.stretch_lipschitz(min_sin)).min(2.0);
            // Points are computed in f32: a margin well above their rounding.
            let half = half * (1.0 + 1e-4) + 1e-5;
            for center in [cap.center, -cap.center] {
                if center.z < -cap.angle.sin() {
                    continue;
                }
                let ([cx, cy], _) = normals.project(center);
                let square = PointRect {
                    x0: (cx - half).max(-1.0),
                    x1: (cx + half).min(1.0),
                    y0: (cy - half).max(-1.0),
                    y1: (cy + half).min(1.0),
                };
                rect = Some(match rect {
                    None => square,
                    Some(r) => PointRect {
                        x0: r.x0.min(square.x0),
                        x1: r.x1.max(square.x1),
                        y0: r.y0.min(square.y0),
                        y1: r.y1.max(square.y1),
                    },
                });
            }
        }
        rect.filter(|r| r.x1 > r.x0 && r.y1 > r.y0)
    }

    /// The cap of normalize(k wi + wo) over the cone (k = 1 reflects), `None` where the bound
    /// degenerates (wi can come near -wo / k).
    fn cap(k: f64, wo: DVec3, axis: DVec3, gamma: f64, least_dot: f64) -> Option<Cap> {
        let least2 = k * k + 1.0 + 2.0 * k * least_dot;
        let v = k * axis + wo;
        if least2 < 1e-6 || v.length_squared() < 1e-12 {
            return None;
        }
        Some(Cap {
            center: v.normalize(),
            angle: k * gamma / least2.sqrt(),
        })
    }

    /// The visible-normal sampler of this lobe for `wo` (local).
    pub fn normals(&self, wo: Vec3) -> VisibleNormals {
        VisibleNormals::new(&self.distribution, self.scatter.seen_from(wo))
    }
}

/// One component of a BSDF's sampling mixture, as a bounding sampler sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LobeKind {
    /// A density around an axis (lambert, Phong, diffuse transmission).
    Polar(Lobe),
    /// Trowbridge-Reitz visible normals, drawn with probability `weight`.
    Microfacet { weight: f32, lobe: MicrofacetLobe },
    /// One direction (world space), drawn with probability `weight`: a smooth coating's
    /// reflection beside a non-delta base.
    Delta { weight: f32, direction: Vec3 },
}

/// The components of a BSDF's sampling mixture with positive weight (at most three, none for
/// a delta BSDF), or the word that its lobes have no closed-form bound, so a bounding sampler
/// must sample the whole BSDF.
#[derive(Clone, Copy, Debug)]
pub struct Lobes {
    items: [LobeKind; 3],
    len: usize,
    bounded: bool,
}

impl Lobes {
    const UNUSED: LobeKind = LobeKind::Delta {
        weight: 0.0,
        direction: Vec3::Z,
    };

    /// No component: a delta BSDF.
    pub const NONE: Lobes = Lobes {
        items: [Lobes::UNUSED; 3],
        len: 0,
        bounded: true,
    };

    /// No closed-form bound: sample the whole BSDF.
    pub const UNBOUNDED: Lobes = Lobes {
        bounded: false,
        ..Lobes::NONE
    };

    /// The components; empty when [`Lobes::is_bounded`] is false.
    pub fn as_slice(&self) -> &[LobeKind] {
        &self.items[..self.len]
    }

    pub fn is_bounded(&self) -> bool {
        self.bounded
    }

    /// Adds a component (at most three); one of zero weight is left out.
    pub fn push(&mut self, component: LobeKind) {
        let weight = match component {
            LobeKind::Polar(lobe) => lobe.weight,
            LobeKind::Microfacet { weight, .. } | LobeKind::Delta { weight, .. } => weight,
        };
        if weight > 0.0 {
            self.items[self.len] = component;
            self.len += 1;
        }
    }

    /// This and `component`.
    pub fn with(mut self, component: LobeKind) -> Lobes {
        self.push(component);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    /// Every sample the BSDF's own sampler sends into the cone comes from a point inside the
    /// rectangle: random lobes (isotropic and anisotropic, reflecting, refracting and under a
    /// coating, alpha
    /// 0.005 to 1.5), random `wo` (grazing and from inside), random cones of 0.1 to 20
    /// degrees, most of them aimed at a sampled direction so that hits are many.
    #[test]
    fn the_rectangle_holds_every_point_whose_direction_reaches_the_cone() {
        let mut rng = Rng::for_sample(3, 0, 0, Stream::Tentative);
        let (mut bounded, mut hits) = (0, 0u64);
        for case in 0..400 {
            let mut r = || rng.next_f32();
            let alpha = |u: f32| 0.005f32 * 300f32.powf(u);
            let ax = alpha(r());
            let ay = if case % 2 == 0 { ax } else { alpha(r()) };
            let eta = 1.1 + 0.8 * r();
            let scatter = match case % 3 {
                0 => Scatter::Reflect,
                1 => Scatter::Dielectric { eta },
                _ => Scatter::UnderCoating { eta },
            };
            let lobe = MicrofacetLobe {
                distribution: TrowbridgeReitz::new(ax, ay),
                scatter,
            };
            let cos_o = if scatter.transmits() && case % 4 == 1 {
                -0.02 - 0.97 * r()
            } else {
                0.01 + 0.99 * r()
            };
            let phi_o = std::f32::consts::TAU * r();
            let sin_o = (1.0 - cos_o * cos_o).sqrt();
            let wo = Vec3::new(sin_o * phi_o.cos(), sin_o * phi_o.sin(), cos_o);
            let gamma = (0.1f64 + 19.9 * r() as f64).to_radians();
            // The cone around a direction the BSDF samples, or a random one.
            let normals = lobe.normals(wo);
            let aim = [r(), r(), r()];
            let axis = if case % 5 == 0 {
                DVec3::new(r() as f64 - 0.5, r() as f64 - 0.5, r() as f64 - 0.5).normalize()
            } else {
                match lobe
                    .scatter
                    .apply(wo, normals.lift(normals.point([aim[1], aim[2]])), aim[0])
                {
                    Some(wi) => wi.as_dvec3().normalize(),
                    None => continue,
                }
            };
            let Some(rect) = lobe.bound(wo, axis, gamma) else {
                continue;
            };
            bounded += 1;
            for _ in 0..4000 {
                let (u0, p) = (rng.next_f32(), [rng.next_f32(), rng.next_f32()]);
                let p = normals.point(p);
                let Some(wi) = lobe.scatter.apply(wo, normals.lift(p), u0) else {
                    continue;
                };
                if wi.as_dvec3().normalize().dot(axis) >= gamma.cos() {
                    hits += 1;
                    let (x, y) = (p[0] as f64, p[1] as f64);
                    assert!(
                        (rect.x0..=rect.x1).contains(&x) && (rect.y0..=rect.y1).contains(&y),
                        "case {case}: {lobe:?} wo {wo} axis {axis} gamma {gamma}: point {p:?} \
                         outside {rect:?}"
                    );
                }
            }
        }
        assert!(
            bounded > 150 && hits > 100_000,
            "{bounded} bounds, {hits} hits"
        );
    }
}
