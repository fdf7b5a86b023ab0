//! `upg-hybrid`: unbiased photon gathering with every merge gathered from one side, the light
//! side (`upg`) or the camera side (`upg-camera`, UPG*), chosen by a deterministic rule on the
//! path, as Qin et al. 2015 propose (000 footnote 9, sec. 5.2). A technique of its own rather
//! than an option of `upg`: plans and tables compare techniques, and its set of merge
//! techniques differs from both `upg`'s and `upg-camera`'s.
//!
//! Which side. Write a full path x_0 (light) .. x_k (camera), p_L(x_i) the area pdf with which
//! x_{i-1} samples x_i, p_E(x_i) the one with which x_{i+1} does, and prefixes p_L(x_0..x_i),
//! p_E(x_k..x_i) the sub-paths' pdfs. A merge at x_j gathered from the light side joins a light
//! sub-path to x_{j-1} with an eye sub-path to x_j, whose light vertex lands within r of x_j
//! with an acceptance probability that tentative rays from x_{j-1} estimate without bias (000
//! eqs. 2.56-2.66) and the weights approximate by min(p_L(x_j) pi r^2, 1) (000 eq. 2.80): pdf
//! p_L(x_0..x_{j-1}) p_E(x_k..x_j) n_VM min(p_L(x_j) pi r^2, 1). Gathered from the camera side
//! it is p_L(x_0..x_j) p_E(x_k..x_{j+1}) n_VM min(p_E(x_j) pi r^2, 1). Unclamped both are
//! n_VM pi r^2 p_L(x_0..x_j) p_E(x_k..x_j): the two gathers sample the same paths with the
//! same density and differ only where a clamp binds, where the neighbour that sends the
//! tentative rays samples x_j with a density above 1 / (pi r^2), as a glossy lobe does. There
//! the light-side gather keeps only p_E(x_k..x_j) p_L(x_0..x_{j-1}), no more than a connection
//! from x_{j-1}, and its explicit connection evaluates x_{j-1}'s narrow lobe towards a point the
//! lobe did not sample, so f / p_acc spikes across the disc. The merge vertex's own BSDF is
//! evaluated, never sampled, by either gather, so its roughness cannot tell them apart. Hence
//! the rule reads the neighbour: a merge at x_j is gathered from the light side where x_{j-1}
//! is a non-delta surface vertex at least `--hybrid-roughness` rough ([`Rule`]), and from the
//! camera side where x_{j-1} is smoother, a delta vertex or the light point (from which
//! `upg` could not gather at all). The light side is the default for its smoothing (000 sec.
//! 4.3): one light vertex serves many pixels.
//!
//! Weights. The rule is a function of the path, so each path has one merge technique per
//! interior vertex x_j, M_j with side c_j (or none where the neighbour on side c_j is no
//! non-delta surface vertex: [`Gather::merge_at`]), and the power heuristic over the
//! connections, the light hits and {M_j} sums to 1 (000 eq. 2.47). In 001's recursion the merge
//! at x_j enters d^VC with its own eta (001 eq. (35) with eta_j for eta_VCM) and d^VM with 1
//! (eq. (36)), and a merge at x_j weighs with eta_j (eqs. (38)-(39)), where UPG's clamp makes
//! eta_j = n_VM min(pi r^2, 1 / p(x_j)) (000 eqs. 2.81-2.82) with p = p_L for c_j = light and
//! p = p_E for c_j = camera. Both sub-paths evaluate c_j alike:
//! - the light sub-path leaving x_j knows x_{j-1}: for the light side it adds eta_j at once
//!   from its d^VCM (001 eq. (34): mis(1 / p_L(x_j))), as `upg`; for the camera side it defers
//!   the term (`super::Deferred`), as `upg-camera`, until x_{j+1} is known to be a non-delta
//!   surface vertex and a use of it fixes p_E(x_j);
//! - the eye sub-path leaving x_j does not know x_{j-1}, so it defers both: the light side's
//!   term awaiting x_{j-1}'s reverse pdf (p_L(x_j)), and the camera side's, whose
//!   mis(1 / p_E(x_j)) is its d^VCM at x_j, valid where x_{j+1} is a non-delta surface vertex
//!   ([`super::Deferred::with_own`]). Reaching x_{j-1} decides ([`decide`]): as the light
//!   point (a light hit, 001 eqs. (42)-(43)) or left through a delta lobe it is the camera
//!   side's, as a non-delta surface vertex the rule's.
//!
//! The gathers follow: at an eye vertex the light side gathers the light vertices whose
//! predecessor is rough; at the vertex an eye sub-path reaches the camera side gathers the
//! rest. At a connection each end's merge takes the side the rule gives it, its eta from its
//! own sub-path's pdf or from the other end's across the connection.

