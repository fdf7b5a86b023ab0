//! Perfect mirror with reflectance `ks`: a single delta lobe.

use super::{reflect_local, BsdfSample};
use crate::color::Rgb;
use glam::Vec3;

pub(super) fn sample(ks: Rgb, wo: Vec3) -> Option<BsdfSample> {
    let wi = reflect_local(wo);
    // Delta lobe chosen with probability 1: f * |cos| / pdf = ks.
    Some(BsdfSample {
        wi,
        f: ks / wi.z.abs(),
        pdf_w: 1.0,
        rev_pdf_w: 1.0,
        delta: true,
    })
}
