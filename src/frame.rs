//! Orthonormal frames: the local coordinate system in which BSDFs and lobes are written.

use glam::Vec3;

/// Steps of a full turn in an [`Azimuth`] (2^16: 1e-4 radians each).
const AZIMUTH_STEPS: f32 = 65536.0;

/// A tangent's direction about a unit normal `n`, as its angle from `Frame::from_z(n).x`
/// towards `.y` in steps of 1e-4 radians: two bytes (which a stored light vertex has spare)
/// from which [`Frame::turned`] rebuilds the same frame wherever the surface point is used.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Azimuth(u16);

impl Azimuth {
    /// The azimuth of `tangent` (any length) about `n`; zero, pbrt-v4's fallback
    /// `CoordinateSystem(n)`, where it has no component across `n` beyond rounding.
    pub fn of(tangent: Vec3, n: Vec3) -> Self {
        if tangent == Vec3::ZERO {
            return Azimuth(0);
        }
        let base = Frame::from_z(n);
        let (x, y) = (tangent.dot(base.x), tangent.dot(base.y));
        let across = x * x + y * y;
        if !(across.is_finite() && across > 1e-8 * tangent.length_squared()) {
            return Azimuth(0);
        }
        let turns = y.atan2(x) / std::f32::consts::TAU;
        // Negative turns wrap around through i32: the step count is taken modulo 2^16.
        Azimuth((turns * AZIMUTH_STEPS).round() as i32 as u16)
    }

    pub fn radians(self) -> f32 {
        self.0 as f32 * (std::f32::consts::TAU / AZIMUTH_STEPS)
    }
}

/// An orthonormal basis with `z` as the "up" axis (a surface normal, a lobe axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
}

impl Frame {
    /// A frame around the unit vector `z` (Duff et al. 2017, "Building an orthonormal basis,
    /// revisited": branchless and continuous except on one half-plane).
    pub fn from_z(z: Vec3) -> Self {
        let sign = 1.0f32.copysign(z.z);
        let a = -1.0 / (sign + z.z);
        let b = z.x * z.y * a;
        let x = Vec3::new(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x);
        let y = Vec3::new(b, sign + z.y * z.y * a, -z.y);
        Frame { x, y, z }
    }

    /// A frame around `z`, the unit normal `n` or its opposite, whose `x` axis lies at
    /// `azimuth` about `n`: pbrt-v4's `Frame::FromXZ` of a tangent made orthogonal to `n`,
    /// so an anisotropic lobe's first axis follows the surface's parameterisation.
    pub fn turned(n: Vec3, z: Vec3, azimuth: Azimuth) -> Self {
        let base = Frame::from_z(n);
        let (sin, cos) = azimuth.radians().sin_cos();
        let x = base.x * cos + base.y * sin;
        Frame {
            x,
            y: z.cross(x),
            z,
        }
    }

    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_orthonormal() {
        let dirs = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.8, 0.1).normalize(),
            Vec3::new(-1e-7, 0.0, -1.0).normalize(),
        ];
        for z in dirs {
            let f = Frame::from_z(z);
            for (a, b) in [(f.x, f.y), (f.y, f.z), (f.x, f.z)] {
                assert!(a.dot(b).abs() < 1e-6);
            }
            for v in [f.x, f.y, f.z] {
                assert!((v.length() - 1.0).abs() < 1e-6);
            }
            let v = Vec3::new(0.2, 0.5, -0.7);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }

    #[test]
    fn turned_frames_follow_the_tangent() {
        let n = Vec3::new(0.3, -0.8, 0.1).normalize();
        let projected = |t: Vec3| (t - n * n.dot(t)).normalize();
        for tangent in [
            Vec3::new(1.0, 2.0, -0.5),
            Vec3::new(-3.0, 0.1, 0.2),
            Vec3::new(0.2, 0.1, -4.0),
        ] {
            for z in [n, -n] {
                let f = Frame::turned(n, z, Azimuth::of(tangent, n));
                // Within the azimuth's step.
                assert!((f.x - projected(tangent)).length() < 1e-4, "{tangent}");
                assert_eq!(f.z, z);
                assert!(f.x.cross(f.y).dot(f.z) > 0.999);
                for (a, b) in [(f.x, f.y), (f.y, f.z), (f.x, f.z)] {
                    assert!(a.dot(b).abs() < 1e-6);
                }
            }
        }
        let base = Frame::from_z(n);
        assert_eq!(Azimuth::of(Vec3::ZERO, n), Azimuth::default());
        assert_eq!(Azimuth::of(2.0 * n, n), Azimuth::default());
        assert!((Frame::turned(n, n, Azimuth::default()).x - base.x).length() < 1e-6);
    }
}
