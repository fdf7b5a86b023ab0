//! The reciprocal acceptance probability 1/p_acc of a merge, estimated without bias.
//!
//! p_acc is the probability that a direction sampled from the BSDF at an origin vertex, traced
//! to its first hit, lands within `r` of a target point (000 eqs. 2.56-2.57). The number N of
//! such Bernoulli trials up to the first success has mean 1/p_acc (000 eqs. 2.61-2.62). Trials
//! are drawn only inside an angular bound around the cone that the r-sphere subtends; if the
//! bound holds BSDF probability P, the bounded count has mean P/p_acc, so N/P estimates 1/p_acc
//! (000 eqs. 2.63-2.65).
//!
//! The bound of each lobe is an interval of polar and azimuthal angles in the lobe's own frame,
//! where its pdf factorises: P is closed form and sampling inside the bound is exact by
//! inverting the two CDFs.
//!
//! A Trowbridge-Reitz lobe (conductors, rough dielectrics) is sampled through visible
//! normals, which factorise in no angles around a fixed axis. Its bound lives in Heitz's
//! sampling plane instead, where the BSDF's points are uniform over a region of area A: a
//! rectangle R that holds the point of every normal a direction in the cone can come from
//! ([`crate::bsdf::MicrofacetLobe::bound`]). A trial draws a point uniformly in R and fails at
//! once outside the region; inside, it lifts and scatters it as the BSDF does. Its density is
//! then the BSDF's times A / |R| wherever a success is possible: P = |R| / A.
//!
//! For a mixture (Phong's diffuse and glossy parts, weights w_c, bounds B_c with mass p_c) a
//! trial picks component c with probability w_c p_c / P, P = sum_c w_c p_c, and draws from
//! pdf_c / p_c on B_c. Its density at w is (1/P) sum_c w_c pdf_c(w) [w in B_c]. Every direction
//! that can succeed lies in the cone, hence in every B_c where pdf_c is not zero, so there the
//! density is pdf(w) / P: a trial succeeds with probability p_acc / P and E[N / P] = 1/p_acc.

use crate::accel::{offset_ray_origin, Ray, PACKET};
use crate::bsdf::microfacet::{Scatter, VisibleNormals};
use crate::bsdf::{
    Bsdf, Lobe, LobeKind, LobeShape, MicrofacetLobe, PointRect, PolarBound, PolarInterval,
};
use crate::sampling::Rng;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::f64::consts::PI;
use thiserror::Error;

/// A bound holding at least this share of a lobe's probability saves too few trials to be
/// worth its own sampler; the whole lobe is sampled instead.
const WHOLE_LOBE_SHARE: f64 = 0.9;

/// Closest-hit distances for tentative rays: the scene in rendering, analytic geometry in tests.
pub trait TentativeTracer {
    /// Distance `t` (in units of `ray.dir`) of the closest hit in `[ray.tmin, ray.tmax]`.
    fn closest(&self, ray: &Ray) -> Option<f32>;

    /// [`TentativeTracer::closest`] of up to 8 rays; bit `i` of `active` selects `rays[i]`,
    /// inactive lanes answer `None`.
    fn closest8(&self, rays: &[Ray; PACKET], active: u8) -> [Option<f32>; PACKET];
}

impl TentativeTracer for Scene {
    fn closest(&self, ray: &Ray) -> Option<f32> {
        self.accel.intersect(ray).map(|hit| hit.t)
    }

    fn closest8(&self, rays: &[Ray; PACKET], active: u8) -> [Option<f32>; PACKET] {
        let mut hits = [None; PACKET];
        self.intersect8(rays, active, &mut hits);
        hits.map(|hit| hit.map(|hit| hit.t))
    }
}

/// The scene as `upg`'s tentative rays see it. A tentative ray stands for the light sub-path's
/// next vertex, which is stored, and so can be gathered, only on a non-delta surface: a first
/// hit on a mirror or glass is a failure.
pub struct StoredVerticesOnly<'a>(pub &'a Scene);

impl TentativeTracer for StoredVerticesOnly<'_> {
    fn closest(&self, ray: &Ray) -> Option<f32> {
        let hit = self.0.accel.intersect(ray)?;
        (!self.0.hits_delta_surface(&hit)).then_some(hit.t)
    }

    fn closest8(&self, rays: &[Ray; PACKET], active: u8) -> [Option<f32>; PACKET] {
        let mut hits = [None; PACKET];
        self.0.intersect8(rays, active, &mut hits);
        hits.map(|hit| {
            hit.filter(|hit| !self.0.hits_delta_surface(hit))
                .map(|hit| hit.t)
        })
    }
}

