//! One-stage vertex merging in bounded memory (001 sec. 6.2), `memory = one-stage`.
//!
//! Per pixel the light sub-path is traced, its vertices stored as a merge reads them (position,
//! incoming direction, throughput, path length, MIS quantities: no BSDF data), and the eye
//! sub-path traced; it connects to that light sub-path, the only one kept whole, and merges
//! with the vertices the *previous* iteration stored. At the iteration's end the previous
//! vertices are freed and the grid is built over this iteration's. So the light vertices are
//! held once as a merge reads them, twice at the peak (the previous iteration's and this one's),
//! and never with what their BSDFs need: a fraction of the two-stage layout's memory.
//!
//! The estimator is two-stage's in expectation, iteration by iteration: iteration i merges with
//! light sub-paths independent of its eye sub-paths and distributed as its own, so only the
//! weights and the normalisation need care.
//! - Iteration i's weights use radius r_i for every technique of a full path (001 sec. 6.1's
//!   rule). The stored vertices were traced with r_{i-1}: a light sub-path's d^VC carries
//!   eta_VCM linearly in its merge terms (001 eq. (35)), so the sub-paths are traced with those
//!   terms kept apart (the split VCM* keeps, [`VcmWeights::with_density`]; without a density
//!   map its weights are VCM's) and the stored vertices' merge terms are rescaled to r_i when
//!   the grid is built. d^VCM does not depend on the radius; without connections (`bpm`,
//!   `ppm`) nothing stored does.
//! - The first iteration merges with a set of light sub-paths traced for it alone, from a
//!   stream no iteration uses (001's first option; its second, no merges in the first
//!   iteration and twice the merges in the second, is exact only for a fixed radius and an
//!   even number of iterations), so even a one-iteration render has every technique. A
//!   continued render retraces its previous iteration's light sub-paths the same way (they
//!   depend only on the seed), so it is the render that was not interrupted.
//!
//! The image does not depend on the threads: pixels are traced in fixed tasks, the tasks'
//! camera splats are added in task order after each wave of tasks, the stored vertices are
//! concatenated in pixel order, and the previous grid is only read during an iteration.
//!
//! Why a choice and not automatic: the two layouts give different (equally distributed)
//! images from one seed, and a render must give the same image on every machine, so the
//! layout cannot follow the memory a machine has; a two-stage render that does not fit is
//! refused with the advice to render one-stage when that would fit (`memory.rs`).

use super::{EyePass, LightChunk, LightPaths, LightVertex, VertexCm, EYE_TASK};
use crate::color::Rgb;
use crate::film::{add_sample, add_splats};
use crate::hashgrid::HashGrid;
use crate::integrator::mis::{VcmVertex, VcmWeights};
use crate::integrator::subpath::MergeVertex;
use crate::integrator::upg::merge::Tentative;
use crate::integrator::IterationStats;
use crate::options::DensityMis;
use glam::Vec3;
use rayon::prelude::*;

/// Pixels per wave: each wave's camera splats are added before the next starts, so they never
/// take memory in proportion to the image.
const WAVE: usize = 1 << 16;

/// The light sub-paths the first iteration merges with: an iteration index no render reaches
/// (renders end below `options::MAX_ITERATIONS`), so their numbers are nobody else's.
const FIRST_MERGES: u64 = u64::MAX;

/// The light vertices one-stage vertex merging keeps.
#[derive(Default)]
pub(super) struct OneStage {
    /// The previous iteration's vertices as a merge reads them, in `grid`'s order, weighed for
    /// the iteration `serves`.
    merge_vertices: Vec<MergeVertex>,
    grid: HashGrid,
    serves: Option<u64>,
    /// This iteration's vertices, in pixel order, and their positions.
    stored: Vec<Stored>,
    positions: Vec<Vec3>,
    /// The most light vertices held at once and the bytes of their buffers (the grid's own
    /// left out), over the iterations so far.
    pub(super) peak_vertices: usize,
    pub(super) peak_bytes: usize,
}

/// A light vertex as this iteration stores it for the next one's merges: what a merge reads
/// ([`MergeVertex`]) without VCM*'s counts, which take no part here.
#[derive(Clone, Copy)]
struct Stored {
    wo: Vec3,
    throughput: Rgb,
    path_length: u32,
    d_vcm: f32,
    d_vc: f32,
    d_vm: f32,
    d_vc_vm: f32,
}

