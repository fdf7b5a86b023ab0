//! One-stage vertex merging in bounded memory (001 sec. 6.2), `memory = one-stage`.
//!
//! Per pixel the light sub-path is traced, its vertices stored as a merge reads them, packed
//! ([`Packed`]: incoming direction, throughput, path length, the two MIS quantities a merge
//! reads; no BSDF data) beside their positions, and the eye sub-path traced; it connects to
//! that light sub-path, the only one kept whole, and merges with the vertices the *previous*
//! iteration stored. At the iteration's end the previous vertices and their grid are freed, the
//! grid is built over this iteration's positions (in place, [`HashGrid::build`]), and the
//! packed vertices are put in the grid's order. So the light vertices are held twice at the
//! peak (the previous iteration's, 20 bytes each and 16 in the grid; this one's, 20 bytes and
//! their 12-byte position), and never with what their BSDFs need.
//!
//! The estimator is two-stage's in expectation, iteration by iteration: iteration i merges with
//! light sub-paths independent of its eye sub-paths and distributed as its own, so only the
//! weights and the normalisation need care.
//! - Iteration i's weights use radius r_i for every technique of a full path (001 sec. 6.1's
//!   rule). The stored vertices were traced with r_{i-1}: a light sub-path's d^VC carries
//!   eta_VCM linearly in its merge terms (001 eq. (35)), so the sub-paths are traced with those
//!   terms kept apart (the split VCM* keeps, [`VcmWeights::with_density`]; without a density
//!   map its weights are VCM's) and a vertex's merge terms are rescaled to r_i as it is
//!   stored (the radius of the next iteration is known). d^VCM does not depend on the radius;
//!   without connections (`bpm`, `ppm`) nothing stored does.
//! - The packing loses no expectation: MIS quantities stay f32, the throughput is rounded
//!   stochastically (its expectation is the exact value) and the direction to within 5e-5
//!   radians, far below what a BSDF resolves.
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
use crate::integrator::camera_rays::camera_ray_traced;
use crate::integrator::mis::{VcmVertex, VcmWeights};
use crate::integrator::subpath::MergeVertex;
use crate::integrator::upg::merge::Tentative;
use crate::integrator::IterationStats;
use crate::options::DensityMis;
use crate::prefetch::prefetch_lines;
use glam::Vec3;
use rayon::prelude::*;

/// Pixels per wave: each wave's camera splats are added before the next starts, so they never
/// take memory in proportion to the image.
const WAVE: usize = 1 << 16;

/// The light sub-paths the first iteration merges with: an iteration index no render reaches
/// (renders end below `options::MAX_ITERATIONS`), so their numbers are nobody else's.
const FIRST_MERGES: u64 = u64::MAX;

/// Light vertices as a density-estimate merge reads them, by slot of their grid: two-stage's
/// [`MergeVertex`] copies or one-stage's packed records.
pub(super) trait MergeRecords: Sync {
    /// Segments from the light to the vertex in `slot`: what decides whether a merge takes it,
    /// read before the rest.
    fn path_length(&self, slot: u32) -> u32;
    fn vertex(&self, slot: u32) -> MergeVertex;
    /// Prefetches the records of `slots` (a grid range, contiguous in memory), a cache line
    /// each, so that their misses overlap the work before the merge instead of being waited
    /// for as the scan finds the points.
    fn prefetch(&self, slots: std::ops::Range<usize>);
}

impl MergeRecords for [MergeVertex] {
    #[inline]
    fn path_length(&self, slot: u32) -> u32 {
        self[slot as usize].path_length
    }

    #[inline]
    fn vertex(&self, slot: u32) -> MergeVertex {
        self[slot as usize]
    }

    #[inline]
    fn prefetch(&self, slots: std::ops::Range<usize>) {
        prefetch_lines(self, slots);
    }
}