use super::super::mis::{Gather, Neighbour, Side, VcmVertex, VcmWeights};
use super::{Deferred, UpgCounters};
use crate::bsdf::microfacet::TrowbridgeReitz;
use crate::bsdf::{Bsdf, Coating, MaterialKind};

/// `upg-hybrid`'s rule: which surfaces are too glossy to send tentative rays from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule {
    /// `--hybrid-roughness`: the least roughness of a light-side gather's neighbour.
    pub threshold: f32,
}

impl Rule {
    /// Whether a non-delta surface vertex with this BSDF is glossy: its roughness
    /// ([`roughness`]) below the threshold. A function of the material alone, so the light and
    /// the eye sub-path, whose BSDFs there differ in `wo` and transport mode, agree.
    pub fn is_glossy(&self, bsdf: &Bsdf) -> bool {
        roughness(bsdf.kind()) < self.threshold
    }
}

/// Whether `rule` (`upg-hybrid`'s; `None` for every other technique, which never calls a
/// surface glossy) takes a surface with this BSDF as glossy.
pub fn glossy(rule: Option<Rule>, bsdf: &Bsdf) -> bool {
    rule.is_some_and(|rule| rule.is_glossy(bsdf))
}

/// A material's roughness as a microfacet alpha (0 smooth, 1 diffuse): the least over its
/// non-delta lobes, since one narrow lobe is enough to make the explicit connection spike.
/// Phong's exponent n maps to alpha = sqrt(2 / (n + 2)) (Walter et al. 2007's Beckmann
/// equivalent), Trowbridge-Reitz takes the geometric mean of its two alphas, a coating its top
/// interface's. Delta materials are 0. Textured roughness is not read: the material's own.
pub fn roughness(kind: &MaterialKind) -> f32 {
    let microfacet = |d: TrowbridgeReitz| {
        if d.effectively_smooth() {
            None
        } else {
            Some((d.alpha_x * d.alpha_y).sqrt().min(1.0))
        }
    };
    let top = |c: &Coating| {
        if c.is_smooth() {
            None
        } else {
            microfacet(c.top())
        }
    };
    let least = |a: Option<f32>, b: Option<f32>| match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let alpha = match kind {
        MaterialKind::Lambert { .. } | MaterialKind::DiffuseTransmission { .. } => Some(1.0),
        MaterialKind::Phong { ks, exponent, .. } => Some(if ks.is_black() {
            1.0
        } else {
            (2.0 / (exponent.max(0.0) + 2.0)).sqrt()
        }),
        MaterialKind::Mirror { .. }
        | MaterialKind::Glass { .. }
        | MaterialKind::ThinDielectric { .. } => None,
        MaterialKind::Conductor { roughness, .. } | MaterialKind::Dielectric { roughness, .. } => {
            microfacet(roughness.distribution())
        }
        // The smooth coating's reflection is a delta lobe beside the diffuse base.
        MaterialKind::CoatedDiffuse { coating, .. } => least(top(coating), Some(1.0)),
        MaterialKind::CoatedConductor {
            roughness, coating, ..
        } => least(top(coating), microfacet(roughness.distribution())),
    };
    alpha.unwrap_or(0.0)
}

/// The eye sub-path's deferred merge at its previous vertex once the vertex reached, that
/// merge vertex's neighbour towards the light, is known as `reached`: a rough surface vertex
/// keeps the light side's term (it settles with the vertex's reverse pdf, or turns to the
/// camera side's if the vertex is left through a delta lobe, [`Deferred::settle_own`]); anything
/// else takes the camera side's now.
pub fn decide(w: &VcmWeights, mis: &mut VcmVertex, pending: &mut Deferred, reached: Neighbour) {
    if Gather::Hybrid.side(reached) == Side::Camera {
        *mis = pending.settle_own(w, *mis);
        *pending = Deferred::NONE;
    }
}

/// Metadata entries: the share of merges gathered from each side.
pub fn statistics(counters: &UpgCounters) -> Vec<(String, String)> {
    let light = counters.merges.saturating_sub(counters.camera_merges);
    vec![
        ("hybrid_light_side_merges".into(), light.to_string()),
        (
            "hybrid_camera_side_merges".into(),
            counters.camera_merges.to_string(),
        ),
        (
            "hybrid_camera_side_share".into(),
            format!(
                "{:.4}",
                counters.camera_merges as f64 / counters.merges.max(1) as f64
            ),
        ),
    ]
}
