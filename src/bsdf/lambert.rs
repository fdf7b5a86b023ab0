//! Lambertian reflection, f = kd / pi, sampled by the cosine.

use super::{BsdfEval, BsdfSample};
use crate::color::Rgb;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

/// `wo` and `wi` are local, `wo.z > 0`.
pub(super) fn eval(kd: Rgb, wo: Vec3, wi: Vec3) -> BsdfEval {
    if wi.z <= 0.0 {
        return BsdfEval::ZERO;
    }
    BsdfEval {
        f: kd * FRAC_1_PI,
        pdf_w: cosine_hemisphere_pdf(wi.z),
        rev_pdf_w: cosine_hemisphere_pdf(wo.z),
    }
}

pub(super) fn sample(kd: Rgb, wo: Vec3, u: [f32; 2]) -> Option<BsdfSample> {
    let wi = cosine_hemisphere(u);
    let e = eval(kd, wo, wi);
    (e.pdf_w > 0.0).then_some(BsdfSample {
        wi,
        f: e.f,
        pdf_w: e.pdf_w,
        rev_pdf_w: e.rev_pdf_w,
        delta: false,
    })
}
