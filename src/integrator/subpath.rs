//! The sub-path state of the vertex-merging family (SmallVCM's SubPathState and PathVertex):
//! what `vcm.rs` carries while tracing and stores of light sub-paths, and what the UPG merges
//! (`upg/merge.rs`) read back. What a technique keeps per vertex beside it is a type parameter,
//! `P` (a [`PendingMis`]), so that this layer names no technique.

use super::mis::{VcmVertex, VcmWeights};
use super::IterationStats;
use crate::accel::Ray;
use crate::bsdf::{Bsdf, Normals, TransportMode};
use crate::color::Rgb;
use crate::film::{add_splats, Splats};
use crate::frame::Azimuth;
use crate::scene::{Scene, SurfaceHit};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// MIS terms a technique keeps per sub-path vertex beside its [`VcmVertex`] whose value only a
/// use of the vertex decides: a merge at the previous vertex gathered from the other side
/// (000 eqs. 2.81-2.82).
pub trait PendingMis: Copy + Send + Sync {
    /// `v`, the vertex's MIS quantities, with the pending terms added once a use of the vertex
    /// fixes `rev_pdf_w`, the pdf with which it samples its predecessor.
    fn settle(&self, w: &VcmWeights, v: VcmVertex, rev_pdf_w: f32) -> VcmVertex;
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

/// The last eye vertex, kept for `upg-camera`'s merges at the next one.
#[derive(Clone)]
pub struct EyeVertex<'b> {
    pub hit: SurfaceHit,
    pub bsdf: Bsdf<'b>,
    /// Throughput and MIS quantities on arrival, before scattering on.
    pub throughput: Rgb,
    pub mis: VcmVertex,
    pub prev_surface: bool,
    pub path_length: u32,
}

/// What one task of the light pass produces: its vertices, where each of its paths ends, its
/// camera splats and counters.
pub struct LightChunk<P> {
    pub vertices: Vec<LightVertex<P>>,
    pub ends: Vec<u32>,
    pub splats: Splats,
    pub stats: IterationStats,
}

impl<P> Default for LightChunk<P> {
    fn default() -> Self {
        LightChunk {
            vertices: Vec::new(),
            ends: Vec::new(),
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
        self.splats.clear();
        self.stats = IterationStats::default();
    }
}

/// The light sub-paths of one iteration: every stored vertex, path after path.
pub struct LightPaths<P> {
    pub vertices: Vec<LightVertex<P>>,
    /// Where each path's vertices begin, and one past the last path's.
    path_ends: Vec<usize>,
}

impl<P> Default for LightPaths<P> {
    fn default() -> Self {
        LightPaths {
            vertices: Vec::new(),
            path_ends: Vec::new(),
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
        let mut total = 0;
        for chunk in &*chunks {
            self.path_ends
                .extend(chunk.ends.iter().map(|&e| total + e as usize));
            total += chunk.vertices.len();
            stats.rays += chunk.stats.rays;
            stats.dropped_samples += chunk.stats.dropped_samples;
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
    }

    /// The light sub-path the eye sub-path of `pixel` connects to: the one traced for it when
    /// there is one per pixel, the paths taken in turn when there are fewer, and each pixel's own
    /// when there are more (the rest are merged and splatted only). Every eye sub-path connects
    /// to one light sub-path either way (n_VC = 1).
    pub fn for_pixel(&self, pixel: usize) -> &[LightVertex<P>] {
        let path = pixel % (self.path_ends.len() - 1).max(1);
        match self.path_ends.get(path..path + 2) {
            Some(&[start, end]) => &self.vertices[start..end],
            _ => &[],
        }
    }
}
