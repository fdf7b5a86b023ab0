//! The sub-path state of the vertex-merging family (SmallVCM's SubPathState and PathVertex):
//! what `vcm.rs` carries while tracing and stores of light sub-paths, and what the UPG merges
//! (`upg/merge.rs`) read back. What a technique keeps per vertex beside it is a type parameter,
//! `P` (a [`PendingMis`]), so that this layer names no technique.

use super::mis::{Arrival, VcmVertex, VcmWeights, VmHere, NO_DENSITY};
use super::IterationStats;
use crate::accel::Ray;
use crate::bsdf::{Bsdf, Normals, TransportMode};
use crate::color::Rgb;
use crate::film::{add_splats, Splats};
use crate::frame::Azimuth;
use crate::prefetch::prefetch;
use crate::scene::{Scene, SurfaceHit};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::ops::ControlFlow;

/// MIS terms a technique keeps per sub-path vertex beside its [`VcmVertex`] whose value only a
/// use of the vertex decides: a merge at the previous vertex gathered from the other side
/// (000 eqs. 2.81-2.82). The default is none pending.
pub trait PendingMis: Copy + Default + Send + Sync {
    /// `v`, the vertex's MIS quantities, with the pending terms added once a use of the vertex
    /// fixes `rev_pdf_w`, the pdf with which it samples its predecessor.
    fn settle(&self, w: &VcmWeights, v: VcmVertex, rev_pdf_w: f32) -> VcmVertex;

    /// The terms of a merge at the vertex being left, deferred to the next vertex: `ratio` is
    /// what [`VcmWeights::scatter`] returned, `cos_out` the |cos| of the sampled direction,
    /// `rho` the merge's density factor (002; 1 without the density map).
    fn leaving(w: &VcmWeights, ratio: f32, cos_out: f32, rho: f32) -> Self;

    /// Carried across a segment, like d^VC (001 eq. (35)).
    fn arrive(&mut self, a: Arrival);

    /// On arrival: kept only where the vertex reached is a non-delta surface vertex.
    fn keep_if(&mut self, surface: bool);
}

/// One step of a light sub-path's MIS recursion (001 eqs. (31)-(36)) with the inputs it takes
/// (eye sub-paths leave their vertices by the same [`MisStep::Leave`]). The light pass applies
/// each step as it traces. With a radius per eye sub-path (001 sec. 6.1)
/// under UPG's clamped acceptance or 002's density factors, whose sums are not linear in
/// eta_VCM, a light sub-path cannot carry radius-free sums as VCM's c^VC and c^VM do; so its
/// steps are kept, and every use of the sub-path re-runs them at the radius of the eye
/// sub-path that joins it ([`replay`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MisStep {
    /// y_0 on a light: its area pdf and emission pdf (both with the pick), |cos| there (1 for
    /// infinite lights), and whether it is a delta light (001 eqs. (31)-(33)).
    Origin {
        direct_pdf_a: f32,
        emission_pdf_w: f32,
        cos_at_light: f32,
        delta: bool,
    },
    /// Arriving at a vertex `distance` away with |cos| `cos` there (`with_distance` false on the
    /// first segment from an infinite light: 001 sec. 5.1); `surface` when it is a non-delta
    /// surface vertex, which is stored (and holds the position the density map is read at)
    /// and may be merged at.
    Arrive {
        distance: f32,
        cos: f32,
        with_distance: bool,
        surface: bool,
    },
    /// Leaving the vertex in a sampled direction: its |cos|, the pdfs of the direction and of
    /// the reverse, whether the sample was a delta lobe, and whether merging at the vertex is a
    /// technique.
    Leave {
        cos_out: f32,
        pdf_w: f32,
        rev_pdf_w: f32,
        delta: bool,
        here: VmHere,
    },
}

