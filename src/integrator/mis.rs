//! Multiple importance sampling weights of the bidirectional techniques, in one place.
//!
//! Two recursive schemes, kept apart on purpose (000 ch. 3.1 cross-checks BPT against VCM):
//!
//! - [`BptVertex`]: the partial sums a_i, A_i (camera side c_i, C_i) of 000 eqs. (2.50)-(2.51),
//!   used by `bpt.rs`. They turn the power-heuristic weight of 000 eq. (2.47) into O(1) work per
//!   connection.
//! - [`VcmVertex`] and [`VcmWeights`]: SmallVCM's d^VCM, d^VC, d^VM of 001 eqs. (31)-(47), used
//!   by `vcm.rs` for `vcm`, `bpm`, `ppm` and `lt`, and by `upg.rs`.
//!
//! Every quantity is stored "with the power already applied": `mis(x) = x^beta`, applied to
//! each factor, so products and the ratio sums stay what 000 eq. (2.48) writes.
//! Russian roulette stays out of the pdfs: every technique evaluates the same pdfs, so the
//! weights still sum to one.

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

/// The BPT weight of light sampling (s = 1) at eye vertex `eye`: `bsdf_pdf_w` and
/// `bsdf_rev_pdf_w` are the eye BSDF's pdfs towards the light and back; `light_pdf_w` the pick
/// probability times the light point's solid-angle pdf at the receiver; `direct_pdf_w`,
/// `emission_pdf_w` and `cos_at_light` the light's, without the pick; `cos_at_eye` the cosine at
/// the receiver.
#[allow(clippy::too_many_arguments)]
pub fn bpt_light_sample(
    power: Power,
    eye: &BptVertex,
    bsdf_pdf_w: f32,
    bsdf_rev_pdf_w: f32,
    light_pdf_w: f32,
    direct_pdf_w: f32,
    emission_pdf_w: f32,
    cos_at_eye: f32,
    cos_at_light: f32,
    delta_light: bool,
) -> f32 {
    // a_0 mis(p_rev(y_0)) with a_0 = 1 / (pick pdf_a) and p_rev(y_0) = bsdf_pdf_w cos_light / d^2:
    // in solid angle at the receiver, the ratio of the two pdfs of choosing the light point.
    let light_side = if delta_light {
        0.0
    } else {
        power.mis(bsdf_pdf_w / light_pdf_w)
    };
    // The light samples the eye vertex by leaving its point with the emission's direction pdf.
    let eye_rev_pdf_a = emission_pdf_w * cos_at_eye / (direct_pdf_w * cos_at_light);
    bpt_weight(
        light_side,
        eye.ratio_sum(power, bsdf_rev_pdf_w, eye_rev_pdf_a),
    )
}