#[derive(Debug, Error, Clone, PartialEq)]
pub enum AcceptanceError {
    #[error("a delta BSDF (mirror, glass) cannot be merged through")]
    DeltaBsdf,
    #[error("the merge radius must be positive and finite, got {0}")]
    InvalidRadius(f32),
    #[error("tentative rays are traced 1 or 8 at a time, not {0}")]
    PacketWidth(u32),
}

/// How many tentative rays are traced together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PacketWidth {
    One,
    Eight,
}

impl TryFrom<u32> for PacketWidth {
    type Error = AcceptanceError;

    fn try_from(width: u32) -> Result<Self, Self::Error> {
        match width {
            1 => Ok(PacketWidth::One),
            8 => Ok(PacketWidth::Eight),
            _ => Err(AcceptanceError::PacketWidth(width)),
        }
    }
}

/// The polar part of a component's bound.
#[derive(Clone, Copy, Debug)]
enum Polar {
    /// The whole lobe, drawn with the warp the BSDF itself uses.
    Whole,
    /// An interval, with the lobe's closed-form mass and sampler there.
    Bounded(PolarBound),
}

/// One mixture component with its bound, in a frame around its axis.
#[derive(Clone, Copy, Debug)]
struct Component {
    x: DVec3,
    y: DVec3,
    z: DVec3,
    shape: LobeShape,
    polar: Polar,
    /// Azimuths `[phi0, phi0 + phi_span]`.
    phi0: f64,
    phi_span: f64,
}

/// An orthonormal basis around the unit `z` in f64 (the construction of `Frame::from_z`).
fn basis(z: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(z.z);
    let a = -1.0 / (sign + z.z);
    let b = z.x * z.y * a;
    (
        DVec3::new(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x),
        DVec3::new(b, sign + z.y * z.y * a, -z.y),
    )
}

impl Component {
    /// The bound of `lobe` around the cone from `origin` to the r-sphere around `target`, and
    /// its probability p_b (000 eq. 2.64).
    fn new(lobe: &Lobe, origin: DVec3, target: DVec3, radius: f64) -> (Component, f64) {
        let z = lobe.axis.as_dvec3().normalize();
        let (x, y) = basis(z);
        let whole = Component {
            x,
            y,
            z,
            shape: lobe.shape,
            polar: Polar::Whole,
            phi0: 0.0,
            phi_span: 2.0 * PI,
        };
        let to_target = target - origin;
        let d = to_target.length();
        if d <= radius {
            return (whole, 1.0);
        }
        let t = to_target / d;
        let (tx, ty, tz) = (t.dot(x), t.dot(y), t.dot(z));
        // The cone's axis is at polar angle theta_d, its half-angle is gamma; the bound spans
        // polar angles [theta_d - gamma, theta_d + gamma], clamped to the lobe's hemisphere.
        // Their sines and cosines follow from the angle sums, with no inverse trigonometry.
        let (cos_d, sin_d) = (tz, (tx * tx + ty * ty).sqrt());
        let sin_gamma = radius / d;
        let cos_gamma = (1.0 - sin_gamma * sin_gamma).sqrt();
        let cos_lo = cos_d * cos_gamma + sin_d * sin_gamma;
        if cos_lo <= 0.0 {
            // theta_d - gamma >= 90 degrees: the cone lies below the lobe's hemisphere.
            return (whole, 0.0);
        }
        let sin_lo = sin_d * cos_gamma - cos_d * sin_gamma;
        let cos_hi = cos_d * cos_gamma - sin_d * sin_gamma;
        let (cos1, sin1) = if cos_hi <= 0.0 {
            (0.0, 1.0)
        } else {
            (cos_hi, sin_d * cos_gamma + cos_d * sin_gamma)
        };
        let (cos0, sin0, x, y, phi0, phi_span) = if sin_lo <= 0.0 {
            // The cone holds the axis: every azimuth.
            (1.0, 0.0, x, y, 0.0, 2.0 * PI)
        } else {
            // Half-width of the azimuths of a cone of half-angle gamma whose axis is at polar
            // angle theta_d > gamma, seen from the lobe's axis. When the cone holds the
            // antipode too (sin(gamma) >= sin(theta_d)), its part in the lobe's hemisphere
            // still lies within 90 degrees of phi_d, where the ratio is clamped. The frame is
            // turned so that phi_d is azimuth zero.
            let dphi = (sin_gamma / sin_d).min(1.0).asin();
            let x_d = (x * tx + y * ty) / sin_d;
            (cos_lo, sin_lo, x_d, z.cross(x_d), -dphi, 2.0 * dphi)
        };
        let bound = lobe.shape.polar_bound(&PolarInterval {
            cos0,
            sin0,
            cos1,
            sin1,
            // With neither end clamped the interval is 2 gamma wide: sin(2 gamma) keeps its
            // digits however narrow the cone.
            sin_width: (cos_hi > 0.0 && sin_lo > 0.0).then_some(2.0 * sin_gamma * cos_gamma),
        });
        let p_b = bound.mass() * phi_span / (2.0 * PI);
        if p_b >= WHOLE_LOBE_SHARE {
            return (whole, 1.0);
        }
        let bounded = Component {
            x,
            y,
            polar: Polar::Bounded(bound),
            phi0,
            phi_span,
            ..whole
        };
        (bounded, p_b.max(0.0))
    }