impl MisStep {
    /// Applies the step with weights `w` to a sub-path's MIS quantities, its pending terms and
    /// its density factor (rho, 1 / k) at the current vertex. `inv_k` gives 1 / k at the
    /// vertex (002; `None` without a density map), asked only at surface vertices.
    pub fn apply<P: PendingMis>(
        &self,
        w: &VcmWeights,
        mis: &mut VcmVertex,
        pending: &mut P,
        density: &mut (f32, f32),
        inv_k: impl FnOnce() -> Option<f32>,
    ) {
        match *self {
            MisStep::Origin {
                direct_pdf_a,
                emission_pdf_w,
                cos_at_light,
                delta,
            } => {
                *mis = w.light_origin(direct_pdf_a, emission_pdf_w, cos_at_light, delta);
                *pending = P::default();
                *density = NO_DENSITY;
            }
            MisStep::Arrive {
                distance,
                cos,
                with_distance,
                surface,
            } => {
                pending.arrive(w.arrive(mis, distance, cos, with_distance));
                pending.keep_if(surface);
                *density = if surface {
                    w.density_at(mis, inv_k())
                } else {
                    NO_DENSITY
                };
            }
            MisStep::Leave {
                cos_out,
                pdf_w,
                rev_pdf_w,
                delta,
                here,
            } => {
                if !delta {
                    *mis = pending.settle(w, *mis, rev_pdf_w);
                }
                let merge_here = (here == VmHere::Valid, density.0);
                let ratio = w.scatter(mis, cos_out, pdf_w, rev_pdf_w, delta, merge_here);
                *pending = if !delta && here == VmHere::Deferred {
                    P::leaving(w, ratio, cos_out, density.0)
                } else {
                    P::default()
                };
            }
        }
    }
}

/// Re-runs a light sub-path's steps with weights `w` (an eye sub-path's radius), calling
/// `visit` with the MIS quantities, pending terms and density factor at each of its surface
/// vertices, the stored ones, in order, until `visit` breaks; `inv_k(i)` gives 1 / k at the
/// i-th of them. The same [`MisStep::apply`] as the light pass's, so at the radius the
/// sub-path was traced with it gives what was stored.
pub fn replay<P: PendingMis>(
    w: &VcmWeights,
    steps: &[MisStep],
    mut inv_k: impl FnMut(usize) -> Option<f32>,
    mut visit: impl FnMut(&VcmVertex, &P, (f32, f32)) -> ControlFlow<()>,
) {
    let (mut mis, mut pending, mut density) = (VcmVertex::default(), P::default(), NO_DENSITY);
    let mut surfaces = 0;
    for step in steps {
        step.apply(w, &mut mis, &mut pending, &mut density, || inv_k(surfaces));
        if let MisStep::Arrive { surface: true, .. } = step {
            surfaces += 1;
            if visit(&mis, &pending, density).is_break() {
                return;
            }
        }
    }
}

/// A stored light sub-path vertex: everything a connection or a merge needs.
#[derive(Copy, Debug)]
pub struct LightVertex<P> {
    pub position: Vec3,
    /// Geometric normal.
    pub ng: Vec3,
    /// Shading normal and texture coordinates, for the BSDF there.
    pub ns: Vec3,
    pub uv: Vec2,
    /// The direction of the surface's tangent, which orients an anisotropic BSDF
    /// ([`SurfaceHit::azimuth`]).
    pub azimuth: Azimuth,
    /// Unit direction back towards the previous vertex of the light sub-path.
    pub wo: Vec3,
    pub throughput: Rgb,
    pub material: u32,
    /// Segments from the light to this vertex.
    pub path_length: u32,
    pub mis: VcmVertex,
    /// The pending MIS terms (`upg-camera`'s merge at the previous vertex), awaiting this
    /// vertex's reverse pdf.
    pub pending: P,
    /// The density factor of a merge here (002; 1 without the density map).
    pub rho: f32,
    /// The previous vertex of the sub-path is a non-delta surface vertex, stored just before
    /// this one.
    pub after_surface: bool,
    /// That previous vertex is glossy by `upg-hybrid`'s rule (false for other techniques).
    pub after_glossy: bool,
}

