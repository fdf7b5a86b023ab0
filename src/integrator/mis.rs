//! Multiple importance sampling weights of the bidirectional techniques, in one place.
//!
//! Two recursive schemes, kept apart on purpose (000 ch. 3.1 cross-checks BPT against VCM):
//!
//! - [`BptVertex`]: the partial sums a_i, A_i (camera side c_i, C_i) of 000 eqs. (2.50)-(2.51),
//!   used by `bpt.rs`. They turn the power-heuristic weight of 000 eq. (2.47) into O(1) work per
//!   connection.
//! - [`VcmVertex`] and [`VcmWeights`]: SmallVCM's d^VCM, d^VC, d^VM of 001 eqs. (31)-(47), used
//!   by `vcm.rs` for `vcm`, `bpm`, `ppm`, `lt`, `upg`, `upg-camera` and `upg-hybrid` (UPG with
//!   the clamped acceptance of 000 eqs. (2.80)-(2.82)), with 002's density factors where asked.
//!
//! Every quantity is stored "with the power already applied": `mis(x) = x^beta`, applied to
//! each factor, so products and the ratio sums stay what 000 eq. (2.48) writes.
//! Russian roulette stays out of the pdfs: every technique evaluates the same pdfs, so the
//! weights still sum to one.

use crate::options::DensityMis;
use crate::sampling::mis_power;

/// The MIS power beta (1 = balance heuristic, 2 = power heuristic).
#[derive(Clone, Copy, Debug)]
pub struct Power(pub f32);

impl Power {
    #[inline]
    pub fn mis(self, x: f32) -> f32 {
        mis_power(x, self.0)
    }
}

/// The step that sampled sub-path vertex v_i from v_{i-1}, as the BPT recursion needs it.
/// Delta (specular) pdfs cancel between the two directions at a vertex (001 sec. 5.3), so a
/// delta vertex reports pdfs of 1 and `prev_connectable = false`.
#[derive(Clone, Copy, Debug)]
pub struct BptStep {
    /// Solid-angle pdf with which v_{i-1} sampled the direction to v_i.
    pub pdf_w: f32,
    /// Solid-angle pdf with which v_{i-1} would sample the direction to v_{i-2}, given the
    /// direction to v_i (unused when v_{i-1} is the light point or the camera).
    pub rev_pdf_w: f32,
    /// Area-to-solid-angle factor at v_i: |cos at v_i| / d^2, or |cos at v_i| when v_{i-1} is
    /// at infinity (directional light, sky), so that pdf_w * g is v_i's area pdf.
    pub g: f32,
    /// The same factor at v_{i-1} for sampling it from v_i: |cos at v_{i-1}| / d^2, or 1 for an
    /// infinite light.
    pub g_rev: f32,
    /// A technique can end a sub-path at v_{i-1}: false for delta BSDFs. Light points and the
    /// pinhole camera can always be connected to (light sampling, light tracing).
    pub prev_connectable: bool,
}

/// The BPT partial sums of one sub-path vertex (000 eq. (2.51)).
///
/// For a light sub-path y_0..y_i the ratio sum of the techniques that end the light sub-path
/// earlier, sum_{k=0}^{i} prod_{j=k}^{i} p_rev(y_j) / p_fwd(y_j) (000 eq. (2.48)), is
/// `(big_a * mis(q_rev) + a) * mis(p_rev(y_i))` once a connection fixes q_rev (the pdf at y_i
/// back towards y_{i-1}) and p_rev(y_i) (the area pdf of sampling y_i from the other side). The
/// camera sub-path keeps the same sums (000's c_i, C_i) with c_0 = C_0 = 0: no technique hits
/// the pinhole.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BptVertex {
    /// a_i = mis(1 / p_fwd(v_i)) when the technique connecting v_{i-1} to v_i exists, else 0.
    pub a: f32,
    /// A_i = (A_{i-1} mis(q_rev(v_{i-2})) + a_{i-1}) mis(g_rev(v_{i-1})) a_i (000 eq. (2.51)),
    /// with a_{i-1} left out when v_{i-1} cannot be connected to.
    pub big_a: f32,
}

impl BptVertex {
    /// y_0, a point on a light picked with area pdf `direct_pdf_a` (solid angle for the sky).
    /// A delta light cannot be hit, so no technique ends there: a_0 = 0.
    pub fn light_origin(power: Power, direct_pdf_a: f32, hittable: bool) -> Self {
        BptVertex {
            a: if hittable {
                power.mis(1.0 / direct_pdf_a)
            } else {
                0.0
            },
            big_a: 0.0,
        }
    }

    /// z_0, the pinhole: c_0 = C_0 = 0 (000 eq. (2.51)).
    pub fn camera_origin() -> Self {
        BptVertex::default()
    }