    /// A direction from the component's density restricted to its bound, with `u` uniform.
    fn sample(&self, u: [f32; 2]) -> Vec3 {
        let (cos_theta, sin_theta) = match self.polar {
            Polar::Whole => {
                let local = self.shape.sample(u);
                let w = self.x * local.x as f64 + self.y * local.y as f64 + self.z * local.z as f64;
                return w.as_vec3();
            }
            Polar::Bounded(bound) => bound.sample(u[0]),
        };
        // The azimuth in f32: its rounding moves the direction by less than f32 can resolve.
        let phi = (self.phi0 + u[1] as f64 * self.phi_span) as f32;
        let (sin_phi, cos_phi) = phi.sin_cos();
        let w = self.x * (sin_theta * cos_phi as f64)
            + self.y * (sin_theta * sin_phi as f64)
            + self.z * cos_theta;
        w.as_vec3()
    }
}

/// A microfacet lobe's bound: its sampling points drawn uniformly from `rect`, or as the BSDF
/// draws them (`None`: the whole lobe).
#[derive(Clone, Copy, Debug)]
struct NormalsBound {
    normals: VisibleNormals,
    scatter: Scatter,
    rect: Option<PointRect>,
}

impl NormalsBound {
    /// The bound of `lobe` for `wo` (local) around the cone of half-angle `gamma` about
    /// `axis` (local), and its probability p_b.
    fn new(lobe: &MicrofacetLobe, wo: Vec3, axis: DVec3, gamma: f64) -> (NormalsBound, f64) {
        let normals = lobe.normals(wo);
        let rect = lobe
            .bound(wo, axis, gamma)
            .map(|rect| (rect, rect.area() / normals.area()))
            .filter(|&(_, p_b)| p_b < WHOLE_LOBE_SHARE);
        let bound = NormalsBound {
            normals,
            scatter: lobe.scatter,
            rect: rect.map(|(rect, _)| rect),
        };
        (bound, rect.map_or(1.0, |(_, p_b)| p_b))
    }

    /// A local direction from the lobe restricted to the bound; `None` for a point outside
    /// the sampler's region or a direction the BSDF would reject.
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<Vec3> {
        let p = match self.rect {
            Some(rect) => {
                let p = rect.sample([u[1], u[2]]);
                if !self.normals.contains(p) {
                    return None;
                }
                p
            }
            None => self.normals.point([u[1], u[2]]),
        };
        self.scatter.apply(wo, self.normals.lift(p), u[0])
    }
}

/// How a trial draws inside one component's bound.
#[derive(Clone, Copy, Debug)]
enum Draw {
    Polar(Component),
    Normals(NormalsBound),
    /// A delta component's direction, inside the cone.
    Delta(Vec3),
}

/// One mixture component's bound, with w_c p_b,c and the running sum of it up to and
/// including this component.
#[derive(Clone, Copy, Debug)]
struct Part {
    draw: Draw,
    mass: f64,
    cdf: f64,
}

