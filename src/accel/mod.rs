//! Ray queries. One interface ([`Accel`]), two backends: the system Embree (`embree.rs`, the only
//! file that calls it) and a pure-Rust SAH BVH (`bvh.rs`).
//!
//! Geometry is one flat triangle soup plus a list of analytic spheres; a [`Hit`] names its
//! [`Primitive`] by index into those lists, and a triangle's group (a run of triangles the
//! scene tells apart, its material), so the scene maps a hit to its material in O(1) without
//! a per-triangle read.
//! Triangles may be cut out by an alpha (`alpha.rs`): both backends skip the hits it removes.

use crate::options::OptionName;
pub use alpha::{Alpha, Cutouts, TriangleAlpha};
use glam::Vec3;
use thiserror::Error;

pub mod alpha;
pub mod bvh;
#[cfg(feature = "embree")]
pub mod embree;

/// A ray segment `origin + t * dir` for `t` in `[tmin, tmax]`. `dir` need not be normalised,
/// `t` is measured in units of `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
}

/// Fraction of a shadow segment left out at its far end so the target surface does not occlude
/// itself (pbrt's ShadowEpsilon).
const SHADOW_EPSILON: f32 = 1e-4;

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }

    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// A ray leaving the surface point `p` (geometric normal `ng`) in direction `dir`, its origin
    /// offset off the surface so it cannot hit the surface it starts on.
    pub fn spawn(p: Vec3, ng: Vec3, dir: Vec3) -> Self {
        Ray::new(offset_ray_origin(p, ng, dir), dir)
    }

    /// A shadow segment from surface point `p` (normal `ng`) to the point `target`, which need
    /// not be on a surface. `dir` is `target - origin` and `tmax` stops just short of 1.
    pub fn spawn_to(p: Vec3, ng: Vec3, target: Vec3) -> Self {
        let origin = offset_ray_origin(p, ng, target - p);
        Ray {
            origin,
            dir: target - origin,
            tmin: 0.0,
            tmax: 1.0 - SHADOW_EPSILON,
        }
    }

    /// A shadow segment between two surface points, both ends offset off their surfaces.
    pub fn spawn_between(p: Vec3, ng: Vec3, q: Vec3, ng_q: Vec3) -> Self {
        let origin = offset_ray_origin(p, ng, q - p);
        let target = offset_ray_origin(q, ng_q, p - q);
        Ray {
            origin,
            dir: target - origin,
            tmin: 0.0,
            tmax: 1.0 - SHADOW_EPSILON,
        }
    }
}

/// Offset of a ray origin along the geometric normal, scaled to the magnitude of the
/// coordinates: f32 positions carry a relative error of about 2^-24 of their largest
/// component, so a fixed epsilon is either too small far from the origin or too large near it.
pub fn offset_ray_origin(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    const RELATIVE: f32 = 1.0 / 16384.0 / 32.0; // ~1.9e-6: a few dozen ulps of the magnitude
    const ABSOLUTE: f32 = 1e-6;
    let magnitude = p.abs().max_element();
    let offset = ng * (magnitude * RELATIVE + ABSOLUTE);
    if dir.dot(ng) < 0.0 {
        p - offset
    } else {
        p + offset
    }
}

/// Which primitive a ray hit: the index of a triangle or of a sphere in the [`Geometry`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Primitive {
    Triangle(u32),
    Sphere(u32),
}

/// The closest (or any) intersection of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit, in units of the ray's `dir`.
    pub t: f32,
    pub primitive: Primitive,
    /// The triangle's group ([`Geometry::group_starts`]); zero for spheres.
    pub group: u32,
    /// Barycentrics of a triangle hit: `p = (1 - u - v) p0 + u p1 + v p2`; zero for spheres.
    pub u: f32,
    pub v: f32,
    /// Geometric normal: for a triangle a positive multiple of `(p1 - p0) x (p2 - p0)` (the side
    /// from which its vertices are counter-clockwise), not of unit length; for a sphere the unit
    /// outward normal. Triangle normals are left as Embree returns them because many queries
    /// (tentative rays, for one) never read them, and normalising costs a tenth of a query on
    /// small scenes; the scene normalises them where it makes a surface point.
    pub ng: Vec3,
}

/// The group of `triangle` among groups that start at `group_starts` ([`Geometry::group_starts`]).
pub(crate) fn group_of(group_starts: &[u32], triangle: u32) -> u32 {
    group_starts.partition_point(|&start| start <= triangle) as u32
}

/// An analytic sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

/// Everything the backends intersect: a triangle soup over shared vertices, and spheres.
#[derive(Clone, Debug, Default)]
pub struct Geometry {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub spheres: Vec<Sphere>,
    /// The triangles an alpha cuts out (none by default).
    pub cutouts: Cutouts,
    /// Where each group of triangles but the first (which starts at triangle 0) starts,
    /// ascending: consecutive runs that every hit names by number ([`Hit::group`]). Empty: all
    /// triangles are one group.
    pub group_starts: Vec<u32>,
}

impl Geometry {
    pub fn triangle_vertices(&self, index: u32) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[index as usize];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Each group must hold a triangle: starts ascending, within `(0, triangles)`.
    pub(crate) fn check_groups(&self) -> Result<(), AccelError> {
        let count = self.triangles.len() as u32;
        let mut previous = 0;
        for (i, &start) in self.group_starts.iter().enumerate() {
            if start <= previous || start >= count {
                return Err(AccelError::InvalidGeometry(format!(
                    "group {} starts at triangle {start}, not after {previous} and before {count}",
                    i + 1
                )));
            }
            previous = start;
        }
        Ok(())
    }