    /// v_i from v_{i-1} = `self` (000 eq. (2.51)).
    pub fn next(&self, power: Power, step: &BptStep) -> Self {
        let a_i = power.mis(1.0 / (step.pdf_w * step.g));
        let a_prev = if step.prev_connectable { self.a } else { 0.0 };
        BptVertex {
            a: if step.prev_connectable { a_i } else { 0.0 },
            big_a: (self.big_a * power.mis(step.rev_pdf_w) + a_prev) * power.mis(step.g_rev) * a_i,
        }
    }

    /// The ratio sum of one side of 000 eq. (2.50) at a connection: `rev_pdf_w` is the pdf at
    /// this vertex back along its sub-path given the connection direction, `rev_pdf_a` the
    /// area pdf with which the other side samples this vertex.
    pub fn ratio_sum(&self, power: Power, rev_pdf_w: f32, rev_pdf_a: f32) -> f32 {
        (self.big_a * power.mis(rev_pdf_w) + self.a) * power.mis(rev_pdf_a)
    }
}

/// The weight of a technique from the ratio sums of its two sides (000 eq. (2.50)).
pub fn bpt_weight(light_side: f32, eye_side: f32) -> f32 {
    1.0 / (light_side + 1.0 + eye_side)
}

/// The BPT weight of an eye sub-path that reaches a light (s = 0): `eye` is the vertex on the
/// light, the pdfs are the light's with its pick probability. The light side is empty; the eye
/// side's other techniques start the path at this light point instead: with area pdf
/// `direct_pdf_a`, then leaving it towards the previous eye vertex with solid-angle pdf
/// `emission_pdf_w / direct_pdf_a`.
pub fn bpt_hit_light(power: Power, eye: &BptVertex, direct_pdf_a: f32, emission_pdf_w: f32) -> f32 {
    bpt_weight(
        0.0,
        eye.ratio_sum(power, emission_pdf_w / direct_pdf_a, direct_pdf_a),
    )
}

/// The pdfs of light sampling (s = 1) at an eye vertex, as both weight schemes need them.
#[derive(Clone, Copy, Debug)]
pub struct LightSamplePdfs {
    /// The eye vertex's BSDF towards the light point, and back along the eye sub-path.
    pub bsdf_pdf_w: f32,
    pub bsdf_rev_pdf_w: f32,
    /// The pick probability times the light point's solid-angle pdf at the receiver.
    pub light_pdf_w: f32,
    /// The light's own pdfs of the point (per solid angle at the receiver) and of emitting
    /// towards the receiver, without the pick.
    pub direct_pdf_w: f32,
    pub emission_pdf_w: f32,
    /// |cos| at the receiver and at the light point (1 for infinite lights).
    pub cos_at_receiver: f32,
    pub cos_at_light: f32,
    pub delta_light: bool,
}

impl LightSamplePdfs {
    /// The area pdf with which the light, emitting from its point, samples the eye vertex,
    /// relative to the light point's own: what the eye side's ratio sums multiply.
    fn eye_rev_pdf_a(&self) -> f32 {
        self.emission_pdf_w * self.cos_at_receiver / (self.direct_pdf_w * self.cos_at_light)
    }
}

/// The BPT weight of light sampling (s = 1) at eye vertex `eye`.
pub fn bpt_light_sample(power: Power, eye: &BptVertex, p: &LightSamplePdfs) -> f32 {
    // a_0 mis(p_rev(y_0)) with a_0 = 1 / (pick pdf_a) and p_rev(y_0) = bsdf_pdf_w cos_light / d^2:
    // in solid angle at the receiver, the ratio of the two pdfs of choosing the light point.
    let light_side = if p.delta_light {
        0.0
    } else {
        power.mis(p.bsdf_pdf_w / p.light_pdf_w)
    };
    // The light samples the eye vertex by leaving its point with the emission's direction pdf.
    bpt_weight(
        light_side,
        eye.ratio_sum(power, p.bsdf_rev_pdf_w, p.eye_rev_pdf_a()),
    )
}

/// The pdfs of a connection between a light vertex and an eye vertex (s, t >= 2).
#[derive(Clone, Copy, Debug)]
pub struct ConnectionPdfs {
    /// Each end's solid-angle pdf back along its own sub-path, given the connection.
    pub light_rev_pdf_w: f32,
    pub eye_rev_pdf_w: f32,
    /// The light vertex's area pdf when the eye vertex samples it, and the other way round.
    pub light_pdf_a: f32,
    pub eye_pdf_a: f32,
}

/// The BPT weight of a connection between light vertex `light` and eye vertex `eye`.
pub fn bpt_connect(power: Power, light: &BptVertex, eye: &BptVertex, p: &ConnectionPdfs) -> f32 {
    bpt_weight(
        light.ratio_sum(power, p.light_rev_pdf_w, p.light_pdf_a),
        eye.ratio_sum(power, p.eye_rev_pdf_w, p.eye_pdf_a),
    )
}