/// Where tentative rays from one origin vertex towards one target may go: the angular bound
/// (000 eqs. 2.63-2.64) of each lobe of the origin's BSDF, and the sampler inside it.
#[derive(Clone, Debug)]
pub struct AngularBound<'a> {
    bsdf: Bsdf<'a>,
    /// The ray origin, offset off the surface to the side the BSDF samples; on a surface with
    /// a shading normal the vertex itself, each trial offsetting it to its own side.
    origin: Vec3,
    /// The geometric normal where each trial offsets its own origin (shading normals), `None`
    /// where one origin serves all.
    per_trial_offset: Option<Vec3>,
    target: Vec3,
    radius: f32,
    parts: [Option<Part>; 3],
    /// P = sum_c w_c p_b,c.
    p_bound: f64,
    /// Every component is whole: trials are exactly [`Bsdf::sample`].
    whole: bool,
}

impl<'a> AngularBound<'a> {
    /// The bound for merges at `target` with radius `radius` through the vertex at `position`
    /// (geometric normal `ng`) whose BSDF, built for its fixed `wo`, is `bsdf`.
    pub fn new(
        position: Vec3,
        ng: Vec3,
        bsdf: &Bsdf<'a>,
        target: Vec3,
        radius: f32,
    ) -> Result<Self, AcceptanceError> {
        if !(radius > 0.0 && radius.is_finite()) {
            return Err(AcceptanceError::InvalidRadius(radius));
        }
        if bsdf.is_delta() {
            return Err(AcceptanceError::DeltaBsdf);
        }
        // Lobes with no closed-form bound leave no component: the bound is the whole BSDF.
        let lobes = bsdf.lobes();
        // Where every lobe lies around an axis on the side of the frame's z, every direction the
        // BSDF keeps lies on that side. On a flat surface that is one side of the geometric
        // plane, so this is the origin `Ray::spawn` gives each of them, and the cone is taken
        // from it. With a shading normal the kept hemisphere crosses the geometric plane: each
        // trial offsets the vertex to the side of its own direction, as `Ray::spawn` would, and
        // the cone is taken from the vertex itself with the radius grown by twice the offset
        // (once suffices, the rest covers rounding), so it holds every direction that can
        // succeed from either origin. A BSDF that may transmit (rough dielectrics, diffuse
        // transmission), one without bounded lobes, and one with microfacet or delta lobes
        // offset each trial's origin likewise.
        let one_side = lobes.as_slice().iter().all(|kind| match kind {
            LobeKind::Polar(lobe) => lobe.axis.dot(bsdf.frame().z) > 0.0,
            LobeKind::Microfacet { .. } | LobeKind::Delta { .. } => false,
        });
        let (origin, per_trial_offset, cone_radius) =
            if bsdf.is_smooth() || !lobes.is_bounded() || !one_side {
                let offset = (offset_ray_origin(position, ng, ng) - position).length();
                (position, Some(ng), radius as f64 + 2.0 * offset as f64)
            } else {
                (
                    offset_ray_origin(position, ng, bsdf.frame().z),
                    None,
                    radius as f64,
                )
            };
        let to_target = (target - origin).as_dvec3();
        let distance = to_target.length();
        let frame = bsdf.frame();
        let t = to_target / distance;
        let axis = DVec3::new(
            t.dot(frame.x.as_dvec3()),
            t.dot(frame.y.as_dvec3()),
            t.dot(frame.z.as_dvec3()),
        )
        .normalize();
        let inside = distance <= cone_radius;
        // The cone's half-angle, which only microfacet and delta lobes take (an asin per merge
        // that lambert and Phong do not pay).
        let gamma = || {
            if inside {
                0.0
            } else {
                (cone_radius / distance).asin()
            }
        };
        let mut parts = [None; 3];
        let (mut p_bound, mut whole) = (0.0, true);
        for (kind, slot) in lobes.as_slice().iter().zip(parts.iter_mut()) {
            let (weight, draw, p_b) = match kind {
                LobeKind::Polar(lobe) => {
                    let (component, p_b) =
                        Component::new(lobe, origin.as_dvec3(), target.as_dvec3(), cone_radius);
                    whole &= matches!(component.polar, Polar::Whole) && p_b == 1.0;
                    (lobe.weight, Draw::Polar(component), p_b)
                }
                LobeKind::Microfacet { weight, lobe } => {
                    let (bound, p_b) = if inside {
                        let normals = lobe.normals(bsdf.wo_local());
                        let whole_lobe = NormalsBound {
                            normals,
                            scatter: lobe.scatter,
                            rect: None,
                        };
                        (whole_lobe, 1.0)
                    } else {
                        NormalsBound::new(lobe, bsdf.wo_local(), axis, gamma())
                    };
                    whole &= bound.rect.is_none();
                    (*weight, Draw::Normals(bound), p_b)
                }
                LobeKind::Delta { weight, direction } => {
                    // All of it or nothing lies in the cone; drawn alone it is not the whole
                    // BSDF.
                    whole = false;
                    let held = inside || direction.as_dvec3().dot(t) >= gamma().cos();
                    (
                        *weight,
                        Draw::Delta(*direction),
                        if held { 1.0 } else { 0.0 },
                    )
                }
            };
            let mass = weight as f64 * p_b;
            p_bound += mass;
            *slot = Some(Part {
                draw,
                mass,
                cdf: p_bound,
            });
        }
        Ok(AngularBound {
            bsdf: bsdf.clone(),
            origin,
            per_trial_offset,
            target,
            radius,
            parts,
            p_bound: if whole { 1.0 } else { p_bound },
            whole,
        })
    }