/// The vertices an iteration's merges read, in one of the layouts.
#[derive(Clone, Copy)]
pub(super) enum MergeVertices<'a> {
    Whole(&'a [MergeVertex]),
    Narrow(NarrowVertices<'a>),
    Packed(PackedVertices<'a>),
}

impl MergeVertices<'_> {
    /// [`MergeRecords::prefetch`] of the layout at hand.
    #[inline]
    pub(super) fn prefetch(&self, slots: std::ops::Range<usize>) {
        match self {
            MergeVertices::Whole(v) => v.prefetch(slots),
            MergeVertices::Narrow(v) => v.prefetch(slots),
            MergeVertices::Packed(v) => v.prefetch(slots),
        }
    }
}

/// A light vertex as a two-stage merge reads it where neither per-pixel radii nor a density
/// map weigh it, in 36 bytes against [`MergeVertex`]'s 52: the merge then reads only d^VCM and
/// the [`MergeMis`] quantity, the other MIS fields being zero. Exact, unlike [`Packed`]: the
/// same numbers reach the weights. Fewer bytes, fewer of the cache lines whose misses are most
/// of a merge's cost.
#[derive(Clone, Copy, Debug)]
pub(super) struct Narrow {
    wo: Vec3,
    throughput: Rgb,
    mis: [f32; 2],
    path_length: u32,
}

const _: () = assert!(std::mem::size_of::<Narrow>() == 36);

impl Narrow {
    /// The record of `v` for merges that read `form`.
    pub(super) fn new(v: &LightVertex, form: MergeMis) -> Self {
        let mis = &v.mis;
        let second = match form {
            // What `VcmWeights::merge` reads with nu = 1 (no density map).
            MergeMis::WithConnections => mis.d_vc + mis.d_vc_vm,
            MergeMis::MergesOnly => mis.d_vm,
        };
        Narrow {
            wo: v.wo,
            throughput: v.throughput,
            mis: [mis.d_vcm, second],
            path_length: v.path_length,
        }
    }
}

/// Two-stage's narrow records with the quantity they hold.
#[derive(Clone, Copy)]
pub(super) struct NarrowVertices<'a> {
    pub(super) records: &'a [Narrow],
    pub(super) form: MergeMis,
}

impl MergeRecords for NarrowVertices<'_> {
    #[inline]
    fn path_length(&self, slot: u32) -> u32 {
        self.records[slot as usize].path_length
    }

    #[inline]
    fn vertex(&self, slot: u32) -> MergeVertex {
        let r = &self.records[slot as usize];
        MergeVertex {
            wo: r.wo,
            throughput: r.throughput,
            path_length: r.path_length,
            mis: self.form.unpack(r.mis),
        }
    }

    #[inline]
    fn prefetch(&self, slots: std::ops::Range<usize>) {
        prefetch_lines(self.records, slots);
    }
}

/// One-stage's packed vertices with what unpacks them.
#[derive(Clone, Copy)]
pub(super) struct PackedVertices<'a> {
    records: &'a [Packed],
    form: MergeMis,
}

impl MergeRecords for PackedVertices<'_> {
    #[inline]
    fn path_length(&self, slot: u32) -> u32 {
        self.records[slot as usize].path_length()
    }

    #[inline]
    fn vertex(&self, slot: u32) -> MergeVertex {
        self.records[slot as usize].unpack(self.form)
    }

    #[inline]
    fn prefetch(&self, slots: std::ops::Range<usize>) {
        prefetch_lines(self.records, slots);
    }
}

/// Which MIS quantity besides d^VCM a merge reads ([`VcmWeights::merge`]): where merges compete
/// with connections, d^VC with its merge terms (001 eq. (38) in the form d^VCM + d^VC mis(pdf),
/// over eta_VCM); where they do not (`bpm`, `ppm`), d^VM.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MergeMis {
    WithConnections,
    MergesOnly,
}

impl MergeMis {
    /// The quantity merges weighed with `w` read.
    pub(super) fn of(w: &VcmWeights) -> Self {
        if w.vm_factor > 0.0 {
            MergeMis::WithConnections
        } else {
            MergeMis::MergesOnly
        }
    }

    /// The MIS quantities of a record holding d^VCM and this quantity, the rest zero.
    #[inline]
    fn unpack(self, [d_vcm, second]: [f32; 2]) -> VcmVertex {
        match self {
            MergeMis::WithConnections => VcmVertex {
                d_vcm,
                d_vc: second,
                ..VcmVertex::default()
            },
            MergeMis::MergesOnly => VcmVertex {
                d_vcm,
                d_vm: second,
                ..VcmVertex::default()
            },
        }
    }
}

/// A light vertex as a merge reads it, in 20 bytes (its position is the grid's): the incoming
/// direction in octahedral coordinates, d^VCM and the [`MergeMis`] quantity in f32, and in 64
/// bits the throughput ([`pack_rgb`], 47 bits) and the path length (16 bits; a light sub-path
/// longer than 65535 segments, which roulette all but never leaves, would be taken as that
/// long).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Packed {
    wo: u32,
    mis: [f32; 2],
    bits: [u32; 2],
}