/// The BPT weight of a light vertex connected to the camera (t = 1): `camera_pdf_a` is the
/// vertex's area pdf as the camera samples it for one pixel, shared by the `light_paths` light
/// sub-paths that splat into every pixel (SmallVCM's convention, 001 eq. (46)).
pub fn bpt_to_camera(
    power: Power,
    light: &BptVertex,
    rev_pdf_w: f32,
    camera_pdf_a: f32,
    light_paths: f32,
) -> f32 {
    bpt_weight(
        light.ratio_sum(power, rev_pdf_w, camera_pdf_a / light_paths),
        0.0,
    )
}

/// How the merges of a technique are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gather {
    /// Density estimation around the eye vertex (`vcm`, `bpm`, `ppm`; 001 eq. (20)).
    Density,
    /// `upg`: the light vertex's predecessor is connected to the eye vertex, and the tentative
    /// rays leave from that predecessor (000 sec. 2.4.3).
    UpgLight,
    /// `upg-camera`: the eye vertex's predecessor is connected to the light vertex (UPG*).
    UpgCamera,
    /// `vcm-upg`: density estimation or `upg`'s gather, chosen per merge (`upg/blend.rs`).
    Blend,
    /// `upg-hybrid`: `upg`'s gather where the merge vertex's neighbour towards the light is a
    /// rough surface vertex, `upg-camera`'s elsewhere (`upg/hybrid.rs`).
    Hybrid,
}

/// The side whose sub-path sends the tentative rays of a merge, whose area pdf of the merge
/// vertex its clamped eta takes (000 eqs. 2.81-2.82).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Light,
    Camera,
}

/// What lies next to a vertex along the path, on one side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Neighbour {
    /// A non-delta surface vertex: tentative rays can leave from it.
    Surface,
    /// A non-delta surface vertex smoother than `upg-hybrid`'s threshold: tentative rays could
    /// leave from it, but that technique gathers from the other side of its neighbours. Every
    /// other technique takes it as [`Neighbour::Surface`].
    Glossy,
    /// The light point: a light sub-path's origin, or what light sampling and a light hit
    /// reach.
    Light,
    /// The camera or a delta vertex.
    Other,
    /// Not traced yet: the sub-path has not gone on from here.
    Unknown,
}

impl Neighbour {
    pub fn surface_if(surface: bool) -> Self {
        if surface {
            Neighbour::Surface
        } else {
            Neighbour::Other
        }
    }

    /// A surface vertex as `upg-hybrid`'s rule classes it: [`Neighbour::Glossy`] when
    /// `glossy`, else unchanged.
    pub fn glossy_if(self, glossy: bool) -> Self {
        match self {
            Neighbour::Surface if glossy => Neighbour::Glossy,
            other => other,
        }
    }

    /// What lies towards the light from a light sub-path's vertex `path_length` segments from
    /// the light, whose predecessor is a non-delta surface vertex when `after_surface`.
    pub fn towards_light(path_length: u32, after_surface: bool) -> Self {
        if path_length == 1 {
            Neighbour::Light
        } else {
            Neighbour::surface_if(after_surface)
        }
    }
}

/// Whether merging at a (non-delta) vertex is one of the techniques.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VmHere {
    Valid,
    Invalid,
    /// Decided by a neighbour not traced yet: UPG keeps the merge's term aside (the sub-path's
    /// pending MIS terms) until the sub-path's next vertex decides it.
    Deferred,
}

impl Gather {
    /// The one rule for where a merge is a technique, given the merge vertex's neighbours
    /// towards the light and towards the eye. A density estimate merges at every non-delta
    /// vertex; unbiased photon gathering needs the neighbour on its gathering side to be a
    /// non-delta surface vertex, since the tentative rays leave from it (000 sec. 2.4.3).
    /// `vcm-upg` merges everywhere but next to the light point: those merges neither tentative
    /// rays can make nor a density estimate without its bias, and light sampling makes every
    /// path they would.
    /// `upg-hybrid` gathers each merge from one side, [`Self::side`]: a function of the path,
    /// so both sub-paths decide alike, deferring where the neighbour is not traced yet.
    pub fn merge_at(self, light_side: Neighbour, eye_side: Neighbour) -> VmHere {
        let neighbour = match self {
            Gather::Density => return VmHere::Valid,
            Gather::UpgLight => light_side,
            Gather::UpgCamera => eye_side,
            Gather::Blend => {
                return match light_side {
                    Neighbour::Light => VmHere::Invalid,
                    Neighbour::Unknown => VmHere::Deferred,
                    Neighbour::Surface | Neighbour::Glossy | Neighbour::Other => VmHere::Valid,
                }
            }
            Gather::Hybrid => match light_side {
                Neighbour::Unknown => return VmHere::Deferred,
                _ => match self.side(light_side) {
                    Side::Light => light_side,
                    Side::Camera => eye_side,
                },
            },
        };
        match neighbour {
            Neighbour::Surface | Neighbour::Glossy => VmHere::Valid,
            Neighbour::Light | Neighbour::Other => VmHere::Invalid,
            Neighbour::Unknown => VmHere::Deferred,
        }
    }