    /// The bound of the BSDF's non-delta lobes alone: trials stand for the directions these
    /// sample, and 1/p_acc is that of a sample from them landing within r. Where only vertices
    /// reached through a non-delta lobe are gathered (`upg`: a light vertex reached by a
    /// coating's mirror is not merged), counting the mirror's successes too would make p_acc
    /// larger than the chance of a merge, and the image dark by their share.
    pub fn without_delta(mut self) -> Self {
        let delta = |part: &Part| matches!(part.draw, Draw::Delta(_));
        if !self.parts.iter().flatten().any(delta) {
            return self;
        }
        let mut cdf = 0.0;
        for part in self.parts.iter_mut().flatten() {
            if delta(part) {
                part.mass = 0.0;
            }
            cdf += part.mass;
            part.cdf = cdf;
        }
        self.p_bound = cdf;
        self
    }

    /// P: the probability that the BSDF samples a direction inside the bound. Zero when no
    /// direction it samples can reach the r-sphere.
    pub fn p_bound(&self) -> f64 {
        self.p_bound
    }

    /// True when the bound is the whole BSDF (P = 1) and trials are drawn by [`Bsdf::sample`].
    pub fn is_whole(&self) -> bool {
        self.whole
    }

    /// The ray origin: the vertex offset off its surface on the side the BSDF samples (with a
    /// shading normal, the vertex itself; each trial offsets it to the side it goes).
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// A trial direction from the BSDF's density restricted to the bound and divided by P,
    /// `u[0]` choosing the component; `None` where the BSDF would reject it (below the surface).
    pub fn sample_direction(&self, u: [f32; 3]) -> Option<Vec3> {
        if self.whole {
            return self.bsdf.sample(u).map(|s| s.wi);
        }
        let pick = u[0] as f64 * self.p_bound;
        let mut parts = self.parts.iter().flatten().filter(|p| p.mass > 0.0);
        let first = parts.next()?;
        let part = parts.fold(
            first,
            |chosen, p| if pick < chosen.cdf { chosen } else { p },
        );
        match &part.draw {
            Draw::Polar(component) => {
                let w = component.sample([u[1], u[2]]);
                // A lobe's density lies on its axis's side; Phong's glossy part reaches below
                // the surface, where the BSDF rejects it.
                let axis_up = component.z.dot(self.bsdf.frame().z.as_dvec3()) > 0.0;
                ((w.dot(self.bsdf.frame().z) > 0.0) == axis_up).then_some(w)
            }
            Draw::Normals(bound) => {
                // The pick's place within this part is a fresh uniform number for the scatter.
                let v = ((pick - (part.cdf - part.mass)) / part.mass).clamp(0.0, 1.0) as f32;
                let wi = bound.sample(self.bsdf.wo_local(), [v, u[1], u[2]])?;
                Some(self.bsdf.frame().to_world(wi))
            }
            Draw::Delta(direction) => Some(*direction),
        }
    }