/// Where the path length starts in [`Packed`]'s 64 bits, above the throughput.
const PATH_LENGTH_SHIFT: u32 = 47;

const _: () = assert!(std::mem::size_of::<Packed>() == 20);

impl Packed {
    /// `mis` is d^VCM and the [`MergeMis`] quantity; `dither` is [`pack_rgb`]'s.
    fn new(wo: Vec3, throughput: Rgb, path_length: u32, mis: [f32; 2], dither: [f32; 3]) -> Self {
        let path_length = u64::from(path_length.min(u32::from(u16::MAX)));
        let bits = pack_rgb(throughput, dither) | path_length << PATH_LENGTH_SHIFT;
        Packed {
            wo: pack_direction(wo),
            mis,
            bits: [bits as u32, (bits >> 32) as u32],
        }
    }

    #[inline]
    fn bits(&self) -> u64 {
        u64::from(self.bits[0]) | u64::from(self.bits[1]) << 32
    }

    #[inline]
    fn path_length(&self) -> u32 {
        (self.bits() >> PATH_LENGTH_SHIFT) as u32 & 0xffff
    }

    /// The vertex as a merge of `form` reads it; the MIS quantities it does not read are zero.
    #[inline]
    fn unpack(&self, form: MergeMis) -> MergeVertex {
        MergeVertex {
            wo: unpack_direction(self.wo),
            throughput: unpack_rgb(self.bits()),
            path_length: self.path_length(),
            mis: form.unpack(self.mis),
        }
    }
}

/// How vertices traced with one iteration's weights are packed for the merges of another's.
#[derive(Clone, Copy)]
struct Packing {
    form: MergeMis,
    /// mis(eta_VCM) of the merges over that of the tracing, where merges compete with
    /// connections.
    rescale: Option<f32>,
}

impl Packing {
    /// Vertices traced with weights `from` for merges weighed with `to`.
    fn new(from: &VcmWeights, to: &VcmWeights) -> Self {
        let competing = from.vm_factor > 0.0 && to.vm_factor > 0.0;
        Packing {
            form: MergeMis::of(to),
            rescale: competing.then(|| to.vm_factor / from.vm_factor),
        }
    }

    fn pack(&self, v: &LightVertex) -> Packed {
        let mis = &v.mis;
        let second = match self.form {
            // d^VC's merge terms scale with mis(eta_VCM) (001 eq. (35)); without a density
            // map VCM*'s nu is 1, so the merge reads their sum with the connection terms.
            MergeMis::WithConnections => mis.d_vc + mis.d_vc_vm * self.rescale.unwrap_or(1.0),
            MergeMis::MergesOnly => mis.d_vm,
        };
        let mis = [mis.d_vcm, second];
        Packed::new(v.wo, v.throughput, v.path_length, mis, dither(v.position))
    }
}

/// Bits of a throughput channel's mantissa in [`pack_rgb`].
const MANTISSA_BITS: u32 = 13;
/// Below this largest channel a throughput is stored as black: no light sub-path carries so
/// little, and it keeps the scale factors below normal f32s.
const MIN_THROUGHPUT: f32 = 1e-30;

/// A non-negative colour in 47 bits: three 13-bit mantissas sharing the f32 exponent of the
/// largest channel (Ward's RGBE with wider mantissas), which keeps 12 significant bits, so a
/// step of at most 2^-11 of its value; a channel k times smaller has steps k times coarser,
/// relative to it. Each mantissa is rounded up with the probability of its remainder
/// (`dither` uniform in [0, 1)), so the stored colour is the exact one in expectation: a
/// stored constant (the first vertices of an area light's sub-paths all carry one) rounded
/// to the nearest step would bias their merges by up to half a step. A non-finite colour
/// stays non-finite, so the sample it reaches is dropped as before.
fn pack_rgb(c: Rgb, dither: [f32; 3]) -> u64 {
    let max = c.r.max(c.g).max(c.b);
    if !max.is_finite() {
        return 0xff << (3 * MANTISSA_BITS);
    }
    if max < MIN_THROUGHPUT {
        return 0;
    }
    // max in [2^(e - 127), 2^(e - 126)): scaled by 2^(138 - e), in [2^11, 2^12).
    let exponent = max.to_bits() >> 23;
    let scale = f64::from(f32::from_bits((265 - exponent) << 23));
    let mut bits = u64::from(exponent) << (3 * MANTISSA_BITS);
    for (k, (value, u)) in [c.r, c.g, c.b].into_iter().zip(dither).enumerate() {
        let mantissa = (f64::from(value.max(0.0)) * scale + f64::from(u)).floor() as u64;
        bits |= mantissa << (k as u32 * MANTISSA_BITS);
    }
    bits
}