/// What a density-estimate merge reads of a light vertex: a copy, half the size, stored in the
/// hash grid's order so the merge loop streams through it.
#[derive(Clone, Copy, Debug)]
pub struct MergeVertex {
    pub wo: Vec3,
    pub throughput: Rgb,
    pub path_length: u32,
    pub mis: VcmVertex,
}

// A bitwise copy: the derived `Clone` of a generic type clones field by field, which filling
// the light paths' storage (`LightPaths::refill`) would pay for every vertex.
impl<P: Copy> Clone for LightVertex<P> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<P> LightVertex<P> {
    /// Prefetches the vertex's cache lines (it spans two or three), through three fields that
    /// the compiler's layout puts at its start, less than a line further and at its last byte:
    /// one in every line whatever the vertex's alignment (checked, for the vertices UPG's gathers
    /// prefetch, by `upg::merge`'s `every_line_of_a_light_vertex_is_prefetched`, which fails if
    /// the layout moves them).
    #[inline]
    pub fn prefetch(&self) {
        prefetch(&self.uv);
        prefetch(&self.ns);
        prefetch(&self.after_glossy);
    }
}

impl<P> From<&LightVertex<P>> for MergeVertex {
    fn from(v: &LightVertex<P>) -> Self {
        MergeVertex {
            wo: v.wo,
            throughput: v.throughput,
            path_length: v.path_length,
            mis: v.mis,
        }
    }
}

impl<P: PendingMis> LightVertex<P> {
    /// The vertex's BSDF, as the light sub-path scattered there.
    pub fn bsdf<'s>(&self, scene: &'s Scene) -> Option<Bsdf<'s>> {
        let normals = Normals {
            ng: self.ng,
            ns: self.ns,
        };
        scene.oriented_bsdf(
            self.material,
            normals,
            self.azimuth,
            self.uv,
            self.wo,
            TransportMode::Importance,
        )
    }

    /// The MIS quantities once a use of the vertex fixes `rev_pdf_w`, the pdf with which it
    /// samples its predecessor.
    pub fn mis_at(&self, w: &VcmWeights, rev_pdf_w: f32) -> VcmVertex {
        self.pending.settle(w, self.mis, rev_pdf_w)
    }
}

/// The state of a sub-path being traced.
#[derive(Clone, Copy, Debug)]
pub struct SubPath<P> {
    pub ray: Ray,
    pub throughput: Rgb,
    pub path_length: u32,
    /// Light sub-paths: started on a finite light (distance terms apply to the first segment).
    pub finite_light: bool,
    /// Eye sub-paths: every scattering so far was a delta lobe.
    pub specular: bool,
    /// The vertex the ray left from is a non-delta surface vertex.
    pub prev_surface: bool,
    /// That vertex is glossy by `upg-hybrid`'s rule (false for other techniques).
    pub prev_glossy: bool,
    pub mis: VcmVertex,
    /// The pending MIS terms: a UPG merge at the previous vertex gathered from the other side
    /// (`upg` on eye sub-paths, `upg-camera` on light sub-paths).
    pub pending: P,
    /// The density factor rho of a merge at the current vertex and its 1 / k (002; 1 and 0
    /// without the density map).
    pub density: (f32, f32),
}

impl<P: PendingMis> SubPath<P> {
    /// [`LightVertex::mis_at`] of the sub-path's current vertex.
    pub fn mis_at(&self, w: &VcmWeights, rev_pdf_w: f32) -> VcmVertex {
        self.pending.settle(w, self.mis, rev_pdf_w)
    }
}

/// The last eye vertex, kept for the merges gathered from the camera side at the next one.
#[derive(Clone)]
pub struct EyeVertex<'b, P> {
    pub hit: SurfaceHit,
    pub bsdf: Bsdf<'b>,
    /// Throughput and MIS quantities on arrival, before scattering on, with the pending terms
    /// that await the vertex's reverse pdf.
    pub throughput: Rgb,
    pub mis: VcmVertex,
    pub pending: P,
    /// The density factor rho of a merge there and its 1 / k (002; 1 and 0 without the
    /// density map).
    pub density: (f32, f32),
    pub prev_surface: bool,
    pub path_length: u32,
}