    /// The tentative ray of a trial, its `tmax` where it leaves the r-sphere; `None` for a
    /// failure known without tracing (rejected by the BSDF, or missing the sphere).
    fn trial(&self, rng: &mut Rng) -> Option<Ray> {
        // Three numbers per trial whatever happens, so packets and single rays see the same
        // trial sequence.
        let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let dir = self.sample_direction(u)?;
        let origin = match self.per_trial_offset {
            Some(ng) => offset_ray_origin(self.origin, ng, dir),
            None => self.origin,
        };
        let o = (origin - self.target).as_dvec3();
        let w = dir.as_dvec3();
        let a = w.length_squared();
        let half_b = o.dot(w);
        let c = o.length_squared() - (self.radius as f64).powi(2);
        let disc = half_b * half_b - a * c;
        if disc < 0.0 {
            return None;
        }
        let t_exit = (-half_b + disc.sqrt()) / a;
        (t_exit > 0.0).then_some(Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: t_exit as f32,
        })
    }

    fn accepts(&self, ray: &Ray, t: Option<f32>) -> bool {
        t.is_some_and(|t| (ray.at(t) - self.target).length_squared() <= self.radius * self.radius)
    }
}

/// How an estimate ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outcome {
    /// N / P, an unbiased estimate of 1/p_acc (000 eq. 2.65).
    Estimate(f32),
    /// No success within the cap: the merge is dropped.
    Capped,
    /// P = 0: no direction the BSDF samples reaches the r-sphere.
    Unreachable,
}

/// One estimate of 1/p_acc, with what it cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub outcome: Outcome,
    /// Trials counted: the index of the first success, or the cap.
    pub trials: u32,
    /// Rays traced; with packets this includes the lanes after the first success.
    pub rays: u32,
    /// Of those, the rays traced in packets.
    pub packed: u32,
}

impl Estimate {
    pub fn inv_p_acc(&self) -> Option<f32> {
        match self.outcome {
            Outcome::Estimate(value) => Some(value),
            Outcome::Capped | Outcome::Unreachable => None,
        }
    }

    pub fn capped(&self) -> bool {
        self.outcome == Outcome::Capped
    }
}

/// The Bernoulli-trial estimator of 1/p_acc (000 eqs. 2.61-2.65).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Estimator {
    pub packet: PacketWidth,
    /// Trials after which the estimate gives up ([`Outcome::Capped`]).
    pub max_trials: u32,
}

impl Default for Estimator {
    /// Single rays: Embree traces a packet's rays 1.1 to 1.4 times faster than single ones,
    /// but tracing is under 40% of the stage, a render's gathers hold too few merges to fill
    /// packets, and the stage is under a fifth of a render: packets gain nothing measurable
    /// (docs/performance.md, "UPG tentative rays").
    fn default() -> Self {
        Estimator {
            packet: PacketWidth::One,
            max_trials: crate::options::RenderOptions::DEFAULT.upg_max_trials,
        }
    }
}

impl Estimator {
    /// Counts trials in `bound` up to the first success. Packets and single rays return the same
    /// estimate for the same `rng` (a merge alone is traced with single rays at either width).
    pub fn estimate<T: TentativeTracer + ?Sized>(
        &self,
        tracer: &T,
        bound: &AngularBound,
        rng: &mut Rng,
    ) -> Estimate {
        let mut estimate = None;
        self.estimate_all(
            tracer,
            std::slice::from_ref(bound),
            std::slice::from_mut(rng),
            |_, e| estimate = Some(e),
        );
        estimate.expect("one estimate per bound")
    }

    /// Estimates of several merges, merge `i` drawing its trials in `bounds[i]` from `rngs[i]`;
    /// `done(i, estimate)` receives each. Single rays finish one merge after another. Packets
    /// fill their 8 lanes with the next trial of each of 8 merges still open, in turn, while 8
    /// are open; the trials of one merge keep their order, so every estimate is the one single
    /// rays give.
    pub fn estimate_all<T: TentativeTracer + ?Sized>(
        &self,
        tracer: &T,
        bounds: &[AngularBound],
        rngs: &mut [Rng],
        mut done: impl FnMut(usize, Estimate),
    ) {
        assert_eq!(bounds.len(), rngs.len(), "one random stream per bound");
        let unreachable = Estimate {
            outcome: Outcome::Unreachable,
            trials: 0,
            rays: 0,
            packed: 0,
        };
        for (i, _) in bounds.iter().enumerate().filter(|(_, b)| b.p_bound <= 0.0) {
            done(i, unreachable);
        }
        let reachable = (0..bounds.len()).filter(|&i| bounds[i].p_bound > 0.0);
        let finish =
            |bound: &AngularBound, first: Option<u32>, (rays, packed): (u32, u32)| Estimate {
                outcome: match first {
                    Some(n) => Outcome::Estimate((n as f64 / bound.p_bound) as f32),
                    None => Outcome::Capped,
                },
                trials: first.unwrap_or(self.max_trials),
                rays,
                packed,
            };
        // Too few merges to fill a packet: single rays, without the packets' bookkeeping.
        let few = reachable.clone().nth(PACKET - 1).is_none();
        if self.packet == PacketWidth::One || few {
            for i in reachable {
                let (first, rays) = self.single(tracer, &bounds[i], &mut rngs[i], (0, 0));
                done(i, finish(&bounds[i], first, (rays, 0)));
            }
        } else {
            self.packets(
                tracer,
                bounds,
                rngs,
                reachable.collect(),
                |i, first, rays| done(i, finish(&bounds[i], first, rays)),
            );
        }
    }