    /// The side that gathers a merge whose vertex has `light_side` next to it towards the
    /// light (known). `upg-hybrid` gathers from the light side where that neighbour is a rough
    /// surface vertex, and from the camera side where it is glossy, delta or the light point,
    /// from which `upg` could not gather at all.
    pub fn side(self, light_side: Neighbour) -> Side {
        match self {
            Gather::UpgCamera => Side::Camera,
            Gather::Hybrid if light_side != Neighbour::Surface => Side::Camera,
            _ => Side::Light,
        }
    }

    /// Whether the techniques' weights are UPG's clamped ones (000 eqs. 2.80-2.82).
    pub fn clamps(self) -> bool {
        matches!(self, Gather::UpgLight | Gather::UpgCamera | Gather::Hybrid)
    }
}

/// Per-iteration constants of the VCM weights (001 eqs. (20)-(22) and sec. 5.5-5.6).
///
/// The merge at vertex x_j weighs eta_j = n_VM p_acc(x_j) / p(x_j) against the connections,
/// with p_acc approximated by p(x_j) pi r^2 (001 eq. (21)), so eta is one number, eta_VCM. UPG
/// clamps the approximation to min(p(x_j) pi r^2, 1) (000 eq. 2.80), so eta_j =
/// n_VM min(pi r^2, 1 / p(x_j)) depends on the area pdf p(x_j) with which the gathering side
/// samples the merge vertex (000 eqs. 2.81-2.82). Weights are kept in the form where every
/// merge term carries its own eta: d^VC accumulates eta_i at each vertex it passes
/// (001 eq. (35) with eta_i for eta_VCM), and a merge divides by its eta_j.
#[derive(Clone, Copy, Debug)]
pub struct VcmWeights {
    pub power: Power,
    /// n_VC: light sub-paths per iteration, one per pixel.
    pub light_paths: f32,
    pub radius: f32,
    /// mis(eta_VCM) when both VC and VM run, else 0 (001 sec. 5.5-5.6).
    pub vm_factor: f32,
    /// mis(1 / eta_VCM) when both VC and VM run, else 0.
    pub vc_factor: f32,
    /// 1 / (pi r^2 n_VM): the density estimate's normalisation.
    pub vm_normalization: f32,
    /// UPG's clamped acceptance (000 eq. 2.80): mis(pi r^2) and mis(n_VM); `None` for VCM.
    clamp: Option<(f32, f32)>,
    /// 002's heuristic, when the density map has data.
    density: Option<DensityMis>,
    /// Connections are techniques: false for merge-only UPG, whose d^VC then sums the merges'
    /// eta_i alone.
    connections: bool,
    /// VCM's weights with eta_VCM left out ([`Self::radius_free`]).
    radius_free: bool,
}

/// The density factor and 1 / k of a merge where 002's heuristic is off (VCM, UPG).
pub const NO_DENSITY: (f32, f32) = (1.0, 0.0);

/// The geometry factors of arriving at a vertex, mis(d^2) and 1 / mis(|cos|), for whatever
/// else a sub-path carries across the segment.
#[derive(Clone, Copy, Debug)]
pub struct Arrival {
    pub d2: f32,
    pub inv_cos: f32,
}

impl VcmWeights {
    /// eta_VCM = pi r^2 n_VM / n_VC with n_VM = n_VC = `light_paths` (001 eq. (21)).
    pub fn new(power: Power, radius: f32, light_paths: f32, vc: bool, vm: bool) -> Self {
        let eta_vcm = std::f32::consts::PI * radius * radius * light_paths;
        let both = vc && vm;
        VcmWeights {
            power,
            light_paths,
            radius,
            vm_factor: if both { power.mis(eta_vcm) } else { 0.0 },
            vc_factor: if both { power.mis(1.0 / eta_vcm) } else { 0.0 },
            vm_normalization: 1.0 / eta_vcm,
            clamp: None,
            connections: true,
            density: None,
            radius_free: false,
        }
    }

    /// The same weights at another radius: what an eye sub-path of its own radius weighs with
    /// (001 sec. 6.1), UPG's clamp and 002's density factors included. Radius-free weights
    /// ([`Self::radius_free`]) become VCM's at that radius. UPG's clamp and 002's density
    /// factors are not linear in eta_VCM, so light sub-paths weighed with them cannot leave it
    /// out: their recursion is re-run at this radius instead ([`super::subpath::replay`]).
    pub fn at_radius(&self, radius: f32) -> Self {
        let both = self.vm_factor > 0.0 || self.radius_free;
        let area = std::f32::consts::PI * radius * radius;
        VcmWeights {
            clamp: self.clamp.map(|(_, paths)| (self.power.mis(area), paths)),
            density: self.density,
            connections: self.connections,
            ..VcmWeights::new(self.power, radius, self.light_paths, both, both)
        }
    }