/// What one task of the light pass produces: its vertices, where each of its paths ends, its
/// camera splats and counters; where the paths are re-run at other radii, their MIS steps
/// ([`MisStep`]) and where each path's end.
pub struct LightChunk<P> {
    pub vertices: Vec<LightVertex<P>>,
    pub ends: Vec<u32>,
    pub steps: Vec<MisStep>,
    pub step_ends: Vec<u32>,
    pub splats: Splats,
    pub stats: IterationStats,
}

impl<P> Default for LightChunk<P> {
    fn default() -> Self {
        LightChunk {
            vertices: Vec::new(),
            ends: Vec::new(),
            steps: Vec::new(),
            step_ends: Vec::new(),
            splats: Splats::default(),
            stats: IterationStats::default(),
        }
    }
}

impl<P> LightChunk<P> {
    /// Empties the chunk for the next iteration, keeping its storage.
    pub fn clear(&mut self) {
        self.vertices.clear();
        self.ends.clear();
        self.steps.clear();
        self.step_ends.clear();
        self.splats.clear();
        self.stats = IterationStats::default();
    }
}

/// The light sub-paths of one iteration: every stored vertex, path after path.
pub struct LightPaths<P> {
    pub vertices: Vec<LightVertex<P>>,
    /// Where each path's vertices begin, and one past the last path's.
    path_ends: Vec<usize>,
    /// Where the paths are re-run at other radii: their MIS steps, path after path, and where
    /// each path's begin (as `path_ends`); empty otherwise.
    steps: Vec<MisStep>,
    step_ends: Vec<usize>,
}

impl<P> Default for LightPaths<P> {
    fn default() -> Self {
        LightPaths {
            vertices: Vec::new(),
            path_ends: Vec::new(),
            steps: Vec::new(),
            step_ends: Vec::new(),
        }
    }
}

impl<P: PendingMis> LightPaths<P> {
    /// Replaces the paths by the chunks' in order (so the result does not depend on the
    /// threads), adding their camera splats to `frame` and their counters to `stats`. The
    /// storage is kept from one iteration to the next.
    pub fn refill(
        &mut self,
        chunks: &mut [LightChunk<P>],
        frame: &mut [Rgb],
        stats: &mut IterationStats,
    ) {
        stats.dropped_samples += add_splats(frame, chunks, |chunk| &mut chunk.splats);
        self.path_ends.clear();
        self.path_ends.push(0);
        self.steps.clear();
        self.step_ends.clear();
        let mut total = 0;
        for chunk in &*chunks {
            self.path_ends
                .extend(chunk.ends.iter().map(|&e| total + e as usize));
            total += chunk.vertices.len();
            stats.rays += chunk.stats.rays;
            stats.dropped_samples += chunk.stats.dropped_samples;
            if !chunk.step_ends.is_empty() {
                let start = self.steps.len();
                if self.step_ends.is_empty() {
                    self.step_ends.push(0);
                }
                self.step_ends
                    .extend(chunk.step_ends.iter().map(|&e| start + e as usize));
                self.steps.extend_from_slice(&chunk.steps);
            }
        }
        let chunks = &*chunks;
        // The copy runs on every thread, into storage of last iteration's length resized
        // (the filler is overwritten): a serial copy would hold up the other threads. Growth
        // is filled on every thread too: the first iteration's pages are tens of megabytes.
        match chunks.iter().find_map(|c| c.vertices.first()) {
            Some(&filler) if total > self.vertices.len() => {
                let grow = total - self.vertices.len();
                self.vertices
                    .par_extend(rayon::iter::repeat_n(filler, grow));
            }
            Some(_) => self.vertices.truncate(total),
            None => self.vertices.clear(),
        }
        let mut rest = self.vertices.as_mut_slice();
        let mut targets = Vec::with_capacity(chunks.len());
        for chunk in chunks {
            let (target, tail) = rest.split_at_mut(chunk.vertices.len());
            targets.push(target);
            rest = tail;
        }
        targets
            .into_par_iter()
            .zip(chunks)
            .for_each(|(target, chunk)| target.copy_from_slice(&chunk.vertices));
    }