#[inline]
fn unpack_rgb(bits: u64) -> Rgb {
    let exponent = (bits >> (3 * MANTISSA_BITS)) as u32 & 0xff;
    let step = match exponent {
        0 => 0.0,
        0xff => f32::INFINITY,
        e => f32::from_bits((e - 11) << 23),
    };
    let channel = |k: u32| ((bits >> (k * MANTISSA_BITS)) & ((1 << MANTISSA_BITS) - 1)) as f32;
    Rgb::new(channel(0) * step, channel(1) * step, channel(2) * step)
}

/// Three numbers uniform in [0, 1) for [`pack_rgb`]'s rounding, from a hash of a vertex's
/// position: the same on any thread, and unrelated to what is rounded.
fn dither(p: Vec3) -> [f32; 3] {
    let [x, y, z] = p.to_array().map(f32::to_bits);
    let h = mix(mix(u64::from(x) | u64::from(y) << 32) ^ u64::from(z));
    // Three 21-bit fractions.
    [0, 21, 42].map(|shift| ((h >> shift) & 0x1f_ffff) as f32 * (1.0 / (1u32 << 21) as f32))
}

/// SplitMix64's finaliser: every input bit flips about half the output bits.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Largest code of an octahedral coordinate (16 bits).
const OCT_MAX: f32 = u16::MAX as f32;

/// A unit vector in 32 bits: the octahedral map (Cigolle et al. 2014) onto [-1, 1]^2 in
/// 65536 steps a coordinate, of the four codes around the point the one whose direction is
/// closest (their "precise" variant); the round trip is within 5e-5 radians.
fn pack_direction(d: Vec3) -> u32 {
    let l1 = d.x.abs() + d.y.abs() + d.z.abs();
    let (u, v) = octahedral_fold(d.x / l1, d.y / l1, d.z);
    let scaled = |x: f32| (x.clamp(-1.0, 1.0) * 0.5 + 0.5) * OCT_MAX;
    let (u, v) = (scaled(u), scaled(v));
    // By distance, not cosine: a cosine this close to 1 is 1 in f32.
    let mut best = (f32::INFINITY, 0);
    for cu in [u.floor(), u.ceil()] {
        for cv in [v.floor(), v.ceil()] {
            let code = cu as u32 | (cv as u32) << 16;
            let distance = unpack_direction(code).distance_squared(d);
            if distance < best.0 {
                best = (distance, code);
            }
        }
    }
    best.1
}

#[inline]
fn unpack_direction(code: u32) -> Vec3 {
    let coordinate = |c: u32| (c & 0xffff) as f32 * (2.0 / OCT_MAX) - 1.0;
    let (u, v) = (coordinate(code), coordinate(code >> 16));
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = octahedral_fold(u, v, z);
    Vec3::new(x, y, z).normalize()
}

/// The lower hemisphere's (`z` < 0) coordinates folded over the diagonals, and back.
#[inline]
fn octahedral_fold(u: f32, v: f32, z: f32) -> (f32, f32) {
    if z < 0.0 {
        ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum())
    } else {
        (u, v)
    }
}

/// The light vertices one-stage vertex merging keeps.
#[derive(Default)]
pub(super) struct OneStage {
    /// The previous iteration's vertices in `grid`'s order, packed for the iteration `serves`.
    merge_vertices: Vec<Packed>,
    grid: HashGrid,
    serves: Option<u64>,
    /// This iteration's vertices, in pixel order, and their positions.
    stored: Vec<Packed>,
    positions: Vec<Vec3>,
    /// The most light vertices held at once and the bytes of their buffers (the grid's own
    /// left out), over the iterations so far.
    pub(super) peak_vertices: usize,
    pub(super) peak_bytes: usize,
}

/// Bytes of a light vertex stored for the next iteration: what a merge reads and the position.
pub const STORED_BYTES: usize = std::mem::size_of::<Packed>() + std::mem::size_of::<Vec3>();

/// What one task of a wave produces.
#[derive(Default)]
struct Task {
    chunk: LightChunk,
    positions: Vec<Vec3>,
    stored: Vec<Packed>,
    stats: IterationStats,
}

