//! Warps from the unit square to directions and points, each with its density. Directions are
//! in a local frame with `z` up unless stated otherwise.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

/// Cosine-weighted hemisphere (Malley's method on a concentric disk); pdf = cos / pi.
pub fn cosine_hemisphere(u: [f32; 2]) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Directions around `z` with density proportional to cos^n (the Phong lobe):
/// pdf = (n + 1) / (2 pi) cos^n.
pub fn power_cosine(u: [f32; 2], exponent: f32) -> Vec3 {
    let cos_theta = u[0].powf(1.0 / (exponent + 1.0));
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turn(u[1]);
    Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

/// The pdf of [`power_cosine`] at `cos_theta`, given `lobe` = cos_theta^exponent (which its
/// caller has already computed for the BSDF value: one `powf` serves both).
pub fn power_cosine_pdf(cos_theta: f32, lobe: f32, exponent: f32) -> f32 {
    if cos_theta <= 0.0 {
        return 0.0;
    }
    (exponent + 1.0) * 0.5 * FRAC_1_PI * lobe
}

/// Uniform on the unit sphere; pdf = 1 / (4 pi).
pub fn uniform_sphere(u: [f32; 2]) -> Vec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turn(u[1]);
    Vec3::new(r * cos_phi, r * sin_phi, z)
}

pub const UNIFORM_SPHERE_PDF: f32 = 0.25 * FRAC_1_PI;

/// Uniform in the cone of directions within `cos_max` of `z`; pdf = 1 / (2 pi (1 - cos_max)).
pub fn uniform_cone(u: [f32; 2], cos_max: f32) -> Vec3 {
    let cos_theta = 1.0 - u[0] * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = sin_cos_turn(u[1]);
    Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Shirley-Chiu concentric map of the square to the unit disk; uniform, pdf = 1 / pi.
pub fn concentric_disk(u: [f32; 2]) -> Vec2 {
    let a = 2.0 * u[0] - 1.0;
    let b = 2.0 * u[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    // The angle is pi/4 (b/a), or pi/2 - pi/4 (a/b) in the other wedge, whose cosine and sine
    // are those of pi/4 (a/b) swapped: both within pi/4 of an axis, where a short polynomial
    // serves.
    if a * a > b * b {
        let (sin, cos) = sin_cos_octant((PI / 4.0) * (b / a));
        Vec2::new(a * cos, a * sin)
    } else {
        let (sin, cos) = sin_cos_octant((PI / 4.0) * (a / b));
        Vec2::new(b * sin, b * cos)
    }
}

/// `(sin, cos)` of `2 pi t` for `t` in [0, 1]: the quarter turn nearest `t` is taken out exactly
/// (`t - q / 4` needs no rounding there), leaving an angle within pi/4 of zero.
#[inline]
pub fn sin_cos_turn(t: f32) -> (f32, f32) {
    let quarter = (4.0 * t).round();
    let (sin, cos) = sin_cos_octant(2.0 * PI * (t - 0.25 * quarter));
    match quarter as u32 & 3 {
        0 => (sin, cos),
        1 => (cos, -sin),
        2 => (-sin, -cos),
        _ => (-cos, sin),
    }
}

/// `(sin, cos)` of `x` for `|x| <= pi/4`: Cephes' minimax polynomials for single precision
/// (Moshier), within an ulp or two there, inline where a libm call would first reduce the range.
#[inline]
fn sin_cos_octant(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * x + x;
    let cos = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    (sin, cos)
}

/// Uniform barycentrics `(b1, b2)` on a triangle (Heitz 2019, low-distortion and area
/// preserving); the point is `(1 - b1 - b2) p0 + b1 p1 + b2 p2`.
pub fn uniform_triangle(u: [f32; 2]) -> (f32, f32) {
    let (b0, b1) = if u[0] < u[1] {
        let b0 = u[0] / 2.0;
        (b0, u[1] - b0)
    } else {
        let b1 = u[1] / 2.0;
        (u[0] - b1, b1)
    };
    (b1, 1.0 - b0 - b1)
}

/// Power heuristic weight term: `pdf^beta` (beta = 1 is the balance heuristic).
pub fn mis_power(pdf: f32, beta: f32) -> f32 {
    if beta == 2.0 {
        pdf * pdf
    } else if beta == 1.0 {
        pdf
    } else {
        pdf.powf(beta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    /// Mean of cos over the cosine hemisphere is 2/3; over the cos^n lobe (n+1)/(n+2).
    #[test]
    fn lobe_moments() {
        let mut rng = Rng::for_sample(1, 0, 0, Stream::Eye);
        let n = 200_000;
        for exponent in [1.0f32, 10.0, 100.0] {
            let (mut sum, mut sum_cos) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let d = power_cosine(rng.next_2d(), exponent);
                assert!((d.length() - 1.0).abs() < 1e-4);
                sum += d.z as f64;
                sum_cos += (cosine_hemisphere(rng.next_2d()).z) as f64;
            }
            let expected = (exponent + 1.0) as f64 / (exponent + 2.0) as f64;
            // cos is in [0, 1] so its standard deviation is below 0.5: 5 standard errors.
            let tolerance = 5.0 * 0.5 / (n as f64).sqrt();
            assert!((sum / n as f64 - expected).abs() < tolerance);
            assert!((sum_cos / n as f64 - 2.0 / 3.0).abs() < tolerance);
        }
    }

    /// The polynomial sine and cosine against f64's, over every quarter turn and across the
    /// wedges of the disk map.
    #[test]
    fn sin_cos_match_libm_to_a_few_ulps() {
        use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, TAU};
        let n = 1 << 16;
        for k in 0..=n {
            let t = k as f32 / n as f32;
            let (sin, cos) = sin_cos_turn(t);
            let angle = TAU * t as f64;
            assert!((sin as f64 - angle.sin()).abs() < 3e-7, "sin at t = {t}");
            assert!((cos as f64 - angle.cos()).abs() < 3e-7, "cos at t = {t}");
        }
        for k in 0..=256 {
            for l in 0..=256 {
                let u = [k as f32 / 256.0, l as f32 / 256.0];
                let d = concentric_disk(u);
                let (a, b) = (2.0 * u[0] as f64 - 1.0, 2.0 * u[1] as f64 - 1.0);
                let (r, phi) = if a * a > b * b {
                    (a, FRAC_PI_4 * (b / a))
                } else if b != 0.0 {
                    (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
                } else {
                    (0.0, 0.0)
                };
                assert!((d.x as f64 - r * phi.cos()).abs() < 3e-7, "x at {u:?}");
                assert!((d.y as f64 - r * phi.sin()).abs() < 3e-7, "y at {u:?}");
            }
        }
    }

    #[test]
    fn triangle_barycentrics_are_uniform() {
        let mut rng = Rng::for_sample(2, 0, 0, Stream::Eye);
        let n = 200_000;
        let mut mean = [0.0f64; 2];
        for _ in 0..n {
            let (b1, b2) = uniform_triangle(rng.next_2d());
            assert!(b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 + 1e-6);
            mean[0] += b1 as f64;
            mean[1] += b2 as f64;
        }
        // Each barycentric has mean 1/3 and standard deviation sqrt(1/18).
        let tolerance = 5.0 * (1.0f64 / 18.0).sqrt() / (n as f64).sqrt();
        for m in mean {
            assert!((m / n as f64 - 1.0 / 3.0).abs() < tolerance);
        }
    }
}