impl Stored {
    fn new(v: &LightVertex) -> Self {
        Stored {
            wo: v.wo,
            throughput: v.throughput,
            path_length: v.path_length,
            d_vcm: v.mis.d_vcm,
            d_vc: v.mis.d_vc,
            d_vm: v.mis.d_vm,
            d_vc_vm: v.mis.d_vc_vm,
        }
    }

    /// The vertex, stored with weights `from`, as a merge with weights `to` reads it: d^VC's
    /// merge terms scale with mis(eta_VCM) (001 eq. (35)), and d^VM = d^VC / eta_VCM
    /// (001 eqs. (33), (36)).
    fn weighed(self, from: &VcmWeights, to: &VcmWeights) -> MergeVertex {
        let mut mis = VcmVertex {
            d_vcm: self.d_vcm,
            d_vc: self.d_vc,
            d_vm: self.d_vm,
            d_vc_vm: self.d_vc_vm,
            ..VcmVertex::default()
        };
        if from.vm_factor > 0.0 && to.vm_factor > 0.0 {
            mis.d_vc_vm *= to.vm_factor / from.vm_factor;
            mis.d_vm = (mis.d_vc + mis.d_vc_vm) * to.vc_factor;
        }
        MergeVertex {
            wo: self.wo,
            throughput: self.throughput,
            path_length: self.path_length,
            mis,
        }
    }
}

/// Bytes of a light vertex stored for the next iteration: what a merge reads and the position.
pub const STORED_BYTES: usize = std::mem::size_of::<Stored>() + std::mem::size_of::<Vec3>();

/// What one task of a wave produces.
#[derive(Default)]
struct Task {
    chunk: LightChunk,
    positions: Vec<Vec3>,
    stored: Vec<Stored>,
    stats: IterationStats,
}

impl Task {
    /// Keeps the vertices of the light sub-path just traced into `chunk` for the next
    /// iteration's merges.
    fn store_path(&mut self) {
        let path = &self.chunk.vertices;
        self.positions.extend(path.iter().map(|v| v.position));
        self.stored.extend(path.iter().map(Stored::new));
    }
}

/// The weights of `iteration`, with d^VC's merge terms kept apart where merges compete with
/// connections (see the module's doc).
fn weights(vcm: &VertexCm, iteration: u64) -> VcmWeights {
    let w = vcm.weights(iteration);
    if vcm.modes.vc && vcm.modes.vm {
        w.with_density(DensityMis::Star)
    } else {
        w
    }
}

impl OneStage {
    /// Light vertices stored by the last iteration.
    pub(super) fn stored_vertices(&self) -> usize {
        self.merge_vertices.len()
    }

    /// Renders iteration `iteration` into `frame`.
    pub(super) fn render_iteration(
        &mut self,
        vcm: &VertexCm,
        iteration: u64,
        frame: &mut [Rgb],
    ) -> IterationStats {
        let mut stats = IterationStats::default();
        let merges = vcm.modes.vm;
        if merges && self.serves != Some(iteration) {
            let source = iteration.checked_sub(1).unwrap_or(FIRST_MERGES);
            stats = stats + self.trace_only(vcm, source, iteration, frame.len());
        }
        let w = weights(vcm, iteration);
        self.reserve(self.merge_vertices.len());
        let seed = vcm.ctx.options.seed;
        let ready = merges && self.serves == Some(iteration);
        let OneStage {
            merge_vertices,
            grid,
            stored,
            positions,
            ..
        } = &mut *self;
        let (merge_vertices, pass_grid) = (&*merge_vertices, ready.then_some(&*grid));
        for first in (0..frame.len()).step_by(WAVE) {
            let end = (first + WAVE).min(frame.len());
            let mut tasks: Vec<Task> = frame[first..end]
                .par_chunks_mut(EYE_TASK)
                .enumerate()
                .map(|(t, pixels)| {
                    let mut task = Task::default();
                    let mut tentative = Tentative::new(seed, iteration);
                    let mut light = LightPaths::default();
                    for (k, value) in pixels.iter_mut().enumerate() {
                        let pixel = first + t * EYE_TASK + k;
                        task.chunk.vertices.clear();
                        vcm.trace_light_path(&w, iteration, pixel, &mut task.chunk);
                        if merges {
                            task.store_path();
                        }
                        light.hold_one(&task.chunk.vertices);
                        let pass = EyePass {
                            w,
                            iteration,
                            light: &light,
                            grid: pass_grid,
                            merge_vertices,
                        };
                        let mut s = IterationStats::default();
                        let color = vcm.trace_eye_path(&pass, pixel, &mut tentative, &mut s);
                        add_sample(value, color, &mut s.dropped_samples);
                        task.stats = task.stats + s;
                    }
                    task
                })
                .collect();
            stats.dropped_samples += add_splats(frame, &mut tasks, |task| &mut task.chunk.splats);
            keep(tasks, (positions, stored), [end, frame.len()], &mut stats);
        }
        self.measure();
        if merges {
            self.build(&w, &weights(vcm, iteration + 1), iteration + 1);
        }
        stats
    }

