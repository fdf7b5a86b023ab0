//! Fresnel reflectance of dielectric and conducting interfaces, and refraction (pbrt-v4's
//! `FrDielectric`, `FrComplex` and `Refract`).

use crate::color::Rgb;
use glam::Vec3;

/// Unpolarised Fresnel reflectance for light arriving at `cos_theta_i` (to the normal; negative
/// from inside) on an interface of relative index `eta` = n_inside / n_outside. Total internal
/// reflection gives 1.
pub fn dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_theta_i < 0.0 {
        (-cos_theta_i, 1.0 / eta)
    } else {
        (cos_theta_i, eta)
    };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// Unpolarised Fresnel reflectance of a conductor with complex index `eta + i k` per channel
/// (relative to the outside medium), for light arriving at `cos_theta_i` (clamped to [0, 1]).
pub fn complex(cos_theta_i: f32, eta: Rgb, k: Rgb) -> Rgb {
    let c = cos_theta_i.clamp(0.0, 1.0);
    Rgb::new(
        complex_channel(c, Complex::new(eta.r, k.r)),
        complex_channel(c, Complex::new(eta.g, k.g)),
        complex_channel(c, Complex::new(eta.b, k.b)),
    )
}

/// Refraction of `wi` (unit, pointing away from the surface) through the interface with unit
/// normal `n` and relative index `eta` = n on the side `n` points away from over n on its
/// side. From the other side (`wi . n < 0`) the index is inverted. Returns the transmitted
/// direction (unit) and the relative index n_t / n_i actually used, or `None` under total
/// internal reflection.
pub fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(wi);
    let (eta, n) = if cos_i < 0.0 {
        cos_i = -cos_i;
        (1.0 / eta, -n)
    } else {
        (eta, n)
    };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let wt = -wi / eta + n * (cos_i / eta - cos_t);
    Some((wt.normalize(), eta))
}

/// The direction under a flat interface of relative index `eta` (inside over outside) that
/// refracts into the outside direction `w` (upper hemisphere): a layer's inside direction.
pub fn into_layer(w: Vec3, eta: f32) -> Vec3 {
    let sin2 = (1.0 - w.z * w.z).max(0.0) / (eta * eta);
    Vec3::new(w.x / eta, w.y / eta, (1.0 - sin2).max(0.0).sqrt())
}

/// The outside direction an inside one `w` (going up) refracts into across a flat interface of
/// relative index `eta`; `None` under total internal reflection.
pub fn out_of_layer(w: Vec3, eta: f32) -> Option<Vec3> {
    let sin2 = (1.0 - w.z * w.z).max(0.0) * eta * eta;
    (sin2 < 1.0).then(|| Vec3::new(w.x * eta, w.y * eta, (1.0 - sin2).sqrt()))
}

/// The few complex operations the conductor's Fresnel equations need, in f64: its
/// cancellations (cos_t of a metal) lose f32's digits.
#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn new(re: f32, im: f32) -> Self {
        Complex {
            re: re as f64,
            im: im as f64,
        }
    }

    fn real(re: f64) -> Self {
        Complex { re, im: 0.0 }
    }

    fn add(self, o: Complex) -> Complex {
        Complex {
            re: self.re + o.re,
            im: self.im + o.im,
        }
    }

    fn sub(self, o: Complex) -> Complex {
        Complex {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }

    fn mul(self, o: Complex) -> Complex {
        Complex {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }

    fn norm(self) -> f64 {
        self.re * self.re + self.im * self.im
    }

    fn div(self, o: Complex) -> Complex {
        let d = o.norm();
        Complex {
            re: (self.re * o.re + self.im * o.im) / d,
            im: (self.im * o.re - self.re * o.im) / d,
        }
    }

    /// The principal square root (non-negative real part).
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex::real(0.0);
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex { re: t1, im: t2 }
        } else {
            Complex {
                re: t2.abs(),
                im: t1.copysign(self.im),
            }
        }
    }
}

fn complex_channel(cos_i: f32, eta: Complex) -> f32 {
    let cos_i = Complex::real(cos_i as f64);
    let sin2_i = Complex::real(1.0).sub(cos_i.mul(cos_i));
    let sin2_t = sin2_i.div(eta.mul(eta));
    let cos_t = Complex::real(1.0).sub(sin2_t).sqrt();
    let parallel = eta.mul(cos_i).sub(cos_t).div(eta.mul(cos_i).add(cos_t));
    let perpendicular = cos_i.sub(eta.mul(cos_t)).div(cos_i.add(eta.mul(cos_t)));
    (0.5 * (parallel.norm() + perpendicular.norm())) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_at_normal_incidence_and_beyond_the_critical_angle() {
        let r0 = ((1.5f32 - 1.0) / (1.5 + 1.0)).powi(2);
        assert!((dielectric(1.0, 1.5) - r0).abs() < 1e-6);
        assert!((dielectric(-1.0, 1.5) - r0).abs() < 1e-6);
        // From inside glass, beyond asin(1 / 1.5): total internal reflection.
        assert_eq!(dielectric(-0.5, 1.5), 1.0);
        assert!(dielectric(0.0, 1.5) > 0.999);
        assert_eq!(dielectric(0.7, 1.0), 0.0);
    }

    #[test]
    fn a_conductor_without_absorption_is_a_dielectric() {
        for cos in [1.0, 0.8, 0.3, 0.05] {
            let c = complex(cos, Rgb::splat(1.5), Rgb::BLACK);
            let d = dielectric(cos, 1.5);
            assert!((c.g - d).abs() < 1e-5, "{cos}: {} vs {d}", c.g);
        }
    }

    #[test]
    fn a_conductor_at_normal_incidence() {
        // ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2), gold's red channel.
        let (n, k) = (0.143f32, 3.983f32);
        let expected = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        let r = complex(1.0, Rgb::splat(n), Rgb::splat(k));
        assert!((r.r - expected).abs() < 1e-5, "{} vs {expected}", r.r);
        assert!((complex(0.0, Rgb::splat(n), Rgb::splat(k)).b - 1.0).abs() < 1e-5);
    }

    #[test]
    fn refraction_obeys_snell_and_inverts() {
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let (wt, eta) = refract(wi, Vec3::Z, 1.5).unwrap();
        assert_eq!(eta, 1.5);
        assert!(wt.z < 0.0);
        // sin_t = sin_i / eta.
        assert!((wt.x.abs() - 0.6 / 1.5).abs() < 1e-6);
        let (back, eta_back) = refract(wt, Vec3::Z, 1.5).unwrap();
        assert!((eta_back - 1.0 / 1.5).abs() < 1e-6);
        assert!((back - wi).length() < 1e-5);
        assert!(refract(Vec3::new(0.9, 0.0, -0.1).normalize(), Vec3::Z, 1.5).is_none());
    }
}