    /// The index of the first success (or `None` when capped), and the rays traced, going on
    /// after `drawn` trials that traced `rays` rays and did not succeed.
    fn single<T: TentativeTracer + ?Sized>(
        &self,
        tracer: &T,
        bound: &AngularBound,
        rng: &mut Rng,
        (drawn, mut rays): (u32, u32),
    ) -> (Option<u32>, u32) {
        for n in drawn + 1..=self.max_trials {
            if let Some(ray) = bound.trial(rng) {
                rays += 1;
                if bound.accepts(&ray, tracer.closest(&ray)) {
                    return (Some(n), rays);
                }
            }
        }
        (None, rays)
    }

    /// Packets of 8 lanes over the merges `open`; `done(i, first success, (rays, of them
    /// packed))` as each ends. A packet takes the next trial of each of 8 open merges, in turn.
    /// With fewer than 8 open it would have to leave lanes empty or fill them with further
    /// trials of the same merges, mostly ones after a merge's first success, which single rays
    /// never trace; a packet costs several single rays, so the merges left go on with single
    /// rays.
    fn packets<T: TentativeTracer + ?Sized>(
        &self,
        tracer: &T,
        bounds: &[AngularBound],
        rngs: &mut [Rng],
        mut open: Vec<usize>,
        mut done: impl FnMut(usize, Option<u32>, (u32, u32)),
    ) {
        /// Trials drawn and rays traced (all in packets) so far, and the first success found.
        #[derive(Clone, Copy, Default)]
        struct Progress {
            drawn: u32,
            rays: u32,
            first: Option<u32>,
        }
        let mut progress = vec![Progress::default(); bounds.len()];
        let mut packet = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET];
        // Which merge and which of its trials each lane holds.
        let mut lanes = [(0usize, 0u32); PACKET];
        let mut turn = 0;
        while open.len() >= PACKET {
            let mut active = 0u8;
            let mut filled = 0;
            // One traced trial from each open merge in turn, until the lanes are full or every
            // open merge has been asked (those reaching their cap place none).
            for k in 0..open.len() {
                if filled == PACKET {
                    break;
                }
                let i = open[(turn + k) % open.len()];
                let p = &mut progress[i];
                while p.drawn < self.max_trials {
                    p.drawn += 1;
                    if let Some(ray) = bounds[i].trial(&mut rngs[i]) {
                        packet[filled] = ray;
                        lanes[filled] = (i, p.drawn);
                        active |= 1 << filled;
                        p.rays += 1;
                        filled += 1;
                        break;
                    }
                }
            }
            turn += PACKET;
            if active != 0 {
                let hits = tracer.closest8(&packet, active);
                for (lane, &(i, n)) in lanes.iter().enumerate().take(filled) {
                    // One lane per merge: its trial is the merge's next.
                    if bounds[i].accepts(&packet[lane], hits[lane]) {
                        progress[i].first = Some(n);
                    }
                }
            }
            open.retain(|&i| {
                let p = progress[i];
                let ended = p.first.is_some() || p.drawn >= self.max_trials;
                if ended {
                    done(i, p.first, (p.rays, p.rays));
                }
                !ended
            });
        }
        for i in open {
            let p = progress[i];
            let (first, rays) = self.single(tracer, &bounds[i], &mut rngs[i], (p.drawn, p.rays));
            done(i, first, (rays, p.rays));
        }
    }
}
