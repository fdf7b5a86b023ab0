//! Lafortune's energy-conserving Phong (000 eq. 3.1):
//! f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha), alpha the angle between `wi` and the mirror
//! direction of `wo`. Each lobe is importance sampled; the lobe is picked in proportion to its
//! albedo and the pdfs are those of the whole mixture, so MIS sees the real density.

use super::{reflect_local, BsdfEval, BsdfSample};
use crate::color::Rgb;
use crate::frame::Frame;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, power_cosine, power_cosine_pdf};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

pub(super) struct Phong {
    kd: Rgb,
    ks: Rgb,
    pub(super) exponent: f32,
    /// The exponent when it is a whole number (as most scenes' are): `powi`'s few multiplies
    /// then replace `powf`, which the merge loop and every BSDF evaluation would pay.
    whole_exponent: Option<i32>,
    /// Probability of sampling the diffuse lobe.
    pub(super) diffuse_probability: f32,
}

impl Phong {
    pub(super) fn new(kd: Rgb, ks: Rgb, exponent: f32) -> Self {
        let (d, s) = (kd.average(), ks.average());
        let diffuse_probability = if d + s > 0.0 { d / (d + s) } else { 1.0 };
        // Exporters write whole exponents as single-precision decimals (40 as 39.999996):
        // within 1e-5 of a whole number the exponent is that number, a change of the lobe far
        // below any render's noise, so `powi` serves it too. Rounded through i32 (exponents are
        // >= 0; `round` would be a libm call).
        let whole = (exponent + 0.5) as i32;
        let whole_exponent =
            ((whole as f32 - exponent).abs() <= 1e-5 * exponent.max(1.0)).then_some(whole);
        let exponent = whole_exponent.map_or(exponent, |n| n as f32);
        Phong {
            kd,
            ks,
            exponent,
            whole_exponent,
            diffuse_probability,
        }
    }

    /// `wo`, `wi` local, `wo.z > 0`.
    pub(super) fn eval(&self, wo: Vec3, wi: Vec3) -> BsdfEval {
        if wi.z <= 0.0 {
            return BsdfEval::ZERO;
        }
        // cos(alpha) is symmetric in wo and wi, so one value serves both pdfs.
        let cos_alpha = reflect_local(wo).dot(wi).max(0.0);
        let lobe = match self.whole_exponent {
            Some(n) => cos_alpha.powi(n),
            None => cos_alpha.powf(self.exponent),
        };
        let f = self.kd * FRAC_1_PI + self.ks * ((self.exponent + 2.0) * 0.5 * FRAC_1_PI * lobe);
        let specular_pdf = power_cosine_pdf(cos_alpha, lobe, self.exponent);
        let pd = self.diffuse_probability;
        BsdfEval {
            f,
            pdf_w: pd * cosine_hemisphere_pdf(wi.z) + (1.0 - pd) * specular_pdf,
            rev_pdf_w: pd * cosine_hemisphere_pdf(wo.z) + (1.0 - pd) * specular_pdf,
        }
    }

    pub(super) fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let wi = if u[0] < self.diffuse_probability {
            cosine_hemisphere([u[1], u[2]])
        } else {
            Frame::from_z(reflect_local(wo)).to_world(power_cosine([u[1], u[2]], self.exponent))
        };
        let e = self.eval(wo, wi);
        (e.pdf_w > 0.0).then_some(BsdfSample {
            wi,
            f: e.f,
            pdf_w: e.pdf_w,
            rev_pdf_w: e.rev_pdf_w,
            delta: false,
        })
    }
}
