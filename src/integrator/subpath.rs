//! The sub-path state of the vertex-merging family (SmallVCM's SubPathState and PathVertex):
//! what `vcm.rs` carries while tracing and stores of light sub-paths, and what the UPG merges
//! (`upg/merge.rs`) read back.

use super::mis::{VcmVertex, VcmWeights};
use super::upg::Deferred;
use crate::accel::Ray;
use crate::bsdf::{Bsdf, TransportMode};
use crate::color::Rgb;
use crate::scene::{Scene, SurfaceHit};
use glam::Vec3;

/// A stored light sub-path vertex: everything a connection or a merge needs (68 bytes).
#[derive(Clone, Copy, Debug)]
pub struct LightVertex {
    pub position: Vec3,
    /// Geometric normal.
    pub ng: Vec3,
    /// Unit direction back towards the previous vertex of the light sub-path.
    pub wo: Vec3,
    pub throughput: Rgb,
    pub material: u32,
    /// Segments from the light to this vertex.
    pub path_length: u32,
    pub mis: VcmVertex,
    /// `upg-camera`'s merge at the previous vertex, awaiting this one's reverse pdf.
    pub deferred: Deferred,
    /// The previous vertex of the sub-path is a non-delta surface vertex, stored just before
    /// this one.
    pub after_surface: bool,
}

impl LightVertex {
    /// The vertex's BSDF, as the light sub-path scattered there.
    pub fn bsdf<'s>(&self, scene: &'s Scene) -> Option<Bsdf<'s>> {
        let material = &scene.material(self.material).kind;
        Bsdf::new(material, self.ng, self.wo, TransportMode::Importance)
    }

    /// The MIS quantities once a use of the vertex fixes `rev_pdf_w`, the pdf with which it
    /// samples its predecessor.
    pub fn mis_at(&self, w: &VcmWeights, rev_pdf_w: f32) -> VcmVertex {
        self.deferred.settle(w, self.mis, rev_pdf_w)
    }
}

/// The state of a sub-path being traced.
#[derive(Clone, Copy, Debug)]
pub struct SubPath {
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
    /// A UPG merge at the previous vertex gathered from the other side (`upg` on eye
    /// sub-paths, `upg-camera` on light sub-paths).
    pub deferred: Deferred,
}

impl SubPath {
    /// [`LightVertex::mis_at`] of the sub-path's current vertex.
    pub fn mis_at(&self, w: &VcmWeights, rev_pdf_w: f32) -> VcmVertex {
        self.deferred.settle(w, self.mis, rev_pdf_w)
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
