//! Where the infinite lights (directional, sky, environment) start their light sub-paths.
//!
//! A light sub-path of an infinite light picks a direction, then a point on a plane
//! perpendicular to it (001 sec. 5.1), in a region every ray that reaches the scene crosses:
//! - [`Aim::Disc`]: the disc of the bounding sphere (SmallVCM's and pbrt-v4's choice), of area
//!   pi r^2;
//! - [`Aim::Silhouette`]: the silhouette of the bounding box, the projection of the (up to
//!   three) faces that face the light, which do not overlap: a face chosen in proportion to
//!   its projected area, then a uniform point on it, is a uniform point on the silhouette, of
//!   density 1 / (projected area). A cube's is 0.42 to 0.74 of its sphere's disc (0.64 on
//!   average over directions), so that many more of the sub-paths reach geometry.
//!
//! The silhouette pays where every light vertex is worth its cost alone (light tracing and
//! photon mapping: each vertex is one camera connection or waits in the grid); where every eye
//! vertex connects to every vertex of a light sub-path (bpt, vcm), each further vertex costs
//! shadow rays, most of them on the box's outside, and the disc renders sooner (docs/performance.md,
//! "Light sub-paths of infinite lights").

use crate::frame::Frame;
use crate::sampling;
use glam::Vec3;
use std::f32::consts::PI;

/// The plane region an infinite light's sub-paths start from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aim {
    Disc,
    Silhouette,
}

/// The scene's bounding box, padded so no axis is flat, and its bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneBounds {
    min: Vec3,
    max: Vec3,
    /// Areas of the faces across x, y and z.
    face_areas: Vec3,
    center: Vec3,
    radius: f32,
}

impl SceneBounds {
    /// The box from `min` to `max`, each axis widened to at least a thousandth of the diagonal
    /// (a flat scene, lit edge-on, would otherwise have a silhouette of zero area).
    pub fn new(min: Vec3, max: Vec3) -> Self {
        let diagonal = (max - min).length().max(1e-6);
        let pad = ((Vec3::splat(1e-3 * diagonal) - (max - min)) * 0.5).max(Vec3::ZERO);
        let (min, max) = (min - pad, max + pad);
        let e = max - min;
        SceneBounds {
            min,
            max,
            face_areas: Vec3::new(e.y * e.z, e.x * e.z, e.x * e.y),
            center: 0.5 * (min + max),
            radius: 0.5 * e.length(),
        }
    }

    /// The radius of the bounding sphere: twice it from a point in the scene is outside.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Area of the silhouette seen along the unit `dir`: each face's area times |cos|.
    pub fn projected_area(&self, dir: Vec3) -> f32 {
        dir.abs().dot(self.face_areas)
    }

    /// Density of [`Self::origin`] per unit area of the plane perpendicular to `dir`.
    pub fn origin_pdf(&self, dir: Vec3, aim: Aim) -> f32 {
        match aim {
            Aim::Disc => 1.0 / (PI * self.radius * self.radius),
            Aim::Silhouette => 1.0 / self.projected_area(dir),
        }
    }

    /// Area of the silhouette averaged over all directions: a quarter of the box's surface
    /// (Cauchy's formula), the measure of an isotropic infinite light's power.
    pub fn mean_projected_area(&self) -> f32 {
        0.5 * (self.face_areas.x + self.face_areas.y + self.face_areas.z)
    }

    /// A uniform point of the region `aim` seen along the unit `dir`, on the plane one
    /// bounding-sphere radius behind the centre, so a ray from it along `dir` crosses the whole
    /// scene.
    pub fn origin(&self, dir: Vec3, u: [f32; 2], aim: Aim) -> Vec3 {
        match aim {
            Aim::Disc => {
                let frame = Frame::from_z(dir);
                let d = sampling::concentric_disk(u);
                self.center + self.radius * (frame.x * d.x + frame.y * d.y - dir)
            }
            Aim::Silhouette => self.silhouette_origin(dir, u),
        }
    }

