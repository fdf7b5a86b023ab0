//! UPG's merges (000 sec. 2.4.3): instead of a density estimate, the light vertex and the eye
//! vertex within r of each other are joined by an explicit connection from the merge vertex's
//! neighbour on the gathering side (000 eq. 2.67), and the connection's pdf holds 1/p_acc,
//! which tentative rays from that neighbour estimate (`acceptance.rs`, 000 eq. 2.65). The MIS
//! weight is VCM's with the clamped acceptance (000 eqs. 2.80-2.82): the gathering side's
//! quantities are carried across the connection to the merge vertex, and the merge is weighed
//! there like a density-estimate merge with its own eta_j, times 002's density factor rho_j
//! with `--density-mis` ([`VcmWeights::with_density`]).

use super::super::connection::Connection;
use super::super::mis::{Gather, Neighbour, Side, VcmVertex, VcmWeights, VmHere};
use super::super::subpath::{EyeVertex, LightVertex, PendingMis, SubPath};
use super::super::IterationStats;
use super::acceptance::{AngularBound, Estimator, Outcome, StoredVerticesOnly, TentativeTracer};
use super::hybrid::{self, Rule};
use super::{Deferred, UpgCounters};
use crate::accel::Ray;
use crate::bsdf::Bsdf;
use crate::color::Rgb;
use crate::hashgrid::{kept, HashGrid, Within, QUERY_BATCH};
use crate::sampling::{Rng, Stream};
use crate::scene::{Scene, SurfaceHit};
use glam::Vec3;
use std::borrow::Cow;

/// A light vertex, by its index, with its MIS quantities re-run for the weights of the eye
/// sub-path that uses it (per-pixel radii under UPG's clamp or 002's density factors:
/// [`super::super::subpath::LightPaths::reweighed`]).
pub type Reweigh<'i> = dyn Fn(&VcmWeights, usize) -> LightVertex<Deferred> + 'i;

/// 1 / k at a position for merges of the given weights' radius (002 eq. (6)): the density
/// map's lookup, `None` without it.
pub type InvK<'i> = dyn Fn(&VcmWeights, Vec3) -> Option<f32> + 'i;

/// The light vertices of one iteration and the grid over them.
#[derive(Clone, Copy)]
pub struct Gathered<'i> {
    pub vertices: &'i [LightVertex<Deferred>],
    pub grid: &'i HashGrid,
    /// Where the stored MIS quantities are not the eye sub-path's radius's: the vertices
    /// re-run for it.
    pub reweigh: Option<&'i Reweigh<'i>>,
    /// The density map's lookup, for the merge vertex a carried sub-path arrives at.
    pub inv_k: &'i InvK<'i>,
}

impl Gathered<'_> {
    /// Light vertex `index` as weights `w` take it: the stored one where its MIS quantities
    /// are the weights' own.
    fn vertex(&self, w: &VcmWeights, index: usize) -> Cow<'_, LightVertex<Deferred>> {
        match self.reweigh {
            Some(reweigh) => Cow::Owned(reweigh(w, index)),
            None => Cow::Borrowed(&self.vertices[index]),
        }
    }

    /// Gathers the light vertices of a query's `batch` that `gathers` keeps, in order, each by
    /// `gather`. The light vertices `back` steps before each kept one along its sub-path (those
    /// its merge reads whole: its predecessor, itself, or both) are prefetched first: a merge
    /// waits on Embree (its link's shadow ray, its tentative rays), so the misses of the later
    /// merges' vertices, read at random, overlap the earlier merges instead of each being
    /// waited for.
    pub(super) fn gather_batch(
        &self,
        batch: &[u32],
        gathers: impl FnMut(u32) -> bool,
        back: std::ops::RangeInclusive<usize>,
        mut gather: impl FnMut(usize),
    ) {
        let mut found = [0u32; QUERY_BATCH];
        let mut len = 0;
        for i in kept(batch, gathers) {
            for step in back.clone() {
                if let Some(v) = (i as usize).checked_sub(step) {
                    self.vertices[v].prefetch();
                }
            }
            found[len] = i;
            len += 1;
        }
        for &i in &found[..len] {
            gather(i as usize);
        }
    }

    /// Calls `visit` with the indices of the light vertices within `w`'s radius of `q` (the
    /// path's radius, which may not be the grid's), a batch at a time.
    fn query(&self, w: &VcmWeights, q: Vec3, mut visit: impl FnMut(&[u32])) {
        let grid = self.grid;
        grid.query_slot_batches_within(q, Within::radius(w.radius), |slots| {
            let mut indices = [0u32; QUERY_BATCH];
            for (index, &slot) in indices.iter_mut().zip(slots) {
                *index = grid.index_of(slot as usize);
            }
            visit(&indices[..slots.len()]);
        });
    }
}