    /// Holds `vertices` as the one light sub-path every eye sub-path connects to: one-stage
    /// vertex merging (001 sec. 6.2) keeps only the current pixel's sub-path whole.
    pub fn hold_one(&mut self, vertices: &[LightVertex<P>]) {
        self.vertices.clear();
        self.vertices.extend_from_slice(vertices);
        self.path_ends.clear();
        self.path_ends.extend([0, vertices.len()]);
        self.steps.clear();
        self.step_ends.clear();
    }

    /// The bytes of the kept MIS steps' storage.
    pub fn step_bytes(&self) -> usize {
        self.steps.capacity() * std::mem::size_of::<MisStep>()
            + self.step_ends.capacity() * std::mem::size_of::<usize>()
    }

    /// The index of the light sub-path the eye sub-path of `pixel` connects to.
    fn pixel_path(&self, pixel: usize) -> usize {
        pixel % (self.path_ends.len() - 1).max(1)
    }

    /// The kept MIS steps of path `path` (none where no steps are kept).
    fn steps_of(&self, path: usize) -> &[MisStep] {
        match self.step_ends.get(path..path + 2) {
            Some(&[start, end]) => &self.steps[start..end],
            _ => &[],
        }
    }

    /// Vertex `index` with its MIS quantities, pending terms and density factor as weights `w`
    /// give them: its path's steps re-run up to it ([`replay`]). `inv_k` as for
    /// [`MisStep::apply`].
    pub fn reweighed(
        &self,
        w: &VcmWeights,
        index: usize,
        inv_k: impl Fn(Vec3) -> Option<f32>,
    ) -> LightVertex<P> {
        // The path whose vertices begin at or before `index` and end after it.
        let path = self.path_ends.partition_point(|&start| start <= index) - 1;
        let start = self.path_ends[path];
        let mut vertex = self.vertices[index];
        let mut before = index - start;
        let at = |i: usize| inv_k(self.vertices[start + i].position);
        replay(w, self.steps_of(path), at, |mis, pending, density| {
            if before > 0 {
                before -= 1;
                return ControlFlow::Continue(());
            }
            vertex.mis = *mis;
            vertex.pending = *pending;
            vertex.rho = density.0;
            ControlFlow::Break(())
        });
        vertex
    }

    /// [`Self::for_pixel`]'s vertices in order, each [`Self::reweighed`] for weights `w`, handed
    /// to `visit` until it breaks: one walk along the path.
    pub fn reweighed_for_pixel(
        &self,
        pixel: usize,
        w: &VcmWeights,
        inv_k: impl Fn(Vec3) -> Option<f32>,
        mut visit: impl FnMut(&LightVertex<P>) -> ControlFlow<()>,
    ) {
        let vertices = self.for_pixel(pixel);
        let mut stored = vertices.iter();
        let steps = self.steps_of(self.pixel_path(pixel));
        let at = |i: usize| inv_k(vertices.get(i)?.position);
        replay(w, steps, at, |mis, pending, density| {
            let Some(&vertex) = stored.next() else {
                return ControlFlow::Break(());
            };
            visit(&LightVertex {
                mis: *mis,
                pending: *pending,
                rho: density.0,
                ..vertex
            })
        });
    }

    /// The light sub-path the eye sub-path of `pixel` connects to: the one traced for it when
    /// there is one per pixel, the paths taken in turn when there are fewer, and each pixel's own
    /// when there are more (the rest are merged and splatted only). Every eye sub-path connects
    /// to one light sub-path either way (n_VC = 1).
    pub fn for_pixel(&self, pixel: usize) -> &[LightVertex<P>] {
        let path = self.pixel_path(pixel);
        match self.path_ends.get(path..path + 2) {
            Some(&[start, end]) => &self.vertices[start..end],
            _ => &[],
        }
    }
}
