//! Where the infinite lights (directional, sky, environment) start their light sub-paths: on
//! the silhouette of the scene's bounding box seen along the direction of travel.
//!
//! A light sub-path of an infinite light picks a direction, then a point on a plane
//! perpendicular to it (001 sec. 5.1). The usual plane region is the disk of the bounding
//! sphere (SmallVCM, pbrt-v4), of area pi r^2; the box's silhouette holds every ray that
//! reaches the scene too, and is smaller: a cube's is 0.42 to 0.74 of its sphere's disk
//! (0.64 on average over directions), so that many more of the traced paths reach geometry.
//! The silhouette is the projection of the (up to three) box faces that face the light, which
//! do not overlap: a face chosen in proportion to its projected area, then a uniform point on
//! it, is a uniform point on the silhouette, of density 1 / (projected area) per unit area of
//! the plane.

use glam::Vec3;

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
    pub fn origin_pdf(&self, dir: Vec3) -> f32 {
        1.0 / self.projected_area(dir)
    }

    /// Area of the silhouette averaged over all directions: a quarter of the box's surface
    /// (Cauchy's formula), the measure of an isotropic infinite light's power.
    pub fn mean_projected_area(&self) -> f32 {
        0.5 * (self.face_areas.x + self.face_areas.y + self.face_areas.z)
    }

    /// A uniform point of the silhouette seen along the unit `dir`, moved back along `dir` to
    /// the plane one bounding-sphere radius behind the centre, so a ray from it along `dir`
    /// crosses the whole scene. `u[0]` picks the face and, rescaled, the first coordinate on
    /// it; `u[1]` the second.
    pub fn origin(&self, dir: Vec3, u: [f32; 2]) -> Vec3 {
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
    /// sphere's disk whose rays along `dir` hit the box.
    fn hit_fraction_area(b: &SceneBounds, dir: Vec3, rng: &mut Rng, n: usize) -> f64 {
        let frame = crate::frame::Frame::from_z(dir);
        let side = 2.0 * b.radius;
        let mut hits = 0usize;
        for _ in 0..n {
            let (x, y) = (rng.next_f32() - 0.5, rng.next_f32() - 0.5);
            let o = b.center + side * (x * frame.x + y * frame.y) - dir * 2.0 * b.radius;
            let inv = dir.recip();
            let t0 = (b.min - o) * inv;
            let t1 = (b.max - o) * inv;
            let enter = t0.min(t1).max_element();
            let exit = t0.max(t1).min_element();
            hits += usize::from(enter <= exit);
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

    #[test]
    fn origins_cover_the_silhouette_uniformly_from_outside() {
        let b = SceneBounds::new(Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.5));
        let mut rng = Rng::from_seed(3, 2);
        let dir = Vec3::new(0.3, -0.5, 0.8).normalize();
        let frame = crate::frame::Frame::from_z(dir);
        // Histogram of the origins' plane coordinates over a grid, against the silhouette's
        // share of each grid cell (found by the hit test) times the sample count.
        let cells = 8;
        let n = 200_000;
        let mut counts = vec![0u32; cells * cells];
        let cell_of = |p: Vec3| {
            let d = p - b.center;
            let to = |c: f32| (((c / (2.0 * b.radius)) + 0.5) * cells as f32).floor() as usize;
            (
                to(d.dot(frame.x)).min(cells - 1),
                to(d.dot(frame.y)).min(cells - 1),
            )
        };
        for _ in 0..n {
            let o = b.origin(dir, [rng.next_f32(), rng.next_f32()]);
            // On the plane one radius behind the centre, outside the sphere.
            assert!(((o - b.center).dot(dir) + b.radius).abs() < 1e-4 * b.radius);
            let (x, y) = cell_of(o);
            counts[y * cells + x] += 1;
        }
        let mut area = vec![0usize; cells * cells];
        let probes = 64;
        for j in 0..cells * probes {
            for i in 0..cells * probes {
                let x = (i as f32 + 0.5) / (cells * probes) as f32 - 0.5;
                let y = (j as f32 + 0.5) / (cells * probes) as f32 - 0.5;
                let o =
                    b.center + 2.0 * b.radius * (x * frame.x + y * frame.y) - dir * 2.0 * b.radius;
                let t0 = (b.min - o) / dir;
                let t1 = (b.max - o) / dir;
                if t0.min(t1).max_element() <= t0.max(t1).min_element() {
                    area[(j / probes) * cells + i / probes] += 1;
                }
            }
        }
        let total: usize = area.iter().sum();
        for (count, area) in counts.iter().zip(&area) {
            let expected = *area as f64 / total as f64 * n as f64;
            // Cells cut by the silhouette's edge carry the probe grid's error on top of the
            // Poisson noise; 5 standard deviations of both.
            let edge = if *area > 0 && *area < probes * probes {
                0.05 * expected
            } else {
                0.0
            };
            let bound = 5.0 * expected.sqrt().max(1.0) + edge;
            assert!(
                (f64::from(*count) - expected).abs() <= bound,
                "{count} vs {expected}"
            );
        }
    }

    #[test]
    fn flat_scenes_keep_a_silhouette() {
        let b = SceneBounds::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0));
        let edge_on = b.projected_area(Vec3::X);
        assert!(edge_on > 0.0 && edge_on.is_finite());
        assert!(b.origin_pdf(Vec3::X).is_finite());
        assert!((b.projected_area(Vec3::Z) - 4.0).abs() < 1e-2);
    }
}