impl Task {
    /// Keeps the vertices of the light sub-path just traced into `chunk` for the next
    /// iteration's merges.
    fn store_path(&mut self, packing: &Packing) {
        let path = &self.chunk.vertices;
        self.positions.extend(path.iter().map(|v| v.position));
        self.stored.extend(path.iter().map(|v| packing.pack(v)));
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
        let next = weights(vcm, iteration + 1);
        let packing = Packing::new(&w, &next);
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
        let pass_grid = ready.then_some(&*grid);
        let merge_vertices = MergeVertices::Packed(PackedVertices {
            records: merge_vertices,
            form: packing.form,
        });
        for first in (0..frame.len()).step_by(WAVE) {
            let end = (first + WAVE).min(frame.len());
            let mut tasks: Vec<Task> = frame[first..end]
                .par_chunks_mut(EYE_TASK)
                .enumerate()
                .map(|(t, pixels)| {
                    let mut task = Task::default();
                    let mut tentative = Tentative::new(seed, iteration);
                    let mut light_bsdfs = Vec::new();
                    let mut light = LightPaths::default();
                    for (k, value) in pixels.iter_mut().enumerate() {
                        let pixel = first + t * EYE_TASK + k;
                        task.chunk.vertices.clear();
                        vcm.trace_light_path(&w, iteration, pixel, &mut task.chunk);
                        if merges {
                            task.store_path(&packing);
                        }
                        light.hold_one(&task.chunk.vertices);
                        let pass = EyePass {
                            w,
                            light: &light,
                            grid: pass_grid,
                            merge_vertices,
                        };
                        let mut s = IterationStats::default();
                        let (mut sampler, ray, hit) = camera_ray_traced(&vcm.ctx, iteration, pixel);
                        let color = vcm.trace_eye_path(
                            &pass,
                            pixel,
                            (&mut sampler, ray, hit),
                            (&mut tentative, &mut light_bsdfs),
                            &mut s,
                        );
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
            self.build(iteration + 1, next.radius);
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
        self.grid = HashGrid::default();
        self.reserve(0);
        let w = weights(vcm, source.min(serves));
        let to = weights(vcm, serves);
        let packing = Packing::new(&w, &to);
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
                        task.store_path(&packing);
                    }
                    task
                })
                .collect();
            let buffers = (&mut self.positions, &mut self.stored);
            keep(tasks, buffers, [end, paths], &mut stats);
        }
        self.build(serves, to.radius);
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

    /// Frees the previous iteration's vertices and their grid, builds the grid of `radius`
    /// over this iteration's and puts them in its order, for the merges of iteration `serves`.
    /// The grid's build sorts in place, and the reordering copies 20 bytes a vertex once the
    /// positions are freed, so neither holds more than the eye pass did.
    fn build(&mut self, serves: u64, radius: f32) {
        self.merge_vertices = Vec::new();
        self.grid = HashGrid::default();
        self.grid = HashGrid::build(&self.positions, radius);
        self.positions = Vec::new();
        let stored = &self.stored;
        let mut next = Vec::with_capacity(stored.len());
        next.par_extend(self.grid.indices().map(|i| stored[i as usize]));
        self.merge_vertices = next;
        self.measure();
        self.stored = Vec::new();
        self.serves = Some(serves);
    }

    /// Records the vertices held now and their buffers' bytes.
    fn measure(&mut self) {
        let bytes = (self.merge_vertices.capacity() + self.stored.capacity())
            * std::mem::size_of::<Packed>()
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
    (positions, stored): (&mut Vec<Vec3>, &mut Vec<Packed>),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    fn random_direction(rng: &mut Rng) -> Vec3 {
        loop {
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            if (1e-3..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }

    /// Directions come back within 5e-5 radians: random ones, the axes, and the octahedron's
    /// folds (coordinates of either sign zero).
    #[test]
    fn directions_round_trip() {
        let mut rng = Rng::for_sample(1, 0, 0, Stream::Eye);
        let mut directions: Vec<Vec3> = (0..200_000).map(|_| random_direction(&mut rng)).collect();
        for x in [-1.0f32, -0.0, 0.0, 1.0] {
            for y in [-1.0f32, -0.0, 0.0, 1.0] {
                for z in [-1.0f32, -0.0, 0.0, 1.0] {
                    let v = Vec3::new(x, y, z);
                    if v.length_squared() > 0.0 {
                        directions.push(v.normalize());
                    }
                }
            }
        }
        let mut worst = 0.0f32;
        for d in directions {
            let back = unpack_direction(pack_direction(d));
            assert!((back.length() - 1.0).abs() < 1e-6, "{d} -> {back}");
            let angle = d.cross(back).length().atan2(d.dot(back));
            assert!(angle <= 5e-5, "{d} -> {back}: {angle} radians");
            worst = worst.max(angle);
        }
        // The steps are not far finer than claimed either.
        assert!(worst > 5e-6, "{worst}");
    }

    /// Every channel comes back within one step, 2^-11 of the largest channel, whatever the
    /// dither; black, a non-finite colour and the extremes of the f32 range keep what they are.
    #[test]
    fn colours_round_trip_within_a_step() {
        let mut rng = Rng::for_sample(2, 0, 0, Stream::Eye);
        for _ in 0..100_000 {
            let scale = 2f32.powf(rng.next_f32() * 160.0 - 80.0);
            let c = Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32().powi(8)) * scale;
            let dither = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let back = unpack_rgb(pack_rgb(c, dither));
            let step = c.max_component() / 2048.0;
            for (a, b) in [(c.r, back.r), (c.g, back.g), (c.b, back.b)] {
                assert!((a - b).abs() <= step, "{c:?} -> {back:?}");
            }
        }
        for c in [
            Rgb::BLACK,
            Rgb::new(1e-31, 0.0, 0.0),
            Rgb::new(0.0, 0.0, 3e38),
        ] {
            let back = unpack_rgb(pack_rgb(c, [0.5; 3]));
            assert!((back.b - c.b).abs() <= c.b / 2048.0, "{c:?} -> {back:?}");
            assert_eq!(back.r == 0.0, c.r < MIN_THROUGHPUT, "{c:?} -> {back:?}");
        }
        let back = unpack_rgb(pack_rgb(Rgb::new(1.0, f32::INFINITY, 0.0), [0.5; 3]));
        assert!(!back.is_finite(), "{back:?}");
    }

    /// The rounding is unbiased: over the dither of many vertices' positions the mean of a
    /// colour's round trip is the colour, within 4 standard errors (each round trip is off by
    /// less than a step, so a standard error is at most step / (2 sqrt(n))), where rounding
    /// to the nearest step would be off by up to half a step.
    #[test]
    fn colour_rounding_is_unbiased() {
        let mut rng = Rng::for_sample(3, 0, 0, Stream::Eye);
        let n = 200_000;
        for c in [
            Rgb::new(1.0 + 0.3 / 2048.0, 0.1234, 0.000_77),
            Rgb::new(37.9, 12.25, 3.1),
            Rgb::new(0.02, 0.9, 5e-6),
        ] {
            let mut sum = [0.0f64; 3];
            for _ in 0..n {
                let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                let back = unpack_rgb(pack_rgb(c, dither(p)));
                for (s, v) in sum.iter_mut().zip([back.r, back.g, back.b]) {
                    *s += f64::from(v);
                }
            }
            let step = f64::from(c.max_component()) / 2048.0;
            let bound = 4.0 * step / (2.0 * (n as f64).sqrt());
            for (s, exact) in sum.iter().zip([c.r, c.g, c.b]) {
                let error = s / n as f64 - f64::from(exact);
                assert!(
                    error.abs() <= bound,
                    "{c:?}: mean off by {error:e}, bound {bound:e}"
                );
            }
        }
    }

    /// A record gives back what it was given: the MIS quantities exactly, in the field the
    /// form names, and the path length.
    #[test]
    fn records_round_trip() {
        let wo = Vec3::new(0.3, -0.8, 0.2).normalize();
        let throughput = Rgb::new(2.5, 0.75, 0.125);
        for (length, form) in [(1, MergeMis::WithConnections), (9, MergeMis::MergesOnly)] {
            let record = Packed::new(wo, throughput, length, [0.1, 3e7], [0.0; 3]);
            let v = record.unpack(form);
            assert_eq!((v.path_length, record.path_length()), (length, length));
            assert_eq!(v.throughput, throughput);
            assert!(v.wo.distance(wo) < 1e-4);
            assert_eq!(v.mis.d_vcm, 0.1);
            let second = match form {
                MergeMis::WithConnections => (v.mis.d_vc, v.mis.d_vm),
                MergeMis::MergesOnly => (v.mis.d_vm, v.mis.d_vc),
            };
            assert_eq!(second, (3e7, 0.0));
        }
        let long = Packed::new(wo, throughput, 1 << 20, [0.0; 2], [0.0; 3]);
        assert_eq!(long.path_length(), u32::from(u16::MAX));
    }
}