    /// The weights light sub-paths are traced with when every eye sub-path has its own radius
    /// (001 sec. 6.1): with eta_VCM left out (as BPT's, 001 sec. 5.5), the recursion of
    /// d^VC and d^VM is that of c^VC and c^VM (001 eqs. (56)-(61)): every connection term
    /// in d^VC and every merge term, without its eta_VCM, in d^VM. [`Self::resolve`] applies
    /// an eye sub-path's eta_VCM once a technique joins the two.
    pub fn radius_free(self) -> Self {
        VcmWeights {
            vm_factor: 0.0,
            vc_factor: 0.0,
            radius_free: self.vm_factor > 0.0,
            ..self
        }
    }

    /// d^VC and d^VM at this radius of a light vertex whose quantities are c^VC and c^VM
    /// ([`Self::radius_free`]): 001 eqs. (62)-(63), in the powered form mis(eta_VCM) c^VM.
    /// Without connections (bpm) eta_VCM is 0 and d^VM is c^VM.
    pub fn resolve(&self, c: &VcmVertex) -> VcmVertex {
        VcmVertex {
            d_vc: c.d_vc + self.vm_factor * c.d_vm, // 001 eq. (62)
            d_vm: c.d_vc * self.vc_factor + c.d_vm, // 001 eq. (63)
            ..*c
        }
    }

    /// VCM's weights with 002's heuristic. A merge at x_i weighs c_i = n_VM / k_i light
    /// sub-paths instead of n_VM (VCM+, 002 eq. (6)), with k_i the expected number of light
    /// vertices within r of x_i, clamped to [1, n_VM]; so eta_i = eta_VCM / k_i, and in the
    /// powered form mis(eta_i) = mis(eta_VCM) rho_i with rho_i = mis(1 / k_i), which callers
    /// pass as the merge's `rho`.
    ///
    /// VCM* (002 eq. (7)) divides every c_i of a path by the mean 1/k over the path's
    /// non-delta surface vertices, M = S / C with S = sum_j 1/k_j and C their count. The
    /// factor mis(1 / M) is common to all merge terms of one path, and the power heuristic
    /// factorises, so every weight is VCM+'s with its merge terms multiplied by
    /// nu = mis(C / S). Its recursion is 001's with d^VC split: the connection part d^VC
    /// (001 eq. (35) without eta_i) and the merge part d^VC_VM (the eta_i terms alone), both
    /// carried by the same products, so d^VC of VCM+ = d^VC + d^VC_VM and VCM*'s is
    /// d^VC + nu d^VC_VM. Each sub-path carries its own S and C ([`Self::visit`]); a weight
    /// adds the two sub-paths' (counting a merge vertex once) and applies nu.
    /// Without connections (bpm) only merges compete, nu cancels and VCM* is VCM+.
    ///
    /// UPG's clamped merges (000 eqs. 2.80-2.82) take the same factors. 002 eq. (6) counts
    /// c_j = n_VM / k_j light sub-paths at a merge at x_j where VCM counts n_VM, and 000
    /// eq. 2.80 clamps each sub-path's acceptance to min(p(x_j) pi r^2, 1); so the merge's
    /// eta_j = c_j min(pi r^2, 1 / p(x_j)) = (n_VM / k_j) min(pi r^2, 1 / p(x_j)), in the
    /// powered form mis(eta_j) = [`Self::eta`] rho_j: the clamp and the density factor multiply,
    /// and every term that carries the merge, deferred ones included ([`Self::settle_merge`]),
    /// carries both. VCM*'s normalisation over the path (002 eq. (7)) is VCM's: the factor
    /// common to a path's merge terms, applied as nu. A UPG merge joins its two sub-paths at
    /// one vertex, the eye vertex (`upg`) or the light vertex (`upg-camera`): the sub-path
    /// carried across the explicit connection arrives there and counts it, as both
    /// sub-paths of a density estimate count theirs, and [`Self::merge`] counts it once.
    pub fn with_density(self, density: DensityMis) -> Self {
        VcmWeights {
            density: Some(density),
            ..self
        }
    }

    /// UPG's weights: both VC and VM, each merge's acceptance clamped to 1 (000 eq. 2.80).
    pub fn clamped(power: Power, radius: f32, light_paths: f32) -> Self {
        let area = std::f32::consts::PI * radius * radius;
        VcmWeights {
            clamp: Some((power.mis(area), power.mis(light_paths))),
            ..VcmWeights::new(power, radius, light_paths, true, true)
        }
    }

    /// Merge-only UPG (000 sec. 5.2): the clamped merges weighed against each other alone. A
    /// connection's term (d^VCM in d^VC and in a merge's weight) and the light origin's (the
    /// eye sub-path hitting the light) drop out; the merges' eta_i stay.
    pub fn clamped_merges_only(power: Power, radius: f32, light_paths: f32) -> Self {
        VcmWeights {
            connections: false,
            ..VcmWeights::clamped(power, radius, light_paths)
        }
    }

