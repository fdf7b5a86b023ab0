//! The environment light: an equirectangular image around the scene, importance-sampled by
//! luminance x sin(theta) with a 2D piecewise-constant distribution over its texels (pbrt's
//! ImageInfiniteLight). Radiance is constant over each texel, so the sampling density is
//! proportional to it up to the sin(theta) of the mapping inside the texel.

use crate::color::Rgb;
use crate::sampling::Distribution2D;
use crate::texture::Texture;
use glam::{Mat3, Vec3};
use std::f32::consts::PI;
use std::sync::Arc;

/// An equirectangular environment image as the sky: radiance `scale * image(w)` seen looking
/// along `w`. In the image's own frame (`w_image = rotation^T w`), +y is the top row and the
/// centre column looks along -z; u = 0.5 + atan2(x, -z) / (2 pi), v = acos(y) / pi from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMapDesc {
    pub image: Arc<Texture>,
    pub scale: f32,
    /// World from image frame.
    pub rotation: Mat3,
}

#[derive(Clone, Debug)]
pub struct EnvLight {
    image: Arc<Texture>,
    scale: f32,
    /// World from image frame, and its inverse.
    rotation: Mat3,
    inverse: Mat3,
    distribution: Distribution2D,
    /// Integral of the radiance's channel average over the sphere.
    integral: f32,
}

impl PartialEq for EnvLight {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.image, &other.image)
            && self.scale == other.scale
            && self.rotation == other.rotation
    }
}

impl EnvLight {
    /// `None` when the image is black everywhere (it lights nothing).
    pub fn new(desc: &EnvMapDesc) -> Option<Self> {
        let image = &desc.image;
        let (w, h) = (image.width as usize, image.height as usize);
        let mut weights = Vec::with_capacity(w * h);
        let mut integral = 0.0f64;
        for y in 0..h {
            let theta0 = PI * y as f32 / h as f32;
            let theta1 = PI * (y + 1) as f32 / h as f32;
            let sin_centre = (PI * (y as f32 + 0.5) / h as f32).sin();
            // Solid angle of one texel of this row.
            let omega = 2.0 * PI / w as f32 * (theta0.cos() - theta1.cos());
            for x in 0..w {
                let texel = image.texel(x as u32, y as u32) * desc.scale;
                weights.push(texel.luminance().max(0.0) * sin_centre);
                integral += (texel.average() * omega) as f64;
            }
        }
        let distribution = Distribution2D::new(w, &weights)?;
        Some(EnvLight {
            image: Arc::clone(image),
            scale: desc.scale,
            rotation: desc.rotation,
            inverse: desc.rotation.transpose(),
            distribution,
            integral: integral as f32,
        })
    }

    /// Integral of the radiance (channel average) over all directions.
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Bytes held by the sampling distribution (the image is shared with the scene).
    pub fn distribution_bytes(&self) -> usize {
        self.distribution.bytes()
    }

    /// The texel seen along the unit world direction `w`, and sin(theta) there.
    fn texel_of(&self, w: Vec3) -> (u32, u32, f32) {
        let l = self.inverse * w;
        let (width, height) = (self.image.width, self.image.height);
        let u = 0.5 + l.x.atan2(-l.z) * (0.5 / PI);
        let v = l.y.clamp(-1.0, 1.0).acos() / PI;
        let x = ((u * width as f32) as u32).min(width - 1);
        let y = ((v * height as f32) as u32).min(height - 1);
        // From x and z, not 1 - y^2, which rounds to zero near the poles.
        let sin_theta = (l.x * l.x + l.z * l.z).sqrt();
        (x, y, sin_theta)
    }

    /// Radiance seen looking along the unit direction `w`.
    pub fn radiance(&self, w: Vec3) -> Rgb {
        let (x, y, _) = self.texel_of(w);
        self.image.texel(x, y) * self.scale
    }

    /// Density of [`EnvLight::sample`] per solid angle at `w`: the texel's probability over
    /// its area in (u, v), times the Jacobian 1 / (2 pi^2 sin(theta)).
    pub fn pdf_w(&self, w: Vec3) -> f32 {
        let (x, y, sin_theta) = self.texel_of(w);
        if sin_theta <= 0.0 {
            return 0.0;
        }
        let cells = (self.image.width * self.image.height) as f32;
        self.distribution.pmf(x as usize, y as usize) * cells / (2.0 * PI * PI * sin_theta)
    }

    /// A direction towards the environment for `u`, with its radiance and pdf per solid
    /// angle; `None` at the poles, where the mapping has no density.
    pub fn sample(&self, u: [f32; 2]) -> Option<(Vec3, Rgb, f32)> {
        let ([fx, fy], _) = self.distribution.sample(u);
        let phi = 2.0 * PI * (fx / self.image.width as f32 - 0.5);
        let theta = PI * fy / self.image.height as f32;
        let (sin_theta, cos_theta) = theta.sin_cos();
        let (sin_phi, cos_phi) = phi.sin_cos();
        let local = Vec3::new(sin_theta * sin_phi, cos_theta, -sin_theta * cos_phi);
        let w = (self.rotation * local).normalize();
        // Radiance and pdf from the direction itself, as a ray reaching the sky finds them.
        let pdf = self.pdf_w(w);
        (pdf > 0.0).then(|| (w, self.radiance(w), pdf))
    }
}
