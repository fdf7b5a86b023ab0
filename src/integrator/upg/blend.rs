//! `vcm-upg`: VCM whose merges are made by unbiased photon gathering where VCM's density
//! estimate is wrong, the corners and edges of a scene, and by the density estimate elsewhere
//! (000 sec. 5.2: "the decision could be made on the length of the tentative ray").
//!
//! **The choice.** A merge of the light vertex y_i at the eye vertex x is made, at random, by
//! VCM's density estimate (1/p_acc taken as 1/(pi r^2 p(y_i)), the merge's path pdf of 001
//! eq. (10)) with probability b, and with probability 1 - b by UPG's: the light vertex's
//! predecessor y_{i-1} connected to x explicitly (000 eq. 2.67), tentative rays from y_{i-1}
//! estimating 1/p_acc without bias (000 eqs. 2.61-2.66), as `upg` does
//! ([`super::merge::UpgMerges::from_light`]). The density estimate assumes the light vertices'
//! density constant over a flat disc of radius r around x; seen from y_{i-1} it varies as
//! cos / d^2, by a relative O(r / d) across the disc, and in a corner y_{i-1} lies on the other
//! face within a few r of x. So b = b(d / r), d the length of the tentative ray |y_{i-1} - x|:
//! a smoothstep from 0 at `blend_near` radii to 1 at `blend_far`, UPG below, VCM above, no step
//! for a seam to show. Where y_{i-1} is a delta vertex no tentative ray can leave from it: b = 1.
//!
//! d is measured to x, not to y_i, because y_{i-1} and x are the vertices of the path UPG
//! samples: its share (1 - b) f w / p, with 1/p_acc estimated without bias, is then an unbiased
//! estimate of the integral of (1 - b) w f. Measured to y_i, the factor would depend on where
//! the photon that triggered the merge landed in the sphere, and UPG's share would weigh each
//! path by an average of (1 - b) over the sphere instead. The two differ by at most r.
//!
//! **The estimate.** Per merge, E = b E[VCM] + (1 - b) E[UPG]: the integral of w f plus VCM's
//! bias scaled by b, none where b = 0. As the radius shrinks (000 eq. 2.85) b(d / r) -> 1 for
//! every d > 0 and VCM's own bias vanishes, so the technique is consistent as VCM is. Only the
//! merges chosen for UPG trace tentative rays; their share is in the statistics.
//!
//! **The techniques.** A merge at the vertex next to the light point (y_1, whose predecessor
//! is the light) is no technique ([`Gather::Blend`]): no tentative ray leaves a light point, so
//! only a density estimate could make it, and at a large radius these merges carry most of
//! VCM's bias in corners (direct light merged across a shadow's edge or from the other face).
//! Light sampling makes every path they would, so nothing is lost; merges after a delta vertex
//! (SDS caustics) stay techniques, made by density estimate. On `corners` at a fixed radius of
//! 0.15 (24x24, floor camera, 1024 iterations) the squared bias over the image falls from
//! vcm's 1.16 to 0.062 by this rule alone, and the ramp takes it on to 0.033 (2 to 6 radii),
//! 0.014 (4 to 12, the defaults) and 0.003 (8 to 24), at 1.7, 2.5 and 3.1 times vcm's time;
//! every gatherable merge made by UPG gives 0 within noise (docs/techniques.md).
//!
//! **The weights.** VCM's, unclamped (001 eqs. (38)-(39), eta_VCM of 001 eq. (20)), on the
//! path each estimate samples: the density estimate on the light sub-path through y_i, UPG on
//! the path through y_{i-1} and x, its light-side quantities carried across the explicit
//! connection (001 eqs. (34)-(36)) as `upg` carries them. MIS needs the weights of every
//! technique that can sample a path to sum to one on it (001 eq. (12)); they depend on the path
//! and on which merges are techniques, not on how a merge estimates its 1/p_acc, so each merge's
//! estimate, whichever it is, estimates the same weighted contribution (tests/mis_weights.rs
//! checks the sums). An eye sub-path learns whether the merge at its vertex is a technique only
//! at the next vertex (a light point or not), so that term is deferred as `upg` defers its own
//! ([`super::Deferred`]); its eta is eta_VCM, needing no pdf, so it settles at a delta vertex
//! too. UPG's clamp (000 eqs. 2.80-2.82) is left out: it is another set of weights, which the
//! density-estimate merges would have to share.

use super::super::mis::{Gather, Neighbour, VcmWeights, VmHere};
use super::super::subpath::SubPath;
use super::super::IterationStats;
use super::acceptance::Estimator;
use super::merge::{Gathered, Tentative, UpgMerges};
use super::{Deferred, UpgCounters};
use crate::bsdf::Bsdf;
use crate::color::Rgb;
use crate::sampling::Stream;
use crate::scene::{Scene, SurfaceHit};

/// The ramp b(d / r) from UPG to VCM, in radii.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ramp {
    /// Up to this length every merge is UPG's.
    pub near: f32,
    /// From this length every merge is VCM's; above `near`.
    pub far: f32,
}

