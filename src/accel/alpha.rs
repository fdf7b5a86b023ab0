//! Alpha cut-outs: triangles whose alpha (a constant, or a texture read at the hit's uv) makes
//! some of their hits vanish for every ray query, as pbrt-v4's `alpha` on shapes does.
//!
//! The rule is pbrt-v4's `GeometricPrimitive::Intersect`: alpha >= 1 keeps a hit, alpha <= 0
//! drops it, and a fractional alpha `a` keeps it where a hash of the query is at most `a`. pbrt
//! hashes the ray's origin and direction and traces a new ray from each dropped hit, so every
//! surface on the way sees another origin; here one query tests all its candidate hits, so the
//! hash also covers the triangle, which keeps the decisions of two cut-outs on one ray
//! independent. The decision depends on nothing but the ray and the triangle: both backends,
//! single rays and packets make the same one, whatever the thread or the order of the tests.

use super::Ray;
use crate::texture::Texture;
use glam::Vec2;
use std::sync::Arc;

/// An alpha value over a surface.
#[derive(Clone, Debug, PartialEq)]
pub enum Alpha {
    Constant(f32),
    /// A texture read at the surface's uv, its red channel the alpha.
    Texture(Arc<Texture>),
}

/// A cut-out triangle: its alpha and the uvs of its vertices.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleAlpha {
    pub alpha: Alpha,
    pub uvs: [Vec2; 3],
}

impl TriangleAlpha {
    /// Alpha at barycentrics `(b1, b2)` (the weights of vertices 1 and 2).
    #[inline]
    pub fn value(&self, b1: f32, b2: f32) -> f32 {
        match &self.alpha {
            Alpha::Constant(a) => *a,
            Alpha::Texture(texture) => {
                let [a, b, c] = self.uvs;
                texture.lookup((1.0 - b1 - b2) * a + b1 * b + b2 * c).r
            }
        }
    }
}

/// The cut-out triangles of a geometry; empty for most scenes, which then pay nothing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cutouts {
    /// Per triangle up to the last cut-out one: 0 for an opaque triangle, else one more than
    /// its index in `triangles`.
    slots: Vec<u32>,
    triangles: Vec<TriangleAlpha>,
}

impl Cutouts {
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// How many triangles are cut out.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Makes `triangle` a cut-out with `alpha`; a triangle set twice keeps the last.
    pub fn set(&mut self, triangle: u32, alpha: TriangleAlpha) {
        let i = triangle as usize;
        if self.slots.len() <= i {
            self.slots.resize(i + 1, 0);
        }
        match self.slots[i] {
            0 => {
                self.triangles.push(alpha);
                self.slots[i] = self.triangles.len() as u32;
            }
            slot => self.triangles[slot as usize - 1] = alpha,
        }
    }

    /// The alpha of `triangle`, `None` when it is opaque.
    #[inline]
    pub fn get(&self, triangle: u32) -> Option<&TriangleAlpha> {
        match self.slots.get(triangle as usize) {
            Some(&slot) if slot > 0 => Some(&self.triangles[slot as usize - 1]),
            _ => None,
        }
    }

    /// Whether the hit of `ray` on `triangle` at barycentrics `(b1, b2)` counts.
    #[inline]
    pub fn keeps(&self, triangle: u32, b1: f32, b2: f32, ray: &Ray) -> bool {
        self.get(triangle)
            .is_none_or(|alpha| keeps(alpha.value(b1, b2), triangle, ray))
    }
}

/// pbrt-v4's stochastic alpha test (module doc) for alpha `a`.
#[inline]
pub fn keeps(a: f32, triangle: u32, ray: &Ray) -> bool {
    if a >= 1.0 {
        true
    } else if a > 0.0 {
        hash_float(ray, triangle) <= a
    } else {
        // Also NaN, which no texture should hold.
        false
    }
}

/// A number in [0, 1) from the ray's origin and direction and the triangle, as pbrt-v4's
/// `HashFloat`: the low 32 bits of MurmurHash64A over their bytes.
pub fn hash_float(ray: &Ray, triangle: u32) -> f32 {
    let mut bytes = [0u8; 28];
    let values = [
        ray.origin.x,
        ray.origin.y,
        ray.origin.z,
        ray.dir.x,
        ray.dir.y,
        ray.dir.z,
    ];
    for (chunk, v) in bytes.chunks_exact_mut(4).zip(values) {
        chunk.copy_from_slice(&v.to_le_bytes());
    }
    bytes[24..].copy_from_slice(&triangle.to_le_bytes());
    (murmur_hash_64a(&bytes, 0) as u32) as f32 * (1.0 / 4_294_967_296.0)
}

/// Austin Appleby's MurmurHash64A (public domain), as pbrt-v4 hashes with it.
fn murmur_hash_64a(key: &[u8], seed: u64) -> u64 {
    const M: u64 = 0xc6a4_a793_5bd1_e995;
    const R: u32 = 47;
    let mut h = seed ^ (key.len() as u64).wrapping_mul(M);
    let mut blocks = key.chunks_exact(8);
    for block in &mut blocks {
        let mut bytes = [0u8; 8];
        bytes.copy_from_slice(block);
        let mut k = u64::from_le_bytes(bytes).wrapping_mul(M);
        k ^= k >> R;
        k = k.wrapping_mul(M);
        h ^= k;
        h = h.wrapping_mul(M);
    }
    let tail = blocks.remainder();
    if !tail.is_empty() {
        for (i, &b) in tail.iter().enumerate() {
            h ^= (b as u64) << (8 * i);
        }
        h = h.wrapping_mul(M);
    }
    h ^= h >> R;
    h = h.wrapping_mul(M);
    h ^= h >> R;
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// MurmurHash64A values (seed 0) computed with pbrt-v4's C++ implementation.
    #[test]
    fn murmur_matches_the_reference() {
        assert_eq!(murmur_hash_64a(b"", 0), 0);
        assert_eq!(murmur_hash_64a(b"hello", 0), 0x1e68_d17c_457b_f117);
        assert_eq!(
            murmur_hash_64a(b"0123456789abcdefXYZ", 0),
            0x083a_94d5_0cc1_ddd0
        );
    }

    #[test]
    fn hash_is_uniform() {
        let n = 100_000;
        let mut below = [0u32; 10];
        for i in 0..n {
            let ray = Ray::new(Vec3::new(i as f32 * 1e-3, 0.5, -1.0), Vec3::Z);
            let u = hash_float(&ray, 7);
            assert!((0.0..1.0).contains(&u));
            below[(u * 10.0) as usize] += 1;
        }
        // Each decile holds n / 10 within 5 standard deviations of a binomial count.
        let sd = (n as f64 * 0.1 * 0.9).sqrt();
        for count in below {
            assert!(
                (count as f64 - n as f64 / 10.0).abs() < 5.0 * sd,
                "{below:?}"
            );
        }
    }

    #[test]
    fn thresholds_follow_pbrt() {
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!(keeps(1.0, 0, &ray));
        assert!(!keeps(0.0, 0, &ray));
        assert!(!keeps(f32::NAN, 0, &ray));
        let u = hash_float(&ray, 0);
        assert!(keeps(u, 0, &ray));
        assert!(!keeps(u * 0.999, 0, &ray));
    }
}