    /// The triangles of each group, in order (none without triangles).
    pub fn groups(&self) -> impl Iterator<Item = std::ops::Range<u32>> + '_ {
        let count = self.triangles.len() as u32;
        let starts = std::iter::once(0).chain(self.group_starts.iter().copied());
        let ends = self
            .group_starts
            .iter()
            .copied()
            .chain(std::iter::once(count));
        starts
            .zip(ends)
            .map(|(start, end)| start..end)
            .filter(|group| !group.is_empty())
    }

    /// Axis-aligned bounds `(min, max)` of all primitives; `None` when there are none.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut min = Vec3::splat(f32::INFINITY);
        let mut max = Vec3::splat(f32::NEG_INFINITY);
        for tri in &self.triangles {
            for &i in tri {
                let p = self.positions[i as usize];
                min = min.min(p);
                max = max.max(p);
            }
        }
        for s in &self.spheres {
            min = min.min(s.center - Vec3::splat(s.radius));
            max = max.max(s.center + Vec3::splat(s.radius));
        }
        (min.x <= max.x).then_some((min, max))
    }
}

/// Both ray parameters where `ray` meets the sphere, nearest first. Solved in f64 relative
/// to the centre: in f32 the discriminant cancels badly for distant or grazing rays. Both
/// backends report sphere hits through this one function, so they agree to the bit.
pub(crate) fn sphere_roots(s: &Sphere, ray: &Ray) -> Option<[f32; 2]> {
    let o = (ray.origin - s.center).as_dvec3();
    let d = ray.dir.as_dvec3();
    let a = d.length_squared();
    let half_b = o.dot(d);
    let c = o.length_squared() - (s.radius as f64) * (s.radius as f64);
    let disc = half_b * half_b - a * c;
    if disc < 0.0 || a == 0.0 {
        return None;
    }
    // The numerically stable pair of roots (Numerical Recipes 5.6).
    let q = -(half_b + half_b.signum() * disc.sqrt());
    let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, c / q) };
    let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    Some([t0 as f32, t1 as f32])
}

impl Sphere {
    /// The nearest `t` in `[ray.tmin, tmax]` where `ray` meets the sphere. Every sphere test
    /// (the BVH's leaves, the spheres Embree leaves to vmerge) decides through this one function.
    #[inline]
    pub(crate) fn first_hit(&self, ray: &Ray, tmax: f32) -> Option<f32> {
        sphere_roots(self, ray).and_then(|r| r.into_iter().find(|&t| t >= ray.tmin && t <= tmax))
    }

    /// The [`Hit`] of `ray` on this sphere, number `index` of the geometry, at `t`.
    #[inline]
    pub(crate) fn hit(&self, index: u32, ray: &Ray, t: f32) -> Hit {
        Hit {
            t,
            primitive: Primitive::Sphere(index),
            group: 0,
            u: 0.0,
            v: 0.0,
            ng: (ray.at(t) - self.center).normalize(),
        }
    }
}

/// Packet width of the 8-ray queries.
pub const PACKET: usize = 8;

/// Ray queries against a committed scene. Implementations are immutable after building and
/// shared by all render threads.
pub trait Accel: Send + Sync {
    /// Closest hit with `t` in `[ray.tmin, ray.tmax]`; hits the geometry's cut-outs remove
    /// do not count, here and in every query below.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// Whether anything is hit with `t` in `[ray.tmin, ray.tmax]`.
    fn occluded(&self, ray: &Ray) -> bool;

    /// Closest hits of up to 8 rays; bit `i` of `active` selects `rays[i]`. Inactive lanes of
    /// `hits` are set to `None`. Returns exactly what 8 calls of [`Accel::intersect`] return.
    fn intersect8(&self, rays: &[Ray; PACKET], active: u8, hits: &mut [Option<Hit>; PACKET]);

    /// Occlusion of up to 8 rays; returns a mask with bit `i` set where active ray `i` is occluded.
    fn occluded8(&self, rays: &[Ray; PACKET], active: u8) -> u8;

    /// The backend's name, for metadata and benchmarks.
    fn name(&self) -> &'static str;
}

/// The backends, chosen at run time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelKind {
    Embree,
    Bvh,
}

impl AccelKind {
    /// Embree when it was built in, the Rust BVH otherwise.
    pub fn default_kind() -> Self {
        if cfg!(feature = "embree") {
            AccelKind::Embree
        } else {
            AccelKind::Bvh
        }
    }

    pub const ALL: [AccelKind; 2] = [AccelKind::Embree, AccelKind::Bvh];

    pub fn name(self) -> &'static str {
        match self {
            AccelKind::Embree => "embree",
            AccelKind::Bvh => "bvh",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            AccelKind::Embree => "the system Embree",
            AccelKind::Bvh => "vmerge's own SAH BVH (pure Rust)",
        }
    }
}

#[derive(Debug, Error)]
pub enum AccelError {
    #[error("Embree error {code}: {message}")]
    Embree { code: u32, message: String },
    #[error(
        "this build has no Embree backend (built without the `embree` feature); use {} bvh",
        OptionName("accel")
    )]
    EmbreeNotBuilt,
    #[error("invalid geometry: {0}")]
    InvalidGeometry(String),
}

/// Builds the chosen backend over `geometry`.
pub fn build(kind: AccelKind, geometry: &Geometry) -> Result<Box<dyn Accel>, AccelError> {
    match kind {
        AccelKind::Bvh => Ok(Box::new(bvh::Bvh::build(geometry)?)),
        #[cfg(feature = "embree")]
        AccelKind::Embree => Ok(Box::new(embree::EmbreeScene::build(geometry)?)),
        #[cfg(not(feature = "embree"))]
        AccelKind::Embree => Err(AccelError::EmbreeNotBuilt),
    }
}
