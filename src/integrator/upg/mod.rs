//! Unbiased photon gathering (000 secs. 2.4.3-2.4.6): merges made by an explicit connection from
//! the merge vertex's neighbour on the gathering side, divided by the acceptance probability
//! that tentative rays estimate without bias.
//!
//! - `acceptance.rs`: the estimate of 1/p_acc (000 eqs. 2.56-2.66), with its angular bounds;
//! - `merge.rs`: the merges from the light side (`upg`) and from the camera side
//!   (`upg-camera`), gathered and estimated together per eye vertex;
//! - `blend.rs`: `vcm-upg`, each merge made by VCM's density estimate or by UPG's gather from
//!   the light side, chosen by the length of its tentative ray;
//! - `hybrid.rs`: `upg-hybrid`, each merge gathered from the light side or the camera side as
//!   the glossiness of the merge vertex's neighbour towards the light decides, and its weights;
//! - here: [`Deferred`], the weight term of a merge that only the sub-path's next vertex can
//!   decide, and [`UpgCounters`], the tentative-ray work.

use super::mis::{Arrival, VcmVertex, VcmWeights};
use super::subpath::PendingMis;
use super::Counters;
use std::time::Duration;

pub mod acceptance;
pub mod blend;
pub mod hybrid;
pub mod merge;

/// A merge at a sub-path's previous vertex gathered from the other side (VmHere::Deferred):
/// whether it is a technique depends on the vertex reached next (the tentative rays would leave
/// from it), and its clamped eta on the pdf with which that vertex samples the merge vertex,
/// known only once a use of the vertex fixes its reverse direction (000 eqs. 2.81-2.82).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Deferred {
    /// The merge's factor in d^VC before its eta, its density factor rho included, carried
    /// like d^VC's other terms; 0 when none.
    vm: f32,
    /// mis(|cos| / d^2) of the merge vertex seen from the current vertex.
    g: f32,
    /// `upg-hybrid`'s eye sub-paths: mis(1 / p) of the area pdf with which the sub-path's own
    /// side sampled the merge vertex, for the gather from that side that the rule picks where
    /// the vertex reached is not a rough surface vertex ([`Self::settle_own`]); 0 where that
    /// side cannot gather (the vertex before the merge vertex is no non-delta surface).
    own: f32,
}

impl Deferred {
    pub const NONE: Deferred = Deferred {
        vm: 0.0,
        g: 0.0,
        own: 0.0,
    };

    /// Leaving a merge vertex whose merge is deferred: `ratio` is what [`VcmWeights::scatter`]
    /// returned, `cos_out` the |cos| of the sampled direction there, `rho` the merge's density
    /// factor (002 eq. (6); 1 without the density map).
    pub fn new(w: &VcmWeights, ratio: f32, cos_out: f32, rho: f32) -> Self {
        Deferred {
            vm: ratio * rho,
            g: w.mis(cos_out),
            own: 0.0,
        }
    }

    /// The same merge, gatherable from the sub-path's own side too, whose area pdf of the
    /// merge vertex gives `own_inv_pdf` = mis(1 / p) (a d^VCM on arrival there), 0 where that
    /// side cannot gather.
    pub fn with_own(self, own_inv_pdf: f32) -> Self {
        Deferred {
            own: own_inv_pdf,
            ..self
        }
    }

    /// `v` with the merge's terms as the gather from the sub-path's own side makes them: its
    /// eta_j from the pdf known since the merge vertex (000 eq. 2.81), no pdf of the current
    /// vertex needed; `v` unchanged where that side cannot gather.
    pub fn settle_own(&self, w: &VcmWeights, v: VcmVertex) -> VcmVertex {
        if self.vm == 0.0 || self.own == 0.0 {
            return v;
        }
        w.settle_merge(v, self.vm, self.own)
    }
}

impl PendingMis for Deferred {
    fn leaving(w: &VcmWeights, ratio: f32, cos_out: f32, rho: f32) -> Self {
        Deferred::new(w, ratio, cos_out, rho)
    }

    /// Carried across a segment, like d^VC (001 eq. (35)); the merge vertex is sampled from the
    /// far end, so its area factor takes the distance.
    fn arrive(&mut self, a: Arrival) {
        self.vm *= a.inv_cos;
        self.g /= a.d2;
    }

    /// On arrival: the merge is a technique only if the vertex reached is a non-delta surface
    /// vertex the tentative rays can leave from.
    fn keep_if(&mut self, surface: bool) {
        if !surface {
            self.vm = 0.0;
        }
    }