    /// d^VCM as a connection's term in d^VC and in a merge's weight: 0 without connections.
    #[inline]
    fn connection_term(&self, d_vcm: f32) -> f32 {
        if self.connections {
            d_vcm
        } else {
            0.0
        }
    }

    #[inline]
    pub fn mis(&self, x: f32) -> f32 {
        self.power.mis(x)
    }

    /// mis(eta_j) of a merge at a vertex whose gathering-side area pdf p gives
    /// `inv_pdf` = mis(1 / p) (a d^VCM on arrival): n_VM min(pi r^2, 1 / p) (000 eq. 2.81).
    pub fn eta(&self, inv_pdf: f32) -> f32 {
        match self.clamp {
            Some((area, paths)) => paths * area.min(inv_pdf),
            None => self.vm_factor,
        }
    }

    /// [`Self::eta`] for a merge that may not be a technique.
    pub fn eta_if(&self, valid: bool, inv_pdf: f32) -> f32 {
        if valid {
            self.eta(inv_pdf)
        } else {
            0.0
        }
    }

    /// mis(eta_j) of the merge at a connection's end x_j on sub-path side `own`, whose
    /// neighbour towards the light is `behind` (000 eqs. 2.80-2.82 under UPG's clamp): the
    /// gathering side's area pdf of x_j is the end's own sub-path's, its d^VCM `own_d_vcm`
    /// (001 eq. (34)), where that side gathers, else the other end's across the connection,
    /// `across_pdf_a`.
    pub fn end_eta(
        &self,
        gather: Gather,
        valid: bool,
        (own, behind): (Side, Neighbour),
        own_d_vcm: f32,
        across_pdf_a: f32,
    ) -> f32 {
        let inv_pdf = if gather.clamps() && gather.side(behind) != own {
            self.mis(1.0 / across_pdf_a)
        } else {
            own_d_vcm
        };
        self.eta_if(valid, inv_pdf)
    }

    /// A non-delta surface vertex with 1 / k = `inv_k` joins the sub-path's VCM* mean.
    pub fn visit(&self, v: &mut VcmVertex, inv_k: f32) {
        if self.density == Some(DensityMis::Star) {
            v.inv_k_sum += inv_k;
            v.vertices += 1.0;
        }
    }

    /// The density factor rho = mis(1 / k) of a merge at a non-delta surface vertex and its
    /// 1 / k = `inv_k` (002 eq. (6)), the vertex joining `v`'s VCM* mean ([`Self::visit`]);
    /// [`NO_DENSITY`] without the density map (`None`).
    pub fn density_at(&self, v: &mut VcmVertex, inv_k: Option<f32>) -> (f32, f32) {
        match inv_k {
            Some(inv_k) => {
                self.visit(v, inv_k);
                (self.mis(inv_k), inv_k)
            }
            None => NO_DENSITY,
        }
    }

    /// `v` with the terms of a merge that a later step decided (UPG's deferred merges, 000
    /// eqs. 2.81-2.82): `factor` is its term in d^VM (001 eq. (36)), the products carried since
    /// the merge vertex with its density factor rho, and `inv_pdf` = mis(1 / p) of the merge
    /// vertex's gathering-side area pdf gives its eta_j in d^VC (001 eq. (35)), among VCM*'s
    /// merge terms.
    pub fn settle_merge(&self, v: VcmVertex, factor: f32, inv_pdf: f32) -> VcmVertex {
        let eta = factor * self.eta(inv_pdf);
        if self.density == Some(DensityMis::Star) {
            VcmVertex {
                d_vc_vm: v.d_vc_vm + eta,
                d_vm: v.d_vm + factor,
                ..v
            }
        } else {
            VcmVertex {
                d_vc: v.d_vc + eta,
                d_vm: v.d_vm + factor,
                ..v
            }
        }
    }

    /// VCM*'s nu = mis(C / S) of a path whose vertices give `inv_k_sum` = S and `vertices` = C
    /// (002 eq. (7)); 1 otherwise, and for paths with no surface vertex to merge at.
    fn nu(&self, inv_k_sum: f32, vertices: f32) -> f32 {
        if self.density == Some(DensityMis::Star) && vertices > 0.0 && inv_k_sum > 0.0 {
            self.mis(vertices / inv_k_sum)
        } else {
            1.0
        }
    }

    /// d^VC of a sub-path vertex with VCM*'s merge terms multiplied by `nu`.
    fn d_vc(v: &VcmVertex, nu: f32) -> f32 {
        v.d_vc + nu * v.d_vc_vm
    }

    /// y_0 on a light (sec. 5.1-5.2 for infinite and delta lights). `cos_at_light` is 1 for
    /// infinite lights.
    pub fn light_origin(
        &self,
        direct_pdf_a: f32,
        emission_pdf_w: f32,
        cos_at_light: f32,
        delta: bool,
    ) -> VcmVertex {
        // 001 eq. (32); a delta light cannot be hit, so no technique weighs against it (sec. 5.2).
        let d_vc = if delta || !self.connections {
            0.0
        } else {
            self.mis(cos_at_light / emission_pdf_w)
        };
        VcmVertex {
            d_vcm: self.mis(direct_pdf_a / emission_pdf_w), // 001 eq. (31)
            d_vc,
            d_vm: d_vc * self.vc_factor, // 001 eq. (33)
            ..VcmVertex::default()
        }
    }