/// What UPG's merges need of the scene and the options.
pub struct UpgMerges<'s> {
    scene: &'s Scene,
    gather: Gather,
    estimator: Estimator,
    /// Path-length bounds in segments: the shortest path kept, the longest traced.
    min_length: u32,
    max_length: u32,
    /// Path length from which Russian roulette may end paths.
    roulette: u32,
    /// `upg-hybrid`'s rule, which picks each merge's side.
    rule: Option<Rule>,
}

impl<'s> UpgMerges<'s> {
    /// `gather` is [`Gather::UpgLight`], [`Gather::UpgCamera`] or, for `vcm-upg`'s UPG
    /// merges, [`Gather::Blend`].
    pub fn new(
        scene: &'s Scene,
        gather: Gather,
        estimator: Estimator,
        [min_length, max_length]: [u32; 2],
        roulette: u32,
    ) -> Self {
        UpgMerges {
            scene,
            gather,
            estimator,
            min_length,
            max_length,
            roulette,
            rule: None,
        }
    }

    /// `upg-hybrid`'s merges ([`Gather::Hybrid`]), each gathered from the side `rule` picks.
    pub fn with_rule(self, rule: Rule) -> Self {
        UpgMerges {
            rule: Some(rule),
            ..self
        }
    }

    /// `upg`: gathers the light vertices within r of the eye vertex `hit` whose predecessor Q is
    /// a non-delta surface vertex, and for each connects Q to the eye vertex explicitly (000
    /// eq. 2.67), the tentative rays from Q estimating 1/p_acc (000 eq. 2.65). Not yet divided
    /// by the light sub-path count.
    pub fn from_light(
        &self,
        w: &VcmWeights,
        (state, hit, bsdf): (&SubPath<Deferred>, &SurfaceHit, &Bsdf),
        gathered: Gathered,
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) -> Rgb {
        let vertices = gathered.vertices;
        // `upg-hybrid` gathers here only the light vertices whose predecessor is rough.
        let gathers = |i: u32| {
            let i = i as usize;
            vertices[i].after_surface
                && !vertices[i].after_glossy
                && self.keeps(vertices[i - 1].path_length + 1 + state.path_length)
        };
        let mut gather = |i: usize| {
            let q = gathered.vertex(w, i - 1);
            self.through_predecessor(w, (state, hit, bsdf), &q, tentative, stats);
        };
        // The eye sub-path's radius: every technique of the path weighs with it.
        gathered.query(w, hit.position, |batch| {
            gathered.gather_batch(batch, gathers, 1..=1, &mut gather);
        });
        self.estimate_from(Side::Light, tentative, stats)
    }

