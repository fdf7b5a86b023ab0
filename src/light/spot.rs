//! The cone of a spot light: pbrt-v4's falloff and its emission sampling.
//!
//! The intensity is full within `cos_falloff_start` of the axis, zero beyond
//! `cos_falloff_end`, and follows a smoothstep of the cosine between the two. Emission samples
//! the inner cone uniformly or the falloff ring by the smoothstep, each in proportion to its
//! share of the power, so the direction's density is the falloff itself over its integral.

use crate::frame::Frame;
use crate::sampling;
use glam::Vec3;
use std::f32::consts::PI;
use thiserror::Error;

/// Why a cone cannot be built.
#[derive(Debug, Error, PartialEq)]
pub enum SpotError {
    #[error("the cone angle {0} is not in (0, 180] degrees")]
    ConeAngle(f32),
    #[error("the falloff angle {delta} is not in [0, {angle}] degrees (the cone angle)")]
    ConeDelta { delta: f32, angle: f32 },
    #[error("the axis {0} has no direction")]
    Axis(Vec3),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotCone {
    /// `z` is the axis.
    frame: Frame,
    cos_falloff_start: f32,
    cos_falloff_end: f32,
}

impl SpotCone {
    /// The cone around `axis` whose falloff ends `cone_angle` degrees off the axis and starts
    /// `cone_delta` degrees inside that (pbrt-v4's `coneangle` and `conedeltaangle`).
    pub fn new(axis: Vec3, cone_angle: f32, cone_delta: f32) -> Result<Self, SpotError> {
        if !(cone_angle > 0.0 && cone_angle <= 180.0) {
            return Err(SpotError::ConeAngle(cone_angle));
        }
        if !(0.0..=cone_angle).contains(&cone_delta) {
            return Err(SpotError::ConeDelta {
                delta: cone_delta,
                angle: cone_angle,
            });
        }
        let length = axis.length();
        if !(length > 0.0 && length.is_finite()) {
            return Err(SpotError::Axis(axis));
        }
        Ok(SpotCone {
            frame: Frame::from_z(axis / length),
            cos_falloff_start: (cone_angle - cone_delta).to_radians().cos(),
            cos_falloff_end: cone_angle.to_radians().cos(),
        })
    }

    pub fn axis(&self) -> Vec3 {
        self.frame.z
    }

    /// The intensity's fraction along the unit direction `dir` (pbrt-v4's `SpotLight::I`).
    pub fn falloff(&self, dir: Vec3) -> f32 {
        smoothstep(
            dir.dot(self.frame.z),
            self.cos_falloff_end,
            self.cos_falloff_start,
        )
    }

    /// The falloff integrated over the sphere of directions: the power of a unit intensity.
    pub fn solid_angle(&self) -> f32 {
        2.0 * PI * self.inner_and_ring().iter().sum::<f32>()
    }

    /// The solid angles (over 2 pi) of the inner cone and of the ring weighted by its falloff:
    /// the smoothstep of the cosine integrates to half the ring's width.
    fn inner_and_ring(&self) -> [f32; 2] {
        [
            1.0 - self.cos_falloff_start,
            0.5 * (self.cos_falloff_start - self.cos_falloff_end),
        ]
    }

    /// Density of [`Self::sample`] per solid angle along the unit `dir`.
    pub fn pdf_w(&self, dir: Vec3) -> f32 {
        self.falloff(dir) / self.solid_angle()
    }