    /// z_0, the camera, with `camera_pdf_w` its per-pixel solid-angle pdf of the primary ray
    /// (001 eqs. (31)-(33) with p_0^connect = p_0^trace: d^VC = d^VM = 0).
    pub fn camera_origin(&self, camera_pdf_w: f32) -> VcmVertex {
        VcmVertex {
            d_vcm: self.mis(self.light_paths / camera_pdf_w),
            ..VcmVertex::default()
        }
    }

    /// Arrival at a new vertex at `distance` with |cos| `cos_in`: the geometry part of 001
    /// eqs. (34)-(36). The first segment from an infinite light has no distance term
    /// (001 sec. 5.1): `with_distance = false`.
    pub fn arrive(
        &self,
        v: &mut VcmVertex,
        distance: f32,
        cos_in: f32,
        with_distance: bool,
    ) -> Arrival {
        let d2 = if with_distance {
            self.mis(distance * distance)
        } else {
            1.0
        };
        let inv_cos = 1.0 / self.mis(cos_in);
        v.d_vcm *= d2 * inv_cos; // 001 eq. (34)
        v.d_vc *= inv_cos; // 001 eq. (35)
        v.d_vc_vm *= inv_cos;
        v.d_vm *= inv_cos; // 001 eq. (36)
        Arrival { d2, inv_cos }
    }

    /// Scattering at a vertex: the sampling part of 001 eqs. (34)-(36). `pdf_w` the pdf of the
    /// sampled direction, `rev_pdf_w` of the reverse, `cos_out` at the sampled direction;
    /// `merge_here` whether merging at this vertex is a technique, its terms eta_i rho in d^VC
    /// and rho in d^VM (`rho` the density factor, [`Self::with_density`]; 1 for VCM and UPG).
    /// Returns mis(cos_out / pdf_w), the factor a merge term at this vertex takes.
    pub fn scatter(
        &self,
        v: &mut VcmVertex,
        cos_out: f32,
        pdf_w: f32,
        rev_pdf_w: f32,
        delta: bool,
        (merge_here, rho): (bool, f32),
    ) -> f32 {
        if delta {
            // 001 sec. 5.3: delta pdfs cancel; only the cosine ratio survives.
            let cos = self.mis(cos_out);
            v.d_vcm = 0.0;
            v.d_vc *= cos;
            v.d_vc_vm *= cos;
            v.d_vm *= cos;
            return 0.0;
        }
        let ratio = self.mis(cos_out / pdf_w);
        let (eta, here) = if merge_here {
            (self.eta(v.d_vcm) * rho, rho)
        } else {
            (0.0, 0.0)
        };
        let rev = self.mis(rev_pdf_w);
        if self.density == Some(DensityMis::Star) {
            v.d_vc = ratio * (v.d_vc * rev + self.connection_term(v.d_vcm)); // 001 eq. (35), connection terms
            v.d_vc_vm = ratio * (v.d_vc_vm * rev + eta); // 001 eq. (35), merge terms
        } else {
            v.d_vc = ratio * (v.d_vc * rev + self.connection_term(v.d_vcm) + eta);
            // 001 eq. (35)
        }
        v.d_vm = ratio * (v.d_vm * rev + v.d_vcm * self.vc_factor + here); // 001 eq. (36)
        v.d_vcm = self.mis(1.0 / pdf_w); // 001 eq. (34)
        ratio
    }

    /// An eye sub-path hits a light (s = 0; 001 eqs. (42)-(43)); the pdfs include the light's
    /// pick probability. The light point is no vertex to merge at.
    pub fn hit_light(&self, eye: &VcmVertex, direct_pdf_a: f32, emission_pdf_w: f32) -> f32 {
        let nu = self.nu(eye.inv_k_sum, eye.vertices);
        let w_camera =
            self.mis(direct_pdf_a) * eye.d_vcm + self.mis(emission_pdf_w) * Self::d_vc(eye, nu);
        1.0 / (1.0 + w_camera)
    }

    /// Light sampling (s = 1; 001 eqs. (44)-(45)); `eye_eta` is the merge at the eye vertex
    /// ([`Self::eta_if`] times its density factor).
    pub fn light_sample(&self, eye: &VcmVertex, eye_eta: f32, p: &LightSamplePdfs) -> f32 {
        let nu = self.nu(eye.inv_k_sum, eye.vertices);
        let w_light = if p.delta_light {
            0.0
        } else {
            self.mis(p.bsdf_pdf_w / p.light_pdf_w) // 001 eq. (44)
        };
        let w_camera = self.mis(p.eye_rev_pdf_a())
            * (eye_eta * nu + eye.d_vcm + Self::d_vc(eye, nu) * self.mis(p.bsdf_rev_pdf_w)); // 001 eq. (45)
        1.0 / (w_light + 1.0 + w_camera)
    }

