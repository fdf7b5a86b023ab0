//! pbrt-v4's MixMaterial: at each surface point one of two materials, the second with
//! probability `amount` (a constant or a texture), chosen by a hash of the point, so the
//! choice is deterministic and a pixel sees the two in proportion.
//!
//! pbrt-v4 hashes the point and `wo`. Here the hash is of the point alone, as the ray query
//! reports it (the primitive and its barycentrics, or a sphere's normal): a bidirectional path
//! reaches a vertex from the eye and from the light with different `wo`, and every technique's
//! MIS weight takes the pdfs of both sides of that vertex from one BSDF. With `wo` in the hash
//! the light sub-path would scatter by one material there and the eye sub-path's reverse pdf
//! would come from the other, so the weights of a path would no longer sum to one; a function
//! of the point alone is one spatially varying material, the same to every technique.

use crate::accel::{Hit, Primitive};

/// A material that is `materials[0]` or `materials[1]` at each point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mix {
    /// Indices into the scene's materials (either may be a mix itself).
    pub materials: [u32; 2],
    /// The probability of the second material where no texture gives it.
    pub amount: f32,
    /// A texture (index into the scene's textures) whose mean channel gives `amount`.
    pub amount_texture: Option<u32>,
}

/// Mixes nested deeper than this resolve to their first material (the importers build none:
/// a mix names materials defined before it).
pub const MAX_NESTING: usize = 8;

impl Mix {
    /// The material at the point of `hit` where the amount is `amount`.
    pub fn choose(&self, amount: f32, hit: &Hit) -> u32 {
        if amount <= 0.0 {
            return self.materials[0];
        }
        if amount >= 1.0 {
            return self.materials[1];
        }
        // pbrt-v4: the first material where amount < u.
        if amount < point_hash(hit, self.materials) {
            self.materials[0]
        } else {
            self.materials[1]
        }
    }
}

/// A number in [0, 1) that is a fixed function of the point (and of the two materials, so
/// nested mixes choose independently).
fn point_hash(hit: &Hit, materials: [u32; 2]) -> f32 {
    let (id, a, b, c) = match hit.primitive {
        Primitive::Triangle(i) => (u64::from(i), hit.u, hit.v, 0.0f32),
        Primitive::Sphere(i) => (u64::from(i) | 1 << 32, hit.ng.x, hit.ng.y, hit.ng.z),
    };
    let mut h = id ^ (u64::from(materials[0]) << 40) ^ (u64::from(materials[1]) << 52);
    for x in [a, b, c] {
        h = mix64(h ^ u64::from(x.to_bits()));
    }
    // The top 24 bits: every value exact in f32 and below 1.
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// SplitMix64's finaliser: every input bit reaches every output bit.
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn hit(triangle: u32, u: f32, v: f32) -> Hit {
        Hit {
            t: 1.0,
            primitive: Primitive::Triangle(triangle),
            group: 0,
            u,
            v,
            ng: Vec3::Z,
        }
    }

    #[test]
    fn choice_is_a_function_of_the_point_in_proportion() {
        let mix = Mix {
            materials: [3, 7],
            amount: 0.3,
            amount_texture: None,
        };
        let n = 100_000;
        let mut second = 0;
        for i in 0..n {
            let h = hit(
                i % 97,
                (i as f32 * 0.618_034).fract(),
                (i as f32 * 0.414_214).fract() * 0.5,
            );
            let m = mix.choose(mix.amount, &h);
            // Seen again (another ray to the same point), the same material.
            assert_eq!(m, mix.choose(mix.amount, &h));
            second += usize::from(m == 7);
        }
        let p = second as f64 / n as f64;
        let sigma = (0.3 * 0.7 / n as f64).sqrt();
        assert!((p - 0.3).abs() < 4.0 * sigma, "{p}");
        assert_eq!(mix.choose(0.0, &hit(1, 0.2, 0.2)), 3);
        assert_eq!(mix.choose(1.0, &hit(1, 0.2, 0.2)), 7);
    }
}
