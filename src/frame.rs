//! Orthonormal frames: the local coordinate system in which BSDFs and lobes are written.

use glam::Vec3;

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

    /// A frame around the unit vector `z` whose `x` axis is `tangent` made orthogonal to `z`
    /// (pbrt-v4's `Frame::FromXZ` after its Gram-Schmidt step), so an anisotropic lobe's
    /// first axis follows the surface's parameterisation; [`Frame::from_z`] where the tangent
    /// is zero or (within rounding, where its projection is noise) parallel to `z`.
    pub fn from_xz(tangent: Vec3, z: Vec3) -> Self {
        let x = tangent - z * z.dot(tangent);
        let len2 = x.length_squared();
        let usable = len2.is_finite() && len2 > 1e-8 * tangent.length_squared();
        if !usable {
            return Frame::from_z(z);
        }
        let x = x / len2.sqrt();
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
    fn tangent_frames_follow_the_tangent() {
        let z = Vec3::new(0.3, -0.8, 0.1).normalize();
        let tangent = Vec3::new(1.0, 2.0, -0.5);
        let f = Frame::from_xz(tangent, z);
        let projected = (tangent - z * z.dot(tangent)).normalize();
        assert!((f.x - projected).length() < 1e-6);
        assert!(f.x.cross(f.y).dot(f.z) > 0.999);
        for (a, b) in [(f.x, f.y), (f.y, f.z), (f.x, f.z)] {
            assert!(a.dot(b).abs() < 1e-6);
        }
        assert_eq!(Frame::from_xz(Vec3::ZERO, z), Frame::from_z(z));
        assert_eq!(Frame::from_xz(2.0 * z, z), Frame::from_z(z));
    }
}