    /// Connection of a light vertex and an eye vertex (s, t > 1; 001 eqs. (40)-(41)), with the
    /// merges at the two end vertices ([`Self::eta_if`] times their density factors).
    pub fn connect(
        &self,
        light: &VcmVertex,
        light_eta: f32,
        eye: &VcmVertex,
        eye_eta: f32,
        p: &ConnectionPdfs,
    ) -> f32 {
        let nu = self.nu(
            light.inv_k_sum + eye.inv_k_sum,
            light.vertices + eye.vertices,
        );
        let w_light = self.mis(p.light_pdf_a)
            * (light_eta * nu + light.d_vcm + Self::d_vc(light, nu) * self.mis(p.light_rev_pdf_w)); // 001 eq. (40)
        let w_camera = self.mis(p.eye_pdf_a)
            * (eye_eta * nu + eye.d_vcm + Self::d_vc(eye, nu) * self.mis(p.eye_rev_pdf_w)); // 001 eq. (41)
        1.0 / (w_light + 1.0 + w_camera)
    }

    /// A light vertex connected to the camera (t = 1; 001 eqs. (46)-(47)): `camera_pdf_a` the
    /// per-pixel area pdf of the vertex as seen from the camera.
    pub fn to_camera(
        &self,
        light: &VcmVertex,
        light_eta: f32,
        camera_pdf_a: f32,
        rev_pdf_w: f32,
    ) -> f32 {
        let nu = self.nu(light.inv_k_sum, light.vertices);
        let w_light = self.mis(camera_pdf_a / self.light_paths)
            * (light_eta * nu + light.d_vcm + Self::d_vc(light, nu) * self.mis(rev_pdf_w)); // 001 eq. (46)
        1.0 / (w_light + 1.0)
    }

    /// A merge of a light vertex at an eye vertex (001 eqs. (38)-(39)): `pdf_w` the eye BSDF's
    /// pdf towards the light vertex's incoming direction, `rev_pdf_w` the reverse, `eta` the
    /// merge's own ([`Self::eta`]) and `(rho, inv_k)` its density factor and 1 / k (1 and 0
    /// for VCM and UPG; both sub-paths counted the merge vertex, VCM* counts it once).
    ///
    /// 001 eq. (38) writes each side as d^VCM / eta_VCM + d^VM mis(pdf). With connections,
    /// d^VC = eta_VCM d^VM holds at every vertex (compare eqs. (35) and (36): every term of
    /// d^VM is d^VC's divided by eta_VCM, and eq. (33) starts it so), so that form equals
    /// (d^VCM + d^VC mis(pdf)) / eta_VCM, used here because it holds for per-vertex eta_j
    /// too (UPG's clamped acceptance, 002's density factors), where d^VM cannot carry each
    /// merge's own eta. Without connections (bpm) d^VC is zero and d^VM holds the merges alone,
    /// each with its density factor.
    pub fn merge(
        &self,
        light: &VcmVertex,
        eye: &VcmVertex,
        (pdf_w, rev_pdf_w): (f32, f32),
        eta: f32,
        (rho, inv_k): (f32, f32),
    ) -> f32 {
        let (w_light, w_camera) = if self.vm_factor > 0.0 {
            let nu = self.nu(
                light.inv_k_sum + eye.inv_k_sum - inv_k,
                light.vertices + eye.vertices - 1.0,
            );
            let eta = eta * rho * nu;
            (
                (self.connection_term(light.d_vcm) + Self::d_vc(light, nu) * self.mis(pdf_w)) / eta, // 001 eq. (38)
                (self.connection_term(eye.d_vcm) + Self::d_vc(eye, nu) * self.mis(rev_pdf_w)) / eta, // 001 eq. (39)
            )
        } else {
            (
                light.d_vm * self.mis(pdf_w) / rho,
                eye.d_vm * self.mis(rev_pdf_w) / rho,
            )
        };
        1.0 / (w_light + 1.0 + w_camera)
    }
}

/// SmallVCM's MIS quantities of one sub-path vertex (001 eqs. (31)-(36)), and what VCM*
/// carries besides (zero otherwise; see [`VcmWeights::with_density`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VcmVertex {
    pub d_vcm: f32,
    pub d_vc: f32,
    pub d_vm: f32,
    /// VCM*: the merge terms of d^VC, kept apart from its connection terms because the path's
    /// normalisation, known only once the path is whole, multiplies them alone.
    pub d_vc_vm: f32,
    /// VCM*: sum of 1 / k_j over the sub-path's non-delta surface vertices so far, this one
    /// included, and their count (002 eq. (7)'s mean, split between the sub-paths).
    pub inv_k_sum: f32,
    pub vertices: f32,
}