    /// Traces the light sub-paths of `source` for the merges of iteration `serves` alone:
    /// their camera splats and connections belong to no image.
    fn trace_only(
        &mut self,
        vcm: &VertexCm,
        source: u64,
        serves: u64,
        paths: usize,
    ) -> IterationStats {
        self.merge_vertices = Vec::new();
        self.reserve(0);
        let w = weights(vcm, source.min(serves));
        let mut stats = IterationStats::default();
        for first in (0..paths).step_by(WAVE) {
            let end = (first + WAVE).min(paths);
            let tasks: Vec<Task> = (first..end)
                .into_par_iter()
                .step_by(EYE_TASK)
                .map(|start| {
                    let mut task = Task::default();
                    for pixel in start..(start + EYE_TASK).min(end) {
                        task.chunk.vertices.clear();
                        task.chunk.splats.clear();
                        vcm.trace_light_path(&w, source, pixel, &mut task.chunk);
                        task.store_path();
                    }
                    task
                })
                .collect();
            let buffers = (&mut self.positions, &mut self.stored);
            keep(tasks, buffers, [end, paths], &mut stats);
        }
        self.build(&w, &weights(vcm, serves), serves);
        stats
    }

    /// Makes room for about `expected` vertices of this iteration (the previous iteration's
    /// count and a margin), so the buffers do not double past what the iteration stores.
    fn reserve(&mut self, expected: usize) {
        let room = expected + expected / 32;
        self.stored.clear();
        self.positions.clear();
        self.stored.reserve_exact(room);
        self.positions.reserve_exact(room);
    }

    /// Frees the previous iteration's vertices and builds the grid over this one's, their
    /// merge terms weighed for iteration `serves` (`from` the weights they were traced with).
    fn build(&mut self, from: &VcmWeights, to: &VcmWeights, serves: u64) {
        self.merge_vertices = Vec::new();
        self.grid = HashGrid::build(&self.positions, to.radius);
        self.positions = Vec::new();
        let stored = &self.stored;
        let mut next = Vec::with_capacity(stored.len());
        next.par_extend(
            self.grid
                .indices()
                .map(|i| stored[i as usize].weighed(from, to)),
        );
        self.merge_vertices = next;
        self.measure();
        self.stored = Vec::new();
        self.serves = Some(serves);
    }

    /// Records the vertices held now and their buffers' bytes.
    fn measure(&mut self) {
        let bytes = self.merge_vertices.capacity() * std::mem::size_of::<MergeVertex>()
            + self.stored.capacity() * std::mem::size_of::<Stored>()
            + self.positions.capacity() * std::mem::size_of::<Vec3>();
        let held = self.merge_vertices.len() + self.stored.len();
        self.peak_vertices = self.peak_vertices.max(held);
        self.peak_bytes = self.peak_bytes.max(bytes);
    }
}

/// Appends a wave's stored vertices in task order and adds up its counters; `[done, all]`
/// the paths traced so far and in all. Where the buffers would grow, they make room for the
/// vertices the paths so far predict and a margin, not twice what they hold.
fn keep(
    tasks: Vec<Task>,
    (positions, stored): (&mut Vec<Vec3>, &mut Vec<Stored>),
    [done, all]: [usize; 2],
    stats: &mut IterationStats,
) {
    let wave: usize = tasks.iter().map(|task| task.stored.len()).sum();
    let held = stored.len() + wave;
    if held > stored.capacity() {
        let predicted = held * all / done.max(1);
        let room = predicted + predicted / 32 - stored.len();
        stored.reserve_exact(room);
        positions.reserve_exact(room);
    }
    for task in tasks {
        *stats = *stats + task.stats + task.chunk.stats;
        positions.extend_from_slice(&task.positions);
        stored.extend_from_slice(&task.stored);
    }
}