    /// A direction for `u_section` (inner cone or ring) and `u`, with its falloff and density
    /// per solid angle.
    pub fn sample(&self, u_section: f32, u: [f32; 2]) -> (Vec3, f32, f32) {
        let [inner, ring] = self.inner_and_ring();
        let local = if u_section * (inner + ring) < inner {
            sampling::uniform_cone(u, self.cos_falloff_start)
        } else {
            let t = sample_smoothstep(u[0]);
            let cos_theta =
                self.cos_falloff_end + t * (self.cos_falloff_start - self.cos_falloff_end);
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            let phi = 2.0 * PI * u[1];
            Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
        };
        let dir = self.frame.to_world(local);
        (dir, self.falloff(dir), self.pdf_w(dir))
    }
}

/// pbrt-v4's `SmoothStep`: 0 below `a`, 1 above `b`, 3t^2 - 2t^3 between; a step at `a` when
/// the two coincide.
fn smoothstep(x: f32, a: f32, b: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The t in [0, 1] whose normalised smoothstep integral 2t^3 - t^4 is `u`: Newton's method
/// kept inside a shrinking bracket (the cdf is monotone, its derivative vanishes at 0).
fn sample_smoothstep(u: f32) -> f32 {
    let u = f64::from(u);
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let mut t = 0.5;
    for _ in 0..60 {
        let f = t * t * t * (2.0 - t) - u;
        if f.abs() < 1e-9 {
            break;
        }
        if f < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let slope = t * t * (6.0 - 4.0 * t);
        let next = t - f / slope;
        t = if slope > 0.0 && next > lo && next < hi {
            next
        } else {
            0.5 * (lo + hi)
        };
    }
    t as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    fn cone() -> SpotCone {
        SpotCone::new(Vec3::new(0.3, -1.0, 0.2), 40.0, 15.0).unwrap()
    }

    #[test]
    fn the_falloff_is_full_inside_zero_outside_and_smooth_between() {
        let c = cone();
        let at = |deg: f32| {
            let local = Vec3::new(deg.to_radians().sin(), 0.0, deg.to_radians().cos());
            c.falloff(c.frame.to_world(local))
        };
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(24.9), 1.0);
        assert_eq!(at(40.1), 0.0);
        let (cs, ce) = (25f32.to_radians().cos(), 40f32.to_radians().cos());
        let t = (30f32.to_radians().cos() - ce) / (cs - ce);
        assert!((at(30.0) - t * t * (3.0 - 2.0 * t)).abs() < 1e-5);
    }

    #[test]
    fn the_smoothstep_inverse_inverts_its_cdf() {
        for i in 0..=100 {
            let u = i as f32 / 100.0;
            let t = f64::from(sample_smoothstep(u));
            assert!((t * t * t * (2.0 - t) - f64::from(u)).abs() < 1e-6, "u {u}");
        }
    }

    /// The samples' histogram over the cosine matches the pdf, and the pdf integrates to 1.
    #[test]
    fn samples_follow_their_density() {
        let c = cone();
        let mut rng = Rng::for_sample(3, 0, 0, Stream::Light);
        const BINS: usize = 50;
        const N: usize = 400_000;
        let cos_end = c.cos_falloff_end;
        let width = (1.0 - cos_end) / BINS as f32;
        let mut counts = [0u32; BINS];
        for _ in 0..N {
            let (dir, falloff, pdf) = c.sample(rng.next_f32(), rng.next_2d());
            assert!(falloff > 0.0 && (pdf - c.pdf_w(dir)).abs() <= 1e-6 * pdf);
            let cos = dir.dot(c.axis());
            let bin = (((cos - cos_end) / width) as usize).min(BINS - 1);
            counts[bin] += 1;
        }
        let mut total = 0.0;
        for (i, &n) in counts.iter().enumerate() {
            // The expected count: the pdf over the band of cosines, by the midpoint rule on
            // fine steps.
            let steps = 40;
            let mut p = 0.0;
            for j in 0..steps {
                let cos = cos_end + width * (i as f32 + (j as f32 + 0.5) / steps as f32);
                let local = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                p += c.pdf_w(c.frame.to_world(local)) * 2.0 * PI * width / steps as f32;
            }
            total += p;
            let expected = p * N as f32;
            let sd = expected.max(1.0).sqrt();
            assert!(
                (n as f32 - expected).abs() < 5.0 * sd + 2.0,
                "bin {i}: {n} samples, {expected} expected"
            );
        }
        assert!((total - 1.0).abs() < 1e-3, "the pdf integrates to {total}");
    }

    #[test]
    fn bad_cones_are_refused() {
        assert!(SpotCone::new(Vec3::Z, 0.0, 0.0).is_err());
        assert!(SpotCone::new(Vec3::Z, 190.0, 5.0).is_err());
        assert!(SpotCone::new(Vec3::Z, 30.0, 40.0).is_err());
        assert!(SpotCone::new(Vec3::Z, 30.0, f32::NAN).is_err());
        assert!(SpotCone::new(Vec3::ZERO, 30.0, 5.0).is_err());
        assert!(SpotCone::new(Vec3::Z, 30.0, 0.0).is_ok());
        assert!(SpotCone::new(Vec3::Z, 30.0, 30.0).is_ok());
    }
}