impl Ramp {
    /// b: the probability that a merge whose tentative ray is `length` radii long is made by
    /// density estimate. A smoothstep, so its slope is continuous at both ends too.
    pub fn vcm_probability(&self, length: f32) -> f32 {
        let t = ((length - self.near) / (self.far - self.near)).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }
}

/// `vcm-upg`'s merges.
pub struct Blend<'s> {
    upg: UpgMerges<'s>,
    ramp: Ramp,
}

impl<'s> Blend<'s> {
    /// `bounds`: the shortest path kept and the longest traced, in segments; `roulette`: the
    /// path length from which Russian roulette may end paths.
    pub fn new(
        scene: &'s Scene,
        estimator: Estimator,
        bounds: [u32; 2],
        roulette: u32,
        ramp: Ramp,
    ) -> Self {
        Blend {
            upg: UpgMerges::new(scene, Gather::Blend, estimator, bounds, roulette),
            ramp,
        }
    }

    /// Merges the eye vertex `hit` with the light vertices within the radius, each by density
    /// estimate or by UPG as [`Ramp`] draws, normalised (1 / (pi r^2 n_VM) and 1 / n_VM).
    pub fn merge(
        &self,
        w: &VcmWeights,
        (state, hit, bsdf): (&SubPath<Deferred>, &SurfaceHit, &Bsdf),
        gathered: Gathered,
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) -> Rgb {
        let vertices = gathered.vertices;
        let mut choice = tentative.stream(state.path_length, Stream::Blend);
        let mut density = Rgb::BLACK;
        let within = |i: u32| {
            self.upg
                .keeps(vertices[i as usize].path_length + state.path_length)
        };
        // A merge reads the light vertex whole (a density estimate) or its predecessor (UPG),
        // which lies just before it: both are prefetched.
        let mut merge = |i: usize| {
            let lv = &vertices[i];
            let behind = Neighbour::towards_light(lv.path_length, lv.after_surface);
            if Gather::Blend.merge_at(behind, Neighbour::Surface) != VmHere::Valid {
                return;
            }
            // Stored just before: the predecessor the tentative rays would leave from.
            let q = lv.after_surface.then(|| &vertices[i - 1]);
            let b = q.map_or(1.0, |q| {
                self.ramp
                    .vcm_probability(q.position.distance(hit.position) / w.radius)
            });
            match q {
                Some(q) if b < 1.0 && (b <= 0.0 || choice.next_f32() >= b) => {
                    self.upg
                        .through_predecessor(w, (state, hit, bsdf), q, tentative, stats);
                }
                _ => {
                    let eval = bsdf.eval(lv.wo);
                    if eval.f.is_black() {
                        return;
                    }
                    tentative.count_density_merge();
                    // 001 eqs. (38)-(39), as vcm.rs's density-estimate merge weighs.
                    let weight = w.merge(
                        &lv.mis,
                        &state.mis_at(w, eval.rev_pdf_w),
                        (eval.pdf_w, eval.rev_pdf_w),
                        w.vm_factor,
                        state.density,
                    );
                    density += eval.f * lv.throughput * weight;
                }
            }
        };
        gathered.grid.query_batches(hit.position, |batch| {
            gathered.gather_batch(batch, within, 0..=1, &mut merge);
        });
        density * w.vm_normalization + self.upg.estimate(tentative, stats) * (1.0 / w.light_paths)
    }

    /// Metadata entries: UPG's (000 Table 3.2) and the share of merges UPG made.
    pub fn statistics(&self, counters: &UpgCounters) -> Vec<(String, String)> {
        let all = counters.merges + counters.density_merges;
        let mut stats = counters.statistics();
        stats.push((
            "blend_upg_merge_share".into(),
            format!("{:.4}", counters.merges as f64 / all.max(1) as f64),
        ));
        stats.push((
            "blend_density_merges".into(),
            counters.density_merges.to_string(),
        ));
        stats.push((
            "blend_ramp_radii".into(),
            format!("{} to {}", self.ramp.near, self.ramp.far),
        ));
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_smoothly_from_upg_to_vcm() {
        let ramp = Ramp {
            near: 2.0,
            far: 6.0,
        };
        assert_eq!(ramp.vcm_probability(0.0), 0.0);
        assert_eq!(ramp.vcm_probability(2.0), 0.0);
        assert_eq!(ramp.vcm_probability(4.0), 0.5);
        assert_eq!(ramp.vcm_probability(6.0), 1.0);
        assert_eq!(ramp.vcm_probability(1e6), 1.0);
        // Monotone, and no step anywhere: neighbouring lengths differ by little.
        let mut last = 0.0;
        for k in 0..=800 {
            let b = ramp.vcm_probability(k as f32 * 0.01);
            assert!(
                b >= last && b - last < 0.01,
                "at {}: {last} -> {b}",
                k as f32 * 0.01
            );
            last = b;
        }
    }
}