    /// `upg-camera`: gathers the light vertices within r of `position`, the vertex the eye
    /// sub-path just reached, and connects each to the previous eye vertex `prev` explicitly,
    /// the tentative rays from `prev` estimating 1/p_acc (000 sec. 2.4.3, UPG*). Not yet divided
    /// by the light sub-path count.
    pub fn from_camera(
        &self,
        w: &VcmWeights,
        prev: &EyeVertex<'s, Deferred>,
        position: Vec3,
        gathered: Gathered,
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) -> Rgb {
        let vertices = gathered.vertices;
        // `upg-hybrid` gathers here only the light vertices its rule gathers from this side.
        let gathers = |i: u32| {
            let v = &vertices[i as usize];
            let behind =
                Neighbour::towards_light(v.path_length, v.after_surface).glossy_if(v.after_glossy);
            self.gather.side(behind) == Side::Camera
                && self.keeps(v.path_length + 1 + prev.path_length)
        };
        let mut gather = |i: usize| {
            let photon = &gathered.vertex(w, i);
            let Some(p_bsdf) = photon.bsdf(self.scene) else {
                return;
            };
            let Some(link) = self.link(
                (&prev.bsdf, prev.hit.position, prev.hit.ng),
                (&p_bsdf, photon.position, photon.ng),
                stats,
            ) else {
                return;
            };
            let Ok(bound) = AngularBound::new(
                prev.hit.position,
                prev.hit.ng,
                &prev.bsdf,
                photon.position,
                w.radius,
            ) else {
                return;
            };
            // The eye sub-path's quantities as they would be at the light vertex, whose
            // glossiness decides the side of a merge at the previous eye vertex.
            let photon_side = Neighbour::Surface.glossy_if(hybrid::glossy(self.rule, &p_bsdf));
            let merge_at_prev = self
                .gather
                .merge_at(photon_side, Neighbour::surface_if(prev.prev_surface));
            let mut eye = carry(
                w,
                &link,
                prev.pending.settle(w, prev.mis, link.from_eval.rev_pdf_w),
                (merge_at_prev, prev.density.0),
                self.gather.side(photon_side) == Side::Light,
            );
            // The merge vertex is the light vertex: the eye sub-path arrives there and takes
            // its density factor, as the light sub-path did.
            let density = w.density_at(&mut eye, (gathered.inv_k)(w, photon.position));
            // At the merge vertex the eye side samples towards the light vertex's predecessor:
            // the photon's BSDF pdfs, seen the other way round.
            let weight = w.merge(
                &photon.mis_at(w, link.to_eval.rev_pdf_w),
                &eye,
                (link.to_eval.rev_pdf_w, link.to_eval.pdf_w),
                w.eta(eye.d_vcm),
                density,
            );
            let roulette = self.roulette_probability(&prev.bsdf, prev.path_length);
            tentative.push(
                bound,
                prev.throughput * photon.throughput * link.value * (weight / roulette),
            );
        };
        gathered.query(w, position, |batch| {
            gathered.gather_batch(batch, gathers, 0..=0, &mut gather);
        });
        let before = tentative.counters.merges;
        let sum = self.estimate_from(Side::Camera, tentative, stats);
        tentative.counters.camera_merges += tentative.counters.merges - before;
        sum
    }

    /// The merge of a gathered light vertex through Q = `q`, its predecessor (`upg`, and
    /// `vcm-upg`'s merges made by UPG): Q connected to the eye vertex explicitly (000 eq. 2.67),
    /// weighed on that path, its contribution awaiting 1/p_acc in `tentative`.
    pub(super) fn through_predecessor(
        &self,
        w: &VcmWeights,
        (state, hit, bsdf): (&SubPath<Deferred>, &SurfaceHit, &Bsdf),
        q: &LightVertex<Deferred>,
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) {
        let Some(q_bsdf) = q.bsdf(self.scene) else {
            return;
        };
        let Some(link) = self.link(
            (&q_bsdf, q.position, q.ng),
            (bsdf, hit.position, hit.ng),
            stats,
        ) else {
            return;
        };
        // Only light vertices reached through Q's non-delta lobes are gathered (`gathers`:
        // `after_surface`), so the tentative rays stand for those lobes alone.
        let Ok(bound) = AngularBound::new(q.position, q.ng, &q_bsdf, hit.position, w.radius)
            .map(AngularBound::without_delta)
        else {
            return;
        };
        // The light sub-path's quantities as they would be at the eye vertex; Q's own
        // neighbour towards the light decides whether merging at Q is a technique.
        let behind_q =
            Neighbour::towards_light(q.path_length, q.after_surface).glossy_if(q.after_glossy);
        let merge_at_q = self.gather.merge_at(behind_q, Neighbour::Surface);
        // The merge vertex is the eye vertex, whose density factor the eye sub-path holds.
        let mut light = carry(
            w,
            &link,
            q.mis_at(w, link.from_eval.rev_pdf_w),
            (merge_at_q, q.rho),
            self.gather.side(behind_q) == Side::Camera,
        );
        w.visit(&mut light, state.density.1);
        let weight = w.merge(
            &light,
            &state.mis_at(w, link.to_eval.rev_pdf_w),
            (link.to_eval.pdf_w, link.to_eval.rev_pdf_w),
            w.eta(light.d_vcm),
            state.density,
        );
        let roulette = self.roulette_probability(&q_bsdf, q.path_length);
        tentative.push(bound, q.throughput * link.value * (weight / roulette));
    }