    /// [`Self::origin`] on the silhouette: `u[0]` picks the face and, rescaled, the first
    /// coordinate on it; `u[1]` the second.
    fn silhouette_origin(&self, dir: Vec3, u: [f32; 2]) -> Vec3 {
        let weights = dir.abs() * self.face_areas;
        let pick = u[0] * (weights.x + weights.y + weights.z);
        let (axis, below) = if pick < weights.x || weights.y + weights.z <= 0.0 {
            (0, 0.0)
        } else if pick < weights.x + weights.y || weights.z <= 0.0 {
            (1, weights.x)
        } else {
            (2, weights.x + weights.y)
        };
        let s = ((pick - below) / weights[axis]).clamp(0.0, 1.0);
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut p = Vec3::ZERO;
        // Light travelling along +axis enters through the face at the minimum.
        p[axis] = if dir[axis] > 0.0 {
            self.min[axis]
        } else {
            self.max[axis]
        };
        p[a] = self.min[a] + s * (self.max[a] - self.min[a]);
        p[b] = self.min[b] + u[1] * (self.max[b] - self.min[b]);
        p - dir * ((p - self.center).dot(dir) + self.radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{uniform_sphere, Rng};

    /// The silhouette's area by Monte Carlo: the fraction of a square around the bounding
    /// sphere's disc whose rays along `dir` hit the box.
    fn hit_fraction_area(b: &SceneBounds, dir: Vec3, rng: &mut Rng, n: usize) -> f64 {
        let frame = Frame::from_z(dir);
        let side = 2.0 * b.radius;
        let mut hits = 0usize;
        for _ in 0..n {
            let (x, y) = (rng.next_f32() - 0.5, rng.next_f32() - 0.5);
            let o = b.center + side * (x * frame.x + y * frame.y) - dir * 2.0 * b.radius;
            hits += usize::from(hits_box(b, o, dir));
        }
        hits as f64 / n as f64 * f64::from(side * side)
    }

    #[test]
    fn projected_area_matches_monte_carlo() {
        let b = SceneBounds::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(3.0, 0.5, 3.5));
        let mut rng = Rng::from_seed(7, 1);
        for _ in 0..8 {
            let dir = uniform_sphere([rng.next_f32(), rng.next_f32()]);
            let n = 400_000;
            let area = hit_fraction_area(&b, dir, &mut rng, n);
            let p = area / f64::from(4.0 * b.radius * b.radius);
            // Binomial standard error of the estimate, 5 of them.
            let bound =
                5.0 * (p * (1.0 - p) / n as f64).sqrt() * f64::from(4.0 * b.radius * b.radius);
            let exact = f64::from(b.projected_area(dir));
            assert!(
                (area - exact).abs() < bound,
                "{dir}: {area} vs {exact} (+- {bound})"
            );
        }
    }

    /// Whether the ray along `dir` through plane point `o` (outside the box) hits the box.
    fn hits_box(b: &SceneBounds, o: Vec3, dir: Vec3) -> bool {
        let t0 = (b.min - o) / dir;
        let t1 = (b.max - o) / dir;
        t0.min(t1).max_element() <= t0.max(t1).min_element()
    }

    /// Histograms the origins' plane coordinates over a grid of cells and compares each count
    /// with n x `origin_pdf` x the region's area in the cell (measured on a finer probe grid):
    /// the origins are uniform over the region and `origin_pdf` is their density.
    #[test]
    fn origins_are_uniform_over_their_region_with_the_stated_density() {
        let b = SceneBounds::new(Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.5));
        let dir = Vec3::new(0.3, -0.5, 0.8).normalize();
        let frame = Frame::from_z(dir);
        let (cells, probes, n) = (8usize, 64usize, 200_000usize);
        let side = 2.0 * b.radius / cells as f32;
        for aim in [Aim::Disc, Aim::Silhouette] {
            let inside = |o: Vec3| match aim {
                Aim::Disc => (o - b.center + dir * b.radius).length() <= b.radius,
                Aim::Silhouette => hits_box(&b, o, dir),
            };
            let mut rng = Rng::from_seed(3, 2);
            let mut counts = vec![0u32; cells * cells];
            for _ in 0..n {
                let o = b.origin(dir, [rng.next_f32(), rng.next_f32()], aim);
                // On the plane one radius behind the centre, outside the sphere.
                assert!(((o - b.center).dot(dir) + b.radius).abs() < 1e-4 * b.radius);
                let d = o - b.center;
                let to = |c: f32| ((c / side + cells as f32 * 0.5).floor() as usize).min(cells - 1);
                counts[to(d.dot(frame.y)) * cells + to(d.dot(frame.x))] += 1;
            }
            let pdf = f64::from(b.origin_pdf(dir, aim));
            for (cell, &count) in counts.iter().enumerate() {
                let (cy, cx) = (cell / cells, cell % cells);
                let mut covered = 0usize;
                for j in 0..probes {
                    for i in 0..probes {
                        let x = (cx as f32 + (i as f32 + 0.5) / probes as f32) * side - b.radius;
                        let y = (cy as f32 + (j as f32 + 0.5) / probes as f32) * side - b.radius;
                        let o = b.center + x * frame.x + y * frame.y - dir * b.radius;
                        covered += usize::from(inside(o));
                    }
                }
                let area = f64::from(side * side) * covered as f64 / (probes * probes) as f64;
                let expected = n as f64 * pdf * area;
                // 5 Poisson deviations; a cell the region's edge crosses adds the probe grid's
                // error, at most the edge's length (under 2 cell sides) times a probe's width.
                let edge = if covered > 0 && covered < probes * probes {
                    n as f64 * pdf * f64::from(2.0 * side * side) / probes as f64
                } else {
                    0.0
                };
                let bound = 5.0 * expected.sqrt().max(1.0) + edge;
                assert!(
                    (f64::from(count) - expected).abs() <= bound,
                    "{aim:?} cell {cell}: {count} vs {expected} (+- {bound})"
                );
            }
        }
    }

    #[test]
    fn flat_scenes_keep_a_silhouette() {
        let b = SceneBounds::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0));
        let edge_on = b.projected_area(Vec3::X);
        assert!(edge_on > 0.0 && edge_on.is_finite());
        assert!(b.origin_pdf(Vec3::X, Aim::Silhouette).is_finite());
        assert!((b.projected_area(Vec3::Z) - 4.0).abs() < 1e-2);
    }
}
