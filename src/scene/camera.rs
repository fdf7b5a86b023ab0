//! The pinhole camera: primary rays, and the inverse map (a point to its pixel) with the
//! importance needed to splat light-path vertices onto the film (001 sec. 3, SmallVCM).

use crate::accel::Ray;
use crate::frame::Frame;
use glam::Vec3;

/// A camera as the scene file states it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDesc {
    pub name: String,
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Field of view in degrees, across the image axis `fov_axis` names.
    pub fov_deg: f32,
    pub fov_axis: FovAxis,
    /// Mirrors the image left to right: for camera transforms of the other handedness (pbrt
    /// puts camera-space +x on the right, which is `up x forward`, where vmerge puts
    /// `forward x up`).
    pub mirrored: bool,
}

/// Which image axis a camera's field of view spans.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FovAxis {
    Vertical,
    /// The shorter of the two (pbrt's rule).
    Shorter,
}

/// A pinhole camera at a given resolution.
#[derive(Clone, Debug)]
pub struct Camera {
    pub position: Vec3,
    /// `x` right, `y` up, `z` forward (the viewing direction).
    frame: Frame,
    pub width: u32,
    pub height: u32,
    /// Distance from the pinhole to an image plane on which pixels are unit squares.
    image_plane_dist: f32,
}

impl Camera {
    pub fn new(desc: &CameraDesc, width: u32, height: u32) -> Self {
        let forward = (desc.look_at - desc.position).normalize();
        let right = forward.cross(desc.up).normalize();
        let up = right.cross(forward);
        let right = if desc.mirrored { -right } else { right };
        let tan_half = (desc.fov_deg.to_radians() * 0.5).tan();
        let span = match desc.fov_axis {
            FovAxis::Vertical => height,
            FovAxis::Shorter => width.min(height),
        };
        Camera {
            position: desc.position,
            frame: Frame {
                x: right,
                y: up,
                z: forward,
            },
            width,
            height,
            image_plane_dist: span as f32 / (2.0 * tan_half),
        }
    }

    pub fn forward(&self) -> Vec3 {
        self.frame.z
    }

    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The primary ray through raster position `(x, y)` (pixels, y down), unit direction.
    pub fn generate_ray(&self, x: f32, y: f32) -> Ray {
        let local = Vec3::new(
            x - 0.5 * self.width as f32,
            0.5 * self.height as f32 - y,
            self.image_plane_dist,
        );
        Ray::new(self.position, self.frame.to_world(local).normalize())
    }

    /// Raster position of the world point `p`, when it is in front of the camera and on the film.
    pub fn raster(&self, p: Vec3) -> Option<(f32, f32)> {
        let local = self.frame.to_local(p - self.position);
        if local.z <= 0.0 {
            return None;
        }
        let scale = self.image_plane_dist / local.z;
        let x = local.x * scale + 0.5 * self.width as f32;
        let y = 0.5 * self.height as f32 - local.y * scale;
        let inside = x >= 0.0 && x < self.width as f32 && y >= 0.0 && y < self.height as f32;
        inside.then_some((x, y))
    }

    /// Pixel index of a raster position.
    pub fn pixel_index(&self, x: f32, y: f32) -> usize {
        let px = (x as u32).min(self.width - 1);
        let py = (y as u32).min(self.height - 1);
        py as usize * self.width as usize + px as usize
    }

    /// Solid-angle density with which the camera samples `dir` (unit) when one pixel-sized
    /// area of the image plane has measure 1: `d^2 / cos^3` (SmallVCM's cameraPdfW). 0 behind.
    pub fn pdf_w(&self, dir: Vec3) -> f32 {
        let cos = dir.dot(self.frame.z);
        if cos <= 0.0 {
            return 0.0;
        }
        self.image_plane_dist * self.image_plane_dist / (cos * cos * cos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_inverts_generate_ray() {
        let desc = CameraDesc {
            name: "c".into(),
            position: Vec3::new(0.0, 1.0, 3.4),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_deg: 40.0,
            fov_axis: FovAxis::Vertical,
            mirrored: false,
        };
        let cam = Camera::new(&desc, 64, 48);
        for (x, y) in [(0.5, 0.5), (10.25, 40.75), (63.9, 0.1), (32.0, 24.0)] {
            let ray = cam.generate_ray(x, y);
            let (rx, ry) = cam.raster(ray.at(2.7)).unwrap();
            assert!(
                (rx - x).abs() < 1e-3 && (ry - y).abs() < 1e-3,
                "{x},{y} -> {rx},{ry}"
            );
        }
        assert!(cam.raster(Vec3::new(0.0, 1.0, 5.0)).is_none());
        // The vertical field of view spans the image height.
        let top = cam.generate_ray(32.0, 0.0).dir;
        let bottom = cam.generate_ray(32.0, 48.0).dir;
        assert!((top.angle_between(bottom).to_degrees() - 40.0).abs() < 1e-3);
    }
}