    /// Whether a merged path of `segments` lies within the path-length bounds.
    pub(super) fn keeps(&self, segments: u32) -> bool {
        (self.min_length..=self.max_length).contains(&segments)
    }

    /// The probability that Russian roulette let a sub-path go on from a vertex.
    fn roulette_probability(&self, bsdf: &Bsdf, path_length: u32) -> f32 {
        if path_length >= self.roulette {
            bsdf.continuation_probability()
        } else {
            1.0
        }
    }

    /// The explicit connection of a UPG merge between two vertices (BSDF, position, geometric
    /// normal): both BSDFs, the geometry term and the visibility (000 eq. 2.67).
    fn link(
        &self,
        (from, from_position, from_ng): (&Bsdf, Vec3, Vec3),
        (to, to_position, to_ng): (&Bsdf, Vec3, Vec3),
        stats: &mut IterationStats,
    ) -> Option<Connection> {
        Connection::new(from, from_position, to, to_position).filter(|_| {
            stats.rays += 1;
            !self.scene.occluded(&Ray::spawn_between(
                from_position,
                from_ng,
                to_position,
                to_ng,
            ))
        })
    }

    /// Estimates 1/p_acc for the merges of one gather, together so that packets can take lanes
    /// from all of them, and returns the sum of their contributions.
    pub(super) fn estimate(&self, tentative: &mut Tentative, stats: &mut IterationStats) -> Rgb {
        let side = match self.gather {
            Gather::UpgCamera => Side::Camera,
            _ => Side::Light,
        };
        self.estimate_from(side, tentative, stats)
    }

    /// [`Self::estimate`] for merges gathered from `side`.
    fn estimate_from(
        &self,
        side: Side,
        tentative: &mut Tentative,
        stats: &mut IterationStats,
    ) -> Rgb {
        // The light side gathers light vertices, which lie on non-delta surfaces only; the
        // camera side gathers at wherever the eye sub-path lands.
        match side {
            Side::Light => {
                tentative.estimate(&self.estimator, &StoredVerticesOnly(self.scene), stats)
            }
            Side::Camera => tentative.estimate(&self.estimator, self.scene, stats),
        }
    }
}

/// The MIS quantities of the sub-path that ends at the first vertex of `c` (`at_from`),
/// carried across it to the second (001 eqs. (34)-(36)); a merge at the first vertex is a
/// technique or not as `merge_at_from` says, with density factor `rho` (002 eq. (6)). Its eta
/// takes the carried sub-path's own pdf of the first vertex (its d^VCM), or where the other
/// side gathers it (`by_other_side`, `upg-hybrid`), the second vertex's across `c` (000 eq.
/// 2.81).
fn carry(
    w: &VcmWeights,
    c: &Connection,
    at_from: VcmVertex,
    (merge_at_from, rho): (VmHere, f32),
    by_other_side: bool,
) -> VcmVertex {
    let mut v = at_from;
    let valid = merge_at_from == VmHere::Valid;
    let ratio = w.scatter(
        &mut v,
        c.cos_from,
        c.from_eval.pdf_w,
        c.from_eval.rev_pdf_w,
        false,
        (valid && !by_other_side, rho),
    );
    if valid && by_other_side {
        v = w.settle_merge(v, ratio * rho, w.mis(1.0 / c.from_pdf_a()));
    }
    w.arrive(&mut v, c.distance, c.cos_to, true);
    v
}

/// The UPG merges of one eye sub-path awaiting their 1/p_acc: each merge's bound, its own
/// random stream (so an estimate does not depend on how many numbers the packets before it
/// drew) and its contribution without the 1/p_acc factor. Reused from gather to gather; it
/// counts the merges' work until [`Tentative::take_counters`].
pub struct Tentative<'s> {
    seed: u64,
    iteration: u64,
    base: u64,
    merges: u64,
    bounds: Vec<AngularBound<'s>>,
    rngs: Vec<Rng>,
    values: Vec<Rgb>,
    counters: UpgCounters,
}

