//! How bpt's and vcm's sub-paths go on from a vertex: a BSDF sample, then Russian roulette on
//! the BSDF's albedo (`RenderOptions::roulette`).

use crate::bsdf::{Bsdf, BsdfSample};
use crate::sampling::Sampler;

/// The BSDF sample that continues a sub-path from its vertex at path length `length`, and the
/// probability with which Russian roulette (from length `roulette` on) let it go on, which its
/// throughput is divided by (1 before `roulette`); `None` where the sub-path ends.
#[inline]
pub fn continue_sub_path(
    bsdf: &Bsdf,
    sampler: &mut Sampler,
    length: u32,
    roulette: u32,
) -> Option<(BsdfSample, f32)> {
    let roulette = length >= roulette;
    let (u, u_roulette) = sampler.next_scatter(roulette);
    let sample = bsdf.sample(u)?;
    if !roulette {
        return Some((sample, 1.0));
    }
    let q = bsdf.continuation_probability();
    (u_roulette < q).then_some((sample, q))
}