/// The BPT weight of a connection between light vertex `light` and eye vertex `eye`
/// (s, t >= 2): each side's reverse pdf given the connection, and the area pdf with which the
/// other side samples it.
pub fn bpt_connect(
    power: Power,
    light: &BptVertex,
    eye: &BptVertex,
    light_rev_pdf_w: f32,
    eye_rev_pdf_w: f32,
    light_rev_pdf_a: f32,
    eye_rev_pdf_a: f32,
) -> f32 {
    bpt_weight(
        light.ratio_sum(power, light_rev_pdf_w, light_rev_pdf_a),
        eye.ratio_sum(power, eye_rev_pdf_w, eye_rev_pdf_a),
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

/// Whether merging at the vertex a sub-path scatters from is one of the techniques. Vertex
/// merging by density estimation (`vcm`, `bpm`, `ppm`) merges at every non-delta vertex;
/// unbiased photon gathering needs the merge vertex's neighbour on the gathering side to be a
/// non-delta surface vertex too (the tentative rays leave from it, 000 sec. 2.4.3), which for
/// one of the two sub-paths is only known one vertex later.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VmHere {
    Valid,
    Invalid,
    /// Decided on arrival at the next vertex ([`VcmWeights::resolve`]).
    Deferred,
}

/// Per-iteration constants of the VCM weights (001 eqs. (20)-(22) and sec. 5.5-5.6).
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
        }
    }

    #[inline]
    pub fn mis(&self, x: f32) -> f32 {
        self.power.mis(x)
    }

    /// y_0 on a light (001 eqs. (31)-(33); sec. 5.1-5.2 for infinite and delta lights).
    /// `cos_at_light` is 1 for infinite lights.
    pub fn light_origin(
        &self,
        direct_pdf_a: f32,
        emission_pdf_w: f32,
        cos_at_light: f32,
        delta: bool,
    ) -> VcmVertex {
        let d_vc = if delta {
            0.0
        } else {
            self.mis(cos_at_light / emission_pdf_w)
        };
        VcmVertex {
            d_vcm: self.mis(direct_pdf_a / emission_pdf_w),
            d_vc,
            d_vm: d_vc * self.vc_factor,
            pending_vm: 0.0,
        }
    }

    /// z_0, the camera, with `camera_pdf_w` its per-pixel solid-angle pdf of the primary ray
    /// (001 eqs. (31)-(33): p_0^connect = p_0^trace, so d^VC = d^VM = 0).
    pub fn camera_origin(&self, camera_pdf_w: f32) -> VcmVertex {
        VcmVertex {
            d_vcm: self.mis(self.light_paths / camera_pdf_w),
            d_vc: 0.0,
            d_vm: 0.0,
            pending_vm: 0.0,
        }
    }

    /// Arrival at a new vertex at `distance` with |cos| `cos_in` (001 eqs. (34)-(36), the
    /// geometry part). The first segment from an infinite light has no distance term
    /// (001 sec. 5.1): `with_distance = false`.
    pub fn arrive(&self, v: &mut VcmVertex, distance: f32, cos_in: f32, with_distance: bool) {
        if with_distance {
            v.d_vcm *= self.mis(distance * distance);
        }
        let inv = 1.0 / self.mis(cos_in);
        v.d_vcm *= inv;
        v.d_vc *= inv;
        v.d_vm *= inv;
        v.pending_vm *= inv;
    }

    /// Scattering at a vertex (001 eqs. (34)-(36), the sampling part): `pdf_w` the pdf of the
    /// sampled direction, `rev_pdf_w` of the reverse, `cos_out` at the sampled direction.
    /// `merge_here` says whether merging at this vertex is a technique: its terms are
    /// mis(eta_VCM) in d^VC and 1 in d^VM (001 eqs. (35)-(36)), with eta_VCM the same for every
    /// vertex (no clamping), so d^VM stays d^VC / eta_VCM when both VC and VM run.
    pub fn scatter(
        &self,
        v: &mut VcmVertex,
        cos_out: f32,
        pdf_w: f32,
        rev_pdf_w: f32,
        delta: bool,
        merge_here: VmHere,
    ) {
        if delta {
            // 001 sec. 5.3: delta pdfs cancel; only the cosine ratio survives.
            v.d_vcm = 0.0;
            v.d_vc *= self.mis(cos_out);
            v.d_vm *= self.mis(cos_out);
        } else {
            let ratio = self.mis(cos_out / pdf_w);
            let here = if merge_here == VmHere::Valid {
                1.0
            } else {
                0.0
            };
            v.d_vc = ratio * (v.d_vc * self.mis(rev_pdf_w) + v.d_vcm + here * self.vm_factor);
            v.d_vm = ratio * (v.d_vm * self.mis(rev_pdf_w) + v.d_vcm * self.vc_factor + here);
            v.d_vcm = self.mis(1.0 / pdf_w);
            if merge_here == VmHere::Deferred {
                v.pending_vm = ratio;
            }
        }
    }

    /// Settles a [`VmHere::Deferred`] merge at the previous vertex once this vertex shows
    /// whether the tentative rays could leave from it.
    pub fn resolve(&self, v: &mut VcmVertex, valid: bool) {
        if valid {
            v.d_vc += v.pending_vm * self.vm_factor;
            v.d_vm += v.pending_vm;
        }
        v.pending_vm = 0.0;
    }

    /// An eye sub-path hits a light (s = 0; 001 eqs. (42)-(43)); the pdfs include the light's
    /// pick probability.
    pub fn hit_light(&self, eye: &VcmVertex, direct_pdf_a: f32, emission_pdf_w: f32) -> f32 {
        let w_camera = self.mis(direct_pdf_a) * eye.d_vcm + self.mis(emission_pdf_w) * eye.d_vc;
        1.0 / (1.0 + w_camera)
    }

    /// Light sampling (s = 1; 001 eqs. (44)-(45)). `light_pdf_w` is the pick probability times
    /// the solid-angle pdf of the light point at the receiver, `emission_pdf_w` the light's
    /// emission pdf of the connecting direction (without the pick), `bsdf` the eye vertex's
    /// pdfs towards the light.
    #[allow(clippy::too_many_arguments)]
    pub fn light_sample(
        &self,
        eye: &VcmVertex,
        eye_merge: bool,
        bsdf_pdf_w: f32,
        bsdf_rev_pdf_w: f32,
        light_pdf_w: f32,
        direct_pdf_w: f32,
        emission_pdf_w: f32,
        cos_to_light: f32,
        cos_at_light: f32,
        delta_light: bool,
    ) -> f32 {
        let w_light = if delta_light {
            0.0
        } else {
            self.mis(bsdf_pdf_w / light_pdf_w)
        };
        let w_camera = self.mis(emission_pdf_w * cos_to_light / (direct_pdf_w * cos_at_light))
            * (self.vm_term(eye_merge) + eye.d_vcm + eye.d_vc * self.mis(bsdf_rev_pdf_w));
        1.0 / (w_light + 1.0 + w_camera)
    }

    /// The merge at a connection's end vertex, as a share of the connection (001 eq. (40)).
    fn vm_term(&self, merge_here: bool) -> f32 {
        if merge_here {
            self.vm_factor
        } else {
            0.0
        }
    }

    /// Connection of a light vertex and an eye vertex (s, t > 1; 001 eqs. (40)-(41)): each
    /// side's area pdf of being sampled by the other, and each side's reverse pdf.
    /// `*_merge`: whether merging at that end vertex is a technique.
    #[allow(clippy::too_many_arguments)]
    pub fn connect(
        &self,
        light: &VcmVertex,
        light_merge: bool,
        eye: &VcmVertex,
        eye_merge: bool,
        light_rev_pdf_w: f32,
        eye_rev_pdf_w: f32,
        light_pdf_a: f32,
        eye_pdf_a: f32,
    ) -> f32 {
        let w_light = self.mis(eye_pdf_a)
            * (self.vm_term(light_merge) + light.d_vcm + light.d_vc * self.mis(light_rev_pdf_w));
        let w_camera = self.mis(light_pdf_a)
            * (self.vm_term(eye_merge) + eye.d_vcm + eye.d_vc * self.mis(eye_rev_pdf_w));
        1.0 / (w_light + 1.0 + w_camera)
    }

    /// A light vertex connected to the camera (t = 1; 001 eqs. (46)-(47)): `camera_pdf_a` the
    /// per-pixel area pdf of the vertex as seen from the camera.
    pub fn to_camera(
        &self,
        light: &VcmVertex,
        light_merge: bool,
        camera_pdf_a: f32,
        rev_pdf_w: f32,
    ) -> f32 {
        let w_light = self.mis(camera_pdf_a / self.light_paths)
            * (self.vm_term(light_merge) + light.d_vcm + light.d_vc * self.mis(rev_pdf_w));
        1.0 / (w_light + 1.0)
    }

    /// A merge of a light vertex at an eye vertex (001 eqs. (38)-(39)): `pdf_w` the eye BSDF's
    /// pdf towards the light vertex's incoming direction, `rev_pdf_w` the reverse.
    pub fn merge(&self, light: &VcmVertex, eye: &VcmVertex, pdf_w: f32, rev_pdf_w: f32) -> f32 {
        let w_light = light.d_vcm * self.vc_factor + light.d_vm * self.mis(pdf_w);
        let w_camera = eye.d_vcm * self.vc_factor + eye.d_vm * self.mis(rev_pdf_w);
        1.0 / (w_light + 1.0 + w_camera)
    }
}

/// SmallVCM's MIS quantities of one sub-path vertex (001 eqs. (31)-(36)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VcmVertex {
    pub d_vcm: f32,
    pub d_vc: f32,
    pub d_vm: f32,
    /// The factor of a [`VmHere::Deferred`] merge term, until [`VcmWeights::resolve`].
    pub pending_vm: f32,
}