impl<'s> Tentative<'s> {
    /// Empty lists for the eye sub-paths of `iteration`; [`Tentative::start_pixel`] names each.
    pub fn new(seed: u64, iteration: u64) -> Self {
        Tentative {
            seed,
            iteration,
            base: 0,
            merges: 0,
            bounds: Vec::new(),
            rngs: Vec::new(),
            values: Vec::new(),
            counters: UpgCounters::default(),
        }
    }

    /// Starts the merges of `pixel`'s eye sub-path, keeping the lists' storage: one parallel
    /// task of the eye pass reuses it for all its pixels instead of allocating per pixel.
    pub fn start_pixel(&mut self, pixel: usize) {
        self.base = (pixel as u64) << 24;
        self.merges = 0;
        self.bounds.clear();
        self.rngs.clear();
        self.values.clear();
    }

    pub(super) fn push(&mut self, bound: AngularBound<'s>, value: Rgb) {
        self.merges += 1;
        self.rngs.push(Rng::for_sample(
            self.seed,
            self.iteration,
            self.base + self.merges,
            Stream::Tentative,
        ));
        self.bounds.push(bound);
        self.values.push(value);
    }

    /// A random stream of the current pixel's eye vertex `vertex` (its path length) for
    /// `purpose`, apart from the merges' own.
    pub(super) fn stream(&self, vertex: u32, purpose: Stream) -> Rng {
        Rng::for_sample(
            self.seed,
            self.iteration,
            self.base + u64::from(vertex),
            purpose,
        )
    }

    /// Counts a merge made by density estimate instead (`vcm-upg`).
    pub(super) fn count_density_merge(&mut self) {
        self.counters.density_merges += 1;
    }

    /// The work counted since the last call: merges estimated, their trials and tentative rays.
    pub fn take_counters(&mut self) -> UpgCounters {
        std::mem::take(&mut self.counters)
    }

    /// Estimates every pending merge, empties the list and returns the merges' sum. A capped
    /// estimate drops its merge and is counted as capped; an unreachable target drops its merge
    /// too.
    fn estimate<T: TentativeTracer + ?Sized>(
        &mut self,
        estimator: &Estimator,
        tracer: &T,
        stats: &mut IterationStats,
    ) -> Rgb {
        let values = &mut self.values;
        let counters = &mut self.counters;
        estimator.estimate_all(tracer, &self.bounds, &mut self.rngs, |i, estimate| {
            counters.merges += 1;
            counters.trials += estimate.trials as u64;
            counters.tentative_rays += estimate.rays as u64;
            counters.packet_rays += estimate.packed as u64;
            stats.rays += estimate.rays as u64;
            values[i] = match estimate.outcome {
                Outcome::Estimate(inv_p_acc) => values[i] * inv_p_acc,
                Outcome::Capped => {
                    counters.capped += 1;
                    Rgb::BLACK
                }
                Outcome::Unreachable => Rgb::BLACK,
            };
        });
        // Summed in gathering order: packets finish merges in another order than single rays,
        // and the image must not depend on it.
        let sum = values.iter().fold(Rgb::BLACK, |sum, &v| sum + v);
        self.bounds.clear();
        self.rngs.clear();
        self.values.clear();
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::super::Deferred;
    use super::LightVertex;
    use std::collections::BTreeSet;
    use std::mem::{offset_of, size_of};

    /// The fields [`LightVertex::prefetch`] goes through name every cache line of a vertex the
    /// gathers read, at each alignment it can have (a multiple of 4 bytes): a field moved or
    /// added, making a gap of more than a line between them, fails here.
    #[test]
    fn every_line_of_a_light_vertex_is_prefetched() {
        type V = LightVertex<Deferred>;
        let size = size_of::<V>();
        let probes = [
            offset_of!(V, uv),
            offset_of!(V, ns),
            offset_of!(V, after_glossy),
        ];
        for start in (0..64).step_by(4) {
            let named: BTreeSet<usize> = probes.iter().map(|p| (start + p) / 64).collect();
            let spanned: BTreeSet<usize> = (start / 64..=(start + size - 1) / 64).collect();
            assert_eq!(
                named, spanned,
                "vertex of {size} bytes at {start}: {probes:?}"
            );
        }
    }
}
