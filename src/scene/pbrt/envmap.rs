//! pbrt-v4's environment images are square, in the equal-area octahedral mapping (Clarberg,
//! "Fast equal-area mapping of the (hemi)sphere using SIMD", 2008; pbrt-v4's
//! `EqualAreaSphereToSquare`); vmerge's environment light takes an equirectangular image. The
//! import resamples one into the other, with the light's transform folded in.

use crate::texture::Texture;
use glam::{DMat3, DVec3, Vec2};
use std::f64::consts::PI;

/// pbrt-v4's `EqualAreaSphereToSquare`: the unit direction `d` to a point of [0, 1]^2, (0, 0)
/// being the image's top-left corner.
pub fn equal_area_sphere_to_square(d: DVec3) -> [f64; 2] {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = if a == 0.0 { 0.0 } else { x.min(y) / a };
    let mut phi = b.atan() * 2.0 / PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    [0.5 * (u.copysign(d.x) + 1.0), 0.5 * (v.copysign(d.y) + 1.0)]
}

/// The equirectangular image (2n x n for an n x n square) of the octahedral `square` seen in
/// world space, where the light's frame is `light_from_world` of the world: texel (x, y) looks
/// along the world direction of u = (x + 0.5) / 2n, v = (y + 0.5) / n in vmerge's convention
/// (`light::EnvMapDesc`), and takes the square's bilinear value in the light's direction.
pub fn equirect_from_octahedral(square: &Texture, light_from_world: DMat3) -> Texture {
    let (w, h) = (2 * square.width, square.height);
    let mut texels = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        let theta = PI * (y as f64 + 0.5) / h as f64;
        for x in 0..w {
            let phi = 2.0 * PI * ((x as f64 + 0.5) / w as f64 - 0.5);
            let world = DVec3::new(
                theta.sin() * phi.sin(),
                theta.cos(),
                -theta.sin() * phi.cos(),
            );
            let light = (light_from_world * world).normalize_or_zero();
            let [u, v] = equal_area_sphere_to_square(light);
            // Texture::lookup counts v from the bottom row.
            texels.push(square.lookup(Vec2::new(u as f32, (1.0 - v) as f32)));
        }
    }
    Texture {
        width: w,
        height: h,
        texels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::color::Rgb;

    #[test]
    fn the_mapping_puts_the_axes_where_pbrt_does() {
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() + (a[1] - b[1]).abs() < 1e-12;
        assert!(close(equal_area_sphere_to_square(DVec3::Z), [0.5, 0.5]));
        assert!(close(equal_area_sphere_to_square(DVec3::X), [1.0, 0.5]));
        assert!(close(equal_area_sphere_to_square(DVec3::Y), [0.5, 1.0]));
        assert!(close(equal_area_sphere_to_square(-DVec3::X), [0.0, 0.5]));
        assert!(close(
            equal_area_sphere_to_square(DVec3::new(0.0, 0.0, -1.0)),
            [1.0, 1.0]
        ));
        // Equal area: a cap of solid angle 2 pi (1 - cos t) maps to a diamond of area
        // (1 - cos t) / 2 of the unit square; the cap of half the sphere, to half the square.
        let n = 400;
        let inside = (0..n * n)
            .filter(|k| {
                let (i, j) = ((k % n) as f64 + 0.5, (k / n) as f64 + 0.5);
                let (u, v) = (2.0 * i / n as f64 - 1.0, 2.0 * j / n as f64 - 1.0);
                u.abs() + v.abs() <= 1.0
            })
            .count();
        assert!((inside as f64 / (n * n) as f64 - 0.5).abs() < 0.01);
    }

    #[test]
    fn resampling_follows_the_light_transform() {
        // Left half of the square (light-space x < 0) white, right half black.
        let n = 64;
        let texels = (0..n * n)
            .map(|k| {
                if k % n < n / 2 {
                    Rgb::WHITE
                } else {
                    Rgb::BLACK
                }
            })
            .collect();
        let square = Texture::new(n, n, texels).unwrap();
        let at = |image: &Texture, d: DVec3| {
            // The equirectangular texel looking along d.
            let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
            let v = d.y.clamp(-1.0, 1.0).acos() / PI;
            let x = ((u * image.width as f64) as u32).min(image.width - 1);
            let y = ((v * image.height as f64) as u32).min(image.height - 1);
            image.texel(x, y).r
        };
        let plain = equirect_from_octahedral(&square, DMat3::IDENTITY);
        assert_eq!((plain.width, plain.height), (2 * n, n));
        let d = DVec3::new(-0.8, 0.3, 0.2).normalize();
        assert_eq!(at(&plain, d), 1.0);
        assert_eq!(at(&plain, DVec3::new(0.8, 0.3, 0.2).normalize()), 0.0);
        // Turned half a turn about y, the world's -x is the light's +x.
        let turned = equirect_from_octahedral(&square, DMat3::from_rotation_y(PI));
        assert_eq!(at(&turned, d), 0.0);
    }
}