    /// `v` with the merge's terms added once `rev_pdf_w`, the pdf with which the current vertex
    /// samples the merge vertex, gives its gathering-side area pdf: eta_j rho in d^VC (001
    /// eq. (35), 000 eq. 2.81, 002 eq. (6)) and rho in d^VM (001 eq. (36)).
    fn settle(&self, w: &VcmWeights, v: VcmVertex, rev_pdf_w: f32) -> VcmVertex {
        if self.vm == 0.0 {
            return v;
        }
        let pdf = w.mis(rev_pdf_w) * self.g;
        w.settle_merge(v, self.vm, 1.0 / pdf)
    }
}

/// The tentative-ray work of unbiased photon gathering (000 Table 3.2).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UpgCounters {
    /// Merges whose 1/p_acc was estimated.
    pub merges: u64,
    /// Bernoulli trials, and the tentative rays traced for them (a trial whose direction
    /// misses the gathering sphere needs no ray).
    pub trials: u64,
    pub tentative_rays: u64,
    /// Tentative rays traced in packets (`--upg-packet 8`, gathers of enough merges).
    pub packet_rays: u64,
    /// Merges dropped at the trial cap.
    pub capped: u64,
    /// `vcm-upg`: merges made by density estimate instead of tentative rays.
    pub density_merges: u64,
    /// `upg-hybrid`: merges gathered from the camera side (the rest from the light side).
    pub camera_merges: u64,
}

impl std::ops::Add for UpgCounters {
    type Output = UpgCounters;
    fn add(self, other: UpgCounters) -> UpgCounters {
        UpgCounters {
            merges: self.merges + other.merges,
            trials: self.trials + other.trials,
            tentative_rays: self.tentative_rays + other.tentative_rays,
            packet_rays: self.packet_rays + other.packet_rays,
            capped: self.capped + other.capped,
            density_merges: self.density_merges + other.density_merges,
            camera_merges: self.camera_merges + other.camera_merges,
        }
    }
}

impl UpgCounters {
    const MERGES: &'static str = "upg_merges";
    const TRIALS: &'static str = "upg_trials";
    const TENTATIVE_RAYS: &'static str = "upg_tentative_rays";
    const PACKET_RAYS: &'static str = "upg_packet_rays";
    const CAPPED: &'static str = "upg_capped_merges";
    const DENSITY_MERGES: &'static str = "density_merges";
    const CAMERA_MERGES: &'static str = "upg_camera_side_merges";

    /// The counters as the integrator reports them ([`super::Integrator::counters`]).
    pub fn named(&self) -> Counters {
        Counters::new(vec![
            (Self::MERGES, self.merges),
            (Self::TRIALS, self.trials),
            (Self::TENTATIVE_RAYS, self.tentative_rays),
            (Self::PACKET_RAYS, self.packet_rays),
            (Self::CAPPED, self.capped),
            (Self::DENSITY_MERGES, self.density_merges),
            (Self::CAMERA_MERGES, self.camera_merges),
        ])
    }

    /// Reads back what [`named`](Self::named) reported; `None` unless UPG merged at all.
    pub fn from_named(counters: &Counters) -> Option<Self> {
        let get = |name| counters.get(name).unwrap_or(0);
        let upg = UpgCounters {
            merges: get(Self::MERGES),
            trials: get(Self::TRIALS),
            tentative_rays: get(Self::TENTATIVE_RAYS),
            packet_rays: get(Self::PACKET_RAYS),
            capped: get(Self::CAPPED),
            density_merges: get(Self::DENSITY_MERGES),
            camera_merges: get(Self::CAMERA_MERGES),
        };
        (upg.merges > 0).then_some(upg)
    }

    /// Metadata entries of the rates over `elapsed`; none unless UPG merged at all.
    pub fn rates(&self, elapsed: Duration) -> Vec<(String, String)> {
        if self.merges == 0 {
            return Vec::new();
        }
        let seconds = elapsed.as_secs_f64().max(1e-9);
        vec![
            (
                "upg_merges_per_second".into(),
                format!("{:.0}", self.merges as f64 / seconds),
            ),
            (
                "upg_tentative_rays_per_second".into(),
                format!("{:.0}", self.tentative_rays as f64 / seconds),
            ),
        ]
    }

    /// Metadata entries: the thesis reports about 2.81 trials per merge (000 sec. 2.4.3).
    pub fn statistics(&self) -> Vec<(String, String)> {
        let per_merge = |n: u64| format!("{:.3}", n as f64 / self.merges.max(1) as f64);
        vec![
            ("upg_merges".into(), self.merges.to_string()),
            ("upg_trials_per_merge".into(), per_merge(self.trials)),
            ("upg_rays_per_merge".into(), per_merge(self.tentative_rays)),
            ("upg_tentative_rays".into(), self.tentative_rays.to_string()),
            (
                "upg_packet_ray_share".into(),
                format!(
                    "{:.3}",
                    self.packet_rays as f64 / self.tentative_rays.max(1) as f64
                ),
            ),
            ("upg_capped_merges".into(), self.capped.to_string()),
        ]
    }
}
