//! The MIS weights of all techniques that can sample one fixed full path sum to 1.
//!
//! Paths of 2 to 8 segments are generated in the shipped scenes (diffuse, Phong, mirror,
//! glass, rough conductor, rough dielectric and thin dielectric vertices; area, point,
//! directional and sky lights) by a random walk from the camera
//! closed by a light sample. For every way of splitting such a path into a light and an eye
//! sub-path, the sub-paths' MIS quantities are built with the library's recursions
//! (`BptVertex`, 000 eqs. (2.50)-(2.51); `VcmWeights`, 001 eqs. (31)-(47)) from the pdfs the
//! BSDFs, lights and camera give along the path, and each technique's weight is taken from the
//! functions the integrators call. The BPT weights are also checked one by one against the
//! power heuristic evaluated directly from products of area pdfs (000 eq. (2.47)); the VCM
//! weights are checked with merges by density estimation and with UPG's merges from either
//! side, whose clamped acceptance (000 eqs. (2.80)-(2.82)) binds at the larger radii, and
//! with merge-only UPG, whose merges share each path among themselves, and with a radius of
//! its own for every eye sub-path (001 sec. 6.1), the light sub-path carrying c^VC and c^VM.
//! 002's density factors (VCM+, VCM*) are checked on VCM's merges and on UPG's from either
//! side, deferred merges included, at three radii up to where UPG's clamp binds. `upg-hybrid`,
//! whose rule gathers each merge from one side by the roughness of its neighbour towards the
//! light, is checked wherever `upg` and `upg-camera` are: its rule evaluated on the full path
//! gives each technique's eta, the sub-paths' recursions decide it as vcm.rs does.

mod common;

use glam::Vec3;
use std::ops::ControlFlow;
use vmerge::bsdf::{Bsdf, MaterialKind, TransportMode};
use vmerge::integrator::mis::{
    self, BptStep, BptVertex, ConnectionPdfs, Gather, LightSamplePdfs, Neighbour, Power, Side,
    VcmVertex, VcmWeights, VmHere, NO_DENSITY,
};
use vmerge::integrator::subpath::{self, MisStep, PendingMis};
use vmerge::integrator::upg::{hybrid, Deferred};
use vmerge::light::Aim;
use vmerge::options::DensityMis;
use vmerge::sampling::{Rng, Stream};
use vmerge::scene::{Camera, Scene};

/// Pixels of the test camera: n_VC = n_VM.
const PIXELS: u32 = 16;

/// `upg-hybrid`'s threshold here: between the scenes' glossy and rough lobes (Phong exponents
/// 100 and 10 give alphas 0.14 and 0.41), so both sides gather.
const HYBRID_ROUGHNESS: f32 = 0.3;

/// One vertex of a full path, light (index 0) to camera (index k).
#[derive(Clone, Copy)]
enum Vertex {
    Light,
    Surface {
        position: Vec3,
        ng: Vec3,
        material: u32,
        delta: bool,
    },
    Camera,
}

/// A full path with everything the weights need, in the light-to-camera order x_0..x_k.
struct FullPath {
    vertices: Vec<Vertex>,
    /// Positions (the light point; for infinite lights a far point along the direction).
    positions: Vec<Vec3>,
    light: LightEnd,
}

/// The light end x_0 as light sampling saw it from x_1.
#[derive(Clone, Copy)]
struct LightEnd {
    pick: f32,
    /// Area pdf of the point (solid angle for the sky, 1 for delta lights), without the pick.
    pdf_a: f32,
    direct_pdf_w: f32,
    emission_pdf_w: f32,
    cos_at_light: f32,
    /// Unit direction from x_1 to the light.
    dir_to_light: Vec3,
    distance: f32,
    infinite: bool,
    delta: bool,
}

struct Setup<'a> {
    scene: &'a Scene,
    camera: Camera,
    /// Where infinite lights start their sub-paths (their emission pdf).
    aim: Aim,
}

impl Setup<'_> {
    fn n(&self) -> f32 {
        self.camera.pixel_count() as f32
    }

    /// A random path of `k` segments, or `None` when the walk fails (retry).
    fn random_path(&self, k: usize, rng: &mut Rng) -> Option<FullPath> {
        let [x, y] = [
            rng.next_f32() * PIXELS as f32,
            rng.next_f32() * PIXELS as f32,
        ];
        let mut ray = self.camera.generate_ray(x, y);
        // Eye walk: x_k = camera, then x_{k-1} .. x_1.
        let mut eye = Vec::new();
        loop {
            let hit = self.scene.intersect(&ray)?;
            let kind = &self.scene.material(hit.material).kind;
            let wo = -ray.dir.normalize();
            let bsdf = Bsdf::new(kind, hit.ng, wo, TransportMode::Radiance)?;
            eye.push(Vertex::Surface {
                position: hit.position,
                ng: hit.ng,
                material: hit.material,
                delta: bsdf.is_delta(),
            });
            if eye.len() == k - 1 {
                if bsdf.is_delta() {
                    return None;
                }
                break;
            }
            let s = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()])?;
            ray = vmerge::accel::Ray::spawn(hit.position, hit.ng, s.wi);
        }
        let Vertex::Surface { position, ng, .. } = eye[k - 2] else {
            unreachable!()
        };
        let lights = &self.scene.lights;
        let (index, pick) = lights.pick(rng.next_f32())?;
        let light = lights.get(index);
        let il = light.illuminate(position, rng.next_2d(), self.aim)?;
        if self
            .scene
            .occluded(&il.shadow_ray(position, ng, light.is_delta()))
        {
            return None;
        }
        let infinite = !il.distance.is_finite();
        let pdf_a = if light.is_delta() {
            1.0
        } else if infinite {
            il.direct_pdf_w
        } else {
            il.direct_pdf_w * il.cos_at_light / (il.distance * il.distance)
        };
        let mut vertices = vec![Vertex::Light];
        vertices.extend(eye.iter().rev().copied());
        vertices.push(Vertex::Camera);
        let mut positions = vec![if infinite {
            position + il.dir_to_light * 1e6
        } else {
            il.position
        }];
        positions.extend(eye.iter().rev().map(|v| match v {
            Vertex::Surface { position, .. } => *position,
            _ => unreachable!(),
        }));
        positions.push(self.camera.position);
        Some(FullPath {
            vertices,
            positions,
            light: LightEnd {
                pick,
                pdf_a,
                direct_pdf_w: il.direct_pdf_w,
                emission_pdf_w: il.emission_pdf_w,
                cos_at_light: il.cos_at_light,
                dir_to_light: il.dir_to_light,
                distance: il.distance,
                infinite,
                delta: light.is_delta(),
            },
        })
    }
}

/// Pdfs and geometry of a full path, evaluated once.
struct PathPdfs {
    k: usize,
    /// Solid-angle pdf at x_i of sampling the direction to x_{i+1} (light side; delta: 1).
    light_w: Vec<f32>,
    /// Solid-angle pdf at x_i of sampling the direction to x_{i-1} (eye side; delta: 1).
    eye_w: Vec<f32>,
    /// |cos| at x_i towards x_{i+1} and towards x_{i-1}.
    cos_next: Vec<f32>,
    cos_prev: Vec<f32>,
    /// Squared distance of segment (x_i, x_{i+1}).
    dist2: Vec<f32>,
    /// Area pdf of x_i sampled from the light side / the eye side.
    light_a: Vec<f32>,
    eye_a: Vec<f32>,
    connectable: Vec<bool>,
    /// x_i is glossy by `upg-hybrid`'s rule at [`HYBRID_ROUGHNESS`].
    glossy: Vec<bool>,
    /// The camera's per-pixel solid-angle pdf of the direction to x_{k-1}.
    camera_pdf_w: f32,
}

fn evaluate(setup: &Setup, path: &FullPath) -> PathPdfs {
    let k = path.vertices.len() - 1;
    let p = &path.positions;
    let l = path.light;
    let dir = |from: usize, to: usize| {
        if from == 0 && l.infinite {
            -l.dir_to_light
        } else if to == 0 && l.infinite {
            l.dir_to_light
        } else {
            (p[to] - p[from]).normalize()
        }
    };
    let mut dist2 = vec![0.0; k];
    for (i, d) in dist2.iter_mut().enumerate() {
        *d = if i == 0 {
            l.distance * l.distance
        } else {
            p[i].distance_squared(p[i + 1])
        };
    }
    let (mut light_w, mut eye_w) = (vec![1.0f32; k + 1], vec![1.0f32; k + 1]);
    let (mut cos_next, mut cos_prev) = (vec![1.0f32; k + 1], vec![1.0f32; k + 1]);
    let mut connectable = vec![true; k + 1];
    let mut glossy = vec![false; k + 1];
    for i in 1..k {
        let Vertex::Surface {
            ng,
            material,
            delta,
            ..
        } = path.vertices[i]
        else {
            unreachable!()
        };
        let kind = &setup.scene.material(material).kind;
        let (to_prev, to_next) = (dir(i, i - 1), dir(i, i + 1));
        cos_next[i] = ng.dot(to_next).abs();
        cos_prev[i] = ng.dot(to_prev).abs();
        connectable[i] = !delta;
        glossy[i] = hybrid::roughness(kind) < HYBRID_ROUGHNESS;
        if !delta {
            let light_bsdf = Bsdf::new(kind, ng, to_prev, TransportMode::Importance).unwrap();
            let e = light_bsdf.eval(to_next);
            light_w[i] = e.pdf_w;
            eye_w[i] = e.rev_pdf_w;
        }
    }
    // The light point: the emission's direction pdf; the cosine there.
    light_w[0] = l.emission_pdf_w / l.pdf_a;
    cos_next[0] = l.cos_at_light;
    let camera_dir = (p[k - 1] - p[k]).normalize();
    let camera_pdf_w = setup.camera.pdf_w(camera_dir);
    eye_w[k] = camera_pdf_w / setup.n();
    // Area pdfs: x_i from x_{i-1} (light side) and from x_{i+1} (eye side).
    let g = |at: usize, from: usize| {
        let segment = at.min(from);
        let cos = if at < from {
            cos_next[at]
        } else {
            cos_prev[at]
        };
        if segment == 0 && l.infinite {
            // Directions at infinity: no distance term, and the sky point itself is a
            // direction (no cosine).
            if at == 0 {
                1.0
            } else {
                cos
            }
        } else {
            cos / dist2[segment]
        }
    };
    let mut light_a = vec![0.0f32; k + 1];
    let mut eye_a = vec![0.0f32; k + 1];
    light_a[0] = l.pick * l.pdf_a;
    for i in 1..k {
        light_a[i] = light_w[i - 1] * g(i, i - 1);
    }
    eye_a[k] = 1.0;
    for i in (0..k).rev() {
        eye_a[i] = eye_w[i + 1] * g(i, i + 1);
    }
    PathPdfs {
        k,
        light_w,
        eye_w,
        cos_next,
        cos_prev,
        dist2,
        light_a,
        eye_a,
        connectable,
        glossy,
        camera_pdf_w,
    }
}

/// Whether technique (s, t = k + 1 - s) can sample the path.
fn valid(path: &FullPath, q: &PathPdfs, s: usize) -> bool {
    if s == 0 {
        !path.light.delta
    } else {
        q.connectable[s - 1] && q.connectable[s]
    }
}

/// The BPT weights of techniques s = 0..=k through the library's recursion.
fn bpt_weights(power: Power, setup: &Setup, path: &FullPath, q: &PathPdfs) -> Vec<f32> {
    let k = q.k;
    let l = path.light;
    let g_fwd = |i: usize| q.light_a[i] / q.light_w[i - 1];
    let g_back = |i: usize| q.eye_a[i] / q.eye_w[i + 1];
    // Light sub-path y_i = x_i.
    let mut light = vec![BptVertex::light_origin(power, l.pick * l.pdf_a, !l.delta)];
    for i in 1..k {
        let step = BptStep {
            pdf_w: q.light_w[i - 1],
            rev_pdf_w: if i >= 2 { q.eye_w[i - 1] } else { 1.0 },
            g: g_fwd(i),
            g_rev: g_back(i - 1),
            prev_connectable: q.connectable[i - 1],
        };
        light.push(light[i - 1].next(power, &step));
    }
    // Eye sub-path z_j = x_{k-j}.
    let mut eye = vec![BptVertex::default(); k + 1];
    eye[k] = BptVertex::camera_origin();
    for i in (0..k).rev() {
        let step = BptStep {
            pdf_w: q.eye_w[i + 1],
            rev_pdf_w: if i + 2 < k { q.light_w[i + 1] } else { 1.0 },
            g: g_back(i),
            g_rev: if i + 1 == k { 1.0 } else { g_fwd(i + 1) },
            prev_connectable: q.connectable[i + 1],
        };
        eye[i] = eye[i + 1].next(power, &step);
    }
    (0..=k)
        .map(|s| {
            if !valid(path, q, s) {
                return 0.0;
            }
            if s == 0 {
                mis::bpt_hit_light(power, &eye[0], l.pick * l.pdf_a, l.pick * l.emission_pdf_w)
            } else if s == 1 {
                mis::bpt_light_sample(power, &eye[1], &light_sample_pdfs(path, q))
            } else if s == k {
                let camera_pdf_a = q.eye_a[k - 1] * setup.n();
                mis::bpt_to_camera(
                    power,
                    &light[k - 1],
                    q.eye_w[k - 1],
                    camera_pdf_a,
                    setup.n(),
                )
            } else {
                mis::bpt_connect(power, &light[s - 1], &eye[s], &connection_pdfs(q, s))
            }
        })
        .collect()
}

/// The power heuristic straight from 000 eq. (2.47): p_s = prod of the light side's area pdfs
/// of x_0..x_{s-1} times the eye side's of x_s..x_k.
fn direct_weights(power: Power, path: &FullPath, q: &PathPdfs) -> Vec<f64> {
    let k = q.k;
    let pdfs: Vec<f64> = (0..=k)
        .map(|s| {
            if !valid(path, q, s) {
                return 0.0;
            }
            let light: f64 = q.light_a[..s].iter().map(|&p| p as f64).product();
            let eye: f64 = q.eye_a[s..].iter().map(|&p| p as f64).product();
            (light * eye).powf(power.0 as f64)
        })
        .collect();
    let sum: f64 = pdfs.iter().sum();
    pdfs.iter().map(|p| p / sum).collect()
}

/// The pdfs of light sampling at x_1, from the path's own.
fn light_sample_pdfs(path: &FullPath, q: &PathPdfs) -> LightSamplePdfs {
    let l = path.light;
    LightSamplePdfs {
        bsdf_pdf_w: q.eye_w[1],
        bsdf_rev_pdf_w: q.light_w[1],
        light_pdf_w: l.pick * l.direct_pdf_w,
        direct_pdf_w: l.direct_pdf_w,
        emission_pdf_w: l.emission_pdf_w,
        cos_at_receiver: q.cos_prev[1],
        cos_at_light: l.cos_at_light,
        delta_light: l.delta,
    }
}

/// The pdfs of the connection between light vertex x_{s-1} and eye vertex x_s.
fn connection_pdfs(q: &PathPdfs, s: usize) -> ConnectionPdfs {
    ConnectionPdfs {
        light_rev_pdf_w: q.eye_w[s - 1],
        eye_rev_pdf_w: q.light_w[s],
        light_pdf_a: q.eye_a[s - 1],
        eye_pdf_a: q.light_a[s],
    }
}

/// A sub-path's MIS quantities at a vertex, with UPG's deferred merge and the density factor
/// of a merge there.
#[derive(Clone, Copy)]
struct State {
    mis: VcmVertex,
    deferred: Deferred,
    rho: f32,
}

impl Default for State {
    fn default() -> Self {
        State {
            mis: VcmVertex::default(),
            deferred: Deferred::NONE,
            rho: NO_DENSITY.0,
        }
    }
}

impl State {
    fn at(&self, w: &VcmWeights, rev_pdf_w: f32) -> VcmVertex {
        self.deferred.settle(w, self.mis, rev_pdf_w)
    }

    fn arrive(&mut self, w: &VcmWeights, distance: f32, cos: f32, with_distance: bool) {
        let arrival = w.arrive(&mut self.mis, distance, cos, with_distance);
        self.deferred.arrive(arrival);
    }

    /// Scattering at a vertex as vcm.rs does it: the deferred merge settles, and a merge here
    /// gathered from the other side is deferred in turn.
    fn scatter(
        &mut self,
        w: &VcmWeights,
        cos_out: f32,
        pdf_w: f32,
        rev_pdf_w: f32,
        delta: bool,
        (here, rho): (VmHere, f32),
    ) {
        // At a delta vertex only vcm-upg keeps a deferred merge, whose eta needs no pdf.
        self.mis = self.at(w, rev_pdf_w);
        let ratio = w.scatter(
            &mut self.mis,
            cos_out,
            pdf_w,
            rev_pdf_w,
            delta,
            (here == VmHere::Valid, rho),
        );
        self.deferred = if !delta && here == VmHere::Deferred {
            Deferred::new(w, ratio, cos_out, rho)
        } else {
            Deferred::NONE
        };
    }
}

/// The VCM weights of the connection techniques s = 0..=k and the merges at x_1..x_{k-1},
/// following vcm.rs: the light sub-path arrives at x_i, keeps a deferred merge only on a
/// surface, is stored, and scatters on; the eye sub-path likewise from the camera. Which merges
/// are techniques is the library's one rule, [`Gather::merge_at`].
///
/// `inv_k` gives each vertex's 1 / k for 002's heuristics (weights made
/// [`VcmWeights::with_density`]); empty for VCM and UPG.
fn vcm_weights(
    w: &VcmWeights,
    gather: Gather,
    path: &FullPath,
    q: &PathPdfs,
    inv_k: &[f32],
) -> (Vec<f32>, Vec<f32>) {
    vcm_weights_with(LightSide::Same, w, gather, path, q, &|i, _| {
        inv_k.get(i).copied()
    })
}

/// How the light sub-path meets an eye sub-path of its own radius (001 sec. 6.1).
#[derive(Clone, Copy)]
enum LightSide<'a> {
    /// Both sub-paths weigh with the same weights.
    Same,
    /// Traced with these radius-free weights: every use of a light vertex resolves its c^VC,
    /// c^VM at the eye's radius (001 eqs. (62)-(63)).
    Resolved(&'a VcmWeights),
    /// Traced with these weights, its MIS steps kept and re-run with the eye sub-path's
    /// weights by every use ([`subpath::replay`]), as vcm.rs does under UPG's clamp and
    /// 002's density factors.
    Replayed(&'a VcmWeights),
    /// Traced with these weights and used as stored: what a light sub-path weighed at another
    /// radius than the eye sub-path's gives (to show the test can fail).
    Stored(&'a VcmWeights),
}

/// [`vcm_weights`], with the light sub-path traced and used as `side` says and `w` the eye
/// sub-path's weights (001 sec. 6.1), as vcm.rs does with per-pixel radii: the eye sub-path
/// takes `w` from its first non-specular vertex on. `inv_k(i, r)` is x_i's 1 / k for merges
/// of radius r (002's heuristics), `None` without them.
fn vcm_weights_with(
    side: LightSide,
    w: &VcmWeights,
    gather: Gather,
    path: &FullPath,
    q: &PathPdfs,
    inv_k: &dyn Fn(usize, f32) -> Option<f32>,
) -> (Vec<f32>, Vec<f32>) {
    let eye_w = w;
    // Each merge's eta is the eye sub-path's, whichever side holds the merge vertex.
    let w = match side {
        LightSide::Same => eye_w,
        LightSide::Resolved(w) | LightSide::Replayed(w) | LightSide::Stored(w) => w,
    };
    let k = q.k;
    let l = path.light;
    let surface = |i: usize| (1..k).contains(&i) && q.connectable[i];
    // A vertex's density factor and 1 / k at a radius, as vcm.rs takes them at each surface
    // vertex.
    let density_at = |i: usize, radius: f32| match inv_k(i, radius) {
        Some(inv) if surface(i) => (w.mis(inv), inv),
        _ => NO_DENSITY,
    };
    // The eye sub-path's (and a merge's, made at an eye vertex) at the eye's radius.
    let density = |i: usize| density_at(i, eye_w.radius);
    let rho = |i: usize| density(i).0;
    let neighbour = |i: usize| match i {
        0 => Neighbour::Light,
        _ => Neighbour::surface_if(surface(i)).glossy_if(q.glossy[i]),
    };
    let merge_valid = |j: usize| {
        surface(j) && gather.merge_at(neighbour(j - 1), neighbour(j + 1)) == VmHere::Valid
    };
    // mis(eta_j) of the merge at x_j from the gathering side's area pdf of x_j (000 eq. 2.80).
    let eta = |j: usize| {
        let gather_pdf = match gather.side(neighbour(j - 1)) {
            Side::Light => q.light_a[j],
            Side::Camera => q.eye_a[j],
        };
        eye_w.eta_if(merge_valid(j), w.mis(1.0 / gather_pdf))
    };
    // The light sub-path at the radius it is traced with, and its MIS steps as vcm.rs keeps
    // them.
    let mut light = vec![State::default(); k];
    let origin = MisStep::Origin {
        direct_pdf_a: l.pick * l.pdf_a,
        emission_pdf_w: l.pick * l.emission_pdf_w,
        cos_at_light: if l.infinite { 1.0 } else { l.cos_at_light },
        delta: l.delta,
    };
    let mut steps = vec![origin];
    let mut state = State {
        mis: w.light_origin(
            l.pick * l.pdf_a,
            l.pick * l.emission_pdf_w,
            if l.infinite { 1.0 } else { l.cos_at_light },
            l.delta,
        ),
        ..State::default()
    };
    #[allow(clippy::needless_range_loop)] // i indexes several arrays of the path
    for i in 1..k {
        let (distance, cos, with_distance) = (
            q.dist2[i - 1].sqrt(),
            q.cos_prev[i],
            !(i == 1 && l.infinite),
        );
        state.arrive(w, distance, cos, with_distance);
        steps.push(MisStep::Arrive {
            distance,
            cos,
            with_distance,
            surface: surface(i),
        });
        // The light sub-path defers only merges gathered from the camera side, whose
        // neighbour towards the light is one the camera side gathers next to (`Glossy`).
        state
            .deferred
            .keep_if(gather.merge_at(Neighbour::Glossy, neighbour(i)) == VmHere::Valid);
        let (light_rho, light_inv_k) = density_at(i, w.radius);
        if surface(i) && inv_k(i, w.radius).is_some() {
            w.visit(&mut state.mis, light_inv_k);
        }
        state.rho = light_rho;
        light[i] = state;
        if i + 1 < k {
            let here = gather.merge_at(neighbour(i - 1), Neighbour::Unknown);
            let delta = !q.connectable[i];
            let (cos, pdf, rev) = (q.cos_next[i], q.light_w[i], q.eye_w[i]);
            steps.push(MisStep::Leave {
                cos_out: cos,
                pdf_w: pdf,
                rev_pdf_w: rev,
                delta,
                here,
            });
            state.scatter(w, cos, pdf, rev, delta, (here, light_rho));
        }
    }
    if let LightSide::Replayed(_) = side {
        // Each surface vertex in turn.
        let surface_vertices: Vec<usize> = (1..k).filter(|&i| surface(i)).collect();
        let mut surfaces = surface_vertices.iter().copied();
        subpath::replay(
            eye_w,
            &steps,
            |n| inv_k(*surface_vertices.get(n)?, eye_w.radius),
            |mis, pending: &Deferred, (rho, _)| {
                let i = surfaces.next().expect("a visit per surface vertex");
                light[i] = State {
                    mis: *mis,
                    deferred: *pending,
                    rho,
                };
                ControlFlow::Continue(())
            },
        );
        assert_eq!(surfaces.next(), None, "a visit per surface vertex");
    }
    let mut eye = vec![State::default(); k + 1];
    let mut state = State {
        mis: w.camera_origin(q.camera_pdf_w),
        ..State::default()
    };
    let mut w = w;
    for i in (1..k).rev() {
        state.arrive(w, q.dist2[i].sqrt(), q.cos_next[i], true);
        // The eye sub-path's radius, fixed at its first non-specular vertex.
        if q.connectable[i] {
            w = eye_w;
        }
        if gather == Gather::Hybrid {
            hybrid::decide(w, &mut state.mis, &mut state.deferred, neighbour(i));
        } else {
            state
                .deferred
                .keep_if(gather.merge_at(neighbour(i), Neighbour::Surface) == VmHere::Valid);
        }
        if let (true, Some(inv)) = (surface(i), inv_k(i, eye_w.radius)) {
            w.visit(&mut state.mis, inv);
        }
        eye[i] = state;
        let here = gather.merge_at(Neighbour::Unknown, neighbour(i + 1));
        let delta = !q.connectable[i];
        // `upg-hybrid` may gather the merge here from the eye side, its pdf known now.
        let own = if surface(i + 1) { state.mis.d_vcm } else { 0.0 };
        state.scatter(
            w,
            q.cos_prev[i],
            q.eye_w[i],
            q.light_w[i],
            delta,
            (here, rho(i)),
        );
        if gather == Gather::Hybrid {
            state.deferred = state.deferred.with_own(own);
        }
    }
    // Reaching the light: area lights add the last segment, the sky does not; the light
    // point is no surface to merge through.
    if !l.infinite {
        state.arrive(w, q.dist2[0].sqrt(), l.cos_at_light, true);
    }
    if gather == Gather::Hybrid {
        hybrid::decide(w, &mut state.mis, &mut state.deferred, Neighbour::Light);
    }
    eye[0] = state;
    // Every technique weighs with the eye sub-path's radius.
    let w = eye_w;
    let light_at = |i: usize, rev_pdf_w: f32| {
        let v = light[i].at(w, rev_pdf_w);
        if let LightSide::Resolved(_) = side {
            w.resolve(&v)
        } else {
            v
        }
    };
    let vc = (0..=k)
        .map(|s| {
            if !valid(path, q, s) {
                return 0.0;
            }
            if s == 0 {
                w.hit_light(&eye[0].mis, l.pick * l.pdf_a, l.pick * l.emission_pdf_w)
            } else if s == 1 {
                w.light_sample(
                    &eye[1].at(w, q.light_w[1]),
                    eta(1) * rho(1),
                    &light_sample_pdfs(path, q),
                )
            } else if s == k {
                let camera_pdf_a = q.eye_a[k - 1] * w.light_paths;
                let rev = q.eye_w[k - 1];
                w.to_camera(
                    &light_at(k - 1, rev),
                    eta(k - 1) * light[k - 1].rho,
                    camera_pdf_a,
                    rev,
                )
            } else {
                // Each end's eta as vcm.rs picks its gathering side's pdf.
                let p = connection_pdfs(q, s);
                let light_eta = w.end_eta(
                    gather,
                    merge_valid(s - 1),
                    (Side::Light, neighbour(s - 2)),
                    light[s - 1].mis.d_vcm,
                    p.light_pdf_a,
                );
                let eye_eta = w.end_eta(
                    gather,
                    merge_valid(s),
                    (Side::Camera, neighbour(s - 1)),
                    eye[s].mis.d_vcm,
                    p.eye_pdf_a,
                );
                w.connect(
                    &light_at(s - 1, p.light_rev_pdf_w),
                    light_eta * light[s - 1].rho,
                    &eye[s].at(w, p.eye_rev_pdf_w),
                    eye_eta * rho(s),
                    &p,
                )
            }
        })
        .collect();
    // A merge at x_j: the light sub-path's vertex x_j meets the eye sub-path's; the eye BSDF
    // is evaluated towards the light vertex's incoming direction.
    let vm = (1..k)
        .map(|j| {
            if !merge_valid(j) {
                return 0.0;
            }
            let (pdf_w, rev_pdf_w) = (q.eye_w[j], q.light_w[j]);
            w.merge(
                &light_at(j, pdf_w),
                &eye[j].at(w, rev_pdf_w),
                (pdf_w, rev_pdf_w),
                eta(j),
                density(j),
            )
        })
        .collect();
    (vc, vm)
}

/// The techniques checked with a radius per eye sub-path whose light sub-paths are re-run.
const PER_PIXEL: [(&str, Gather, Option<DensityMis>); 10] = [
    ("upg", Gather::UpgLight, None),
    ("upg-camera", Gather::UpgCamera, None),
    ("upg-hybrid", Gather::Hybrid, None),
    ("upg-hybrid vcm*", Gather::Hybrid, Some(DensityMis::Star)),
    ("vcm+", Gather::Density, Some(DensityMis::Plus)),
    ("vcm*", Gather::Density, Some(DensityMis::Star)),
    ("upg vcm+", Gather::UpgLight, Some(DensityMis::Plus)),
    ("upg vcm*", Gather::UpgLight, Some(DensityMis::Star)),
    ("upg-camera vcm+", Gather::UpgCamera, Some(DensityMis::Plus)),
    ("upg-camera vcm*", Gather::UpgCamera, Some(DensityMis::Star)),
];

fn paths(scene_name: &str, seed: u64, count_per_length: usize, aim: Aim) -> (Scene, Vec<FullPath>) {
    let scene = load_scene(scene_name);
    let desc = scene.camera(None).unwrap().clone();
    let setup = Setup {
        scene: &scene,
        camera: Camera::new(&desc, PIXELS, PIXELS),
        aim,
    };
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let mut all = Vec::new();
    for k in 2..=8 {
        let mut found = 0;
        let mut tries = 0;
        while found < count_per_length {
            tries += 1;
            assert!(tries < 100_000, "{scene_name}: no paths of {k} segments");
            if let Some(p) = setup.random_path(k, &mut rng) {
                all.push(p);
                found += 1;
            }
        }
    }
    (scene, all)
}

/// Checks every path of a scene; returns (paths with a specular vertex, paths with merges).
fn check_scene(name: &str, aim: Aim) -> (usize, usize) {
    let (scene, paths) = paths(name, 7, 40, aim);
    let desc = scene.camera(None).unwrap().clone();
    let setup = Setup {
        scene: &scene,
        camera: Camera::new(&desc, PIXELS, PIXELS),
        aim,
    };
    let (mut specular, mut merged, mut clamped, mut shared_merges) = (0, 0, 0, 0);
    let mut per_pixel_mixed = 0;
    // upg-hybrid's merges that weigh, gathered from the light side and from the camera side.
    let mut hybrid_sides = [0usize; 2];
    let (mut replay_mixed, mut replay_needed) = (
        std::collections::HashMap::<&str, usize>::new(),
        std::collections::HashMap::<&str, usize>::new(),
    );
    let mut reweighted = std::collections::HashMap::<(&str, &str), usize>::new();
    for path in &paths {
        let q = evaluate(&setup, path);
        // A path the BSDFs cannot scatter along (light behind a surface) has no techniques.
        if (1..q.k).any(|i| q.connectable[i] && (q.light_w[i] <= 0.0 || q.eye_w[i] <= 0.0)) {
            continue;
        }
        if q.connectable.iter().any(|c| !c) {
            specular += 1;
        }
        for beta in [1.0, 2.0] {
            let power = Power(beta);
            let bpt = bpt_weights(power, &setup, path, &q);
            let direct = direct_weights(power, path, &q);
            let sum: f32 = bpt.iter().sum();
            assert!(
                (sum - 1.0).abs() < 1e-4,
                "{name}: BPT weights of a {}-segment path sum to {sum} (beta {beta}): {bpt:?}",
                q.k
            );
            for (s, (&w, &d)) in bpt.iter().zip(&direct).enumerate() {
                assert!(
                    (w as f64 - d).abs() < 1e-4,
                    "{name}: technique s = {s} of a {}-segment path: recursive weight {w}, \
                     direct {d} (beta {beta})",
                    q.k
                );
            }
            for gather in [
                Gather::Density,
                Gather::UpgLight,
                Gather::UpgCamera,
                Gather::Hybrid,
                Gather::Blend,
            ] {
                // Large radii make UPG's clamped acceptance min(p pi r^2, 1) bind.
                for radius in [1e-3, 1e-2, 0.1, 0.5, 1.0] {
                    let w = if gather.clamps() {
                        VcmWeights::clamped(power, radius, setup.n())
                    } else {
                        VcmWeights::new(power, radius, setup.n(), true, true)
                    };
                    let (vc, vm) = vcm_weights(&w, gather, path, &q, &[]);
                    let sum: f32 = vc.iter().sum::<f32>() + vm.iter().sum::<f32>();
                    assert!(
                        (sum - 1.0).abs() < 1e-4,
                        "{name}: {gather:?} weights of a {}-segment path sum to {sum} \
                         (beta {beta}, r {radius}): VC {vc:?} VM {vm:?}",
                        q.k
                    );
                    if vm.iter().any(|&m| m > 1e-3) {
                        merged += 1;
                    }
                    if gather == Gather::Hybrid {
                        // Which side gathered each merge that weighs: the rule on x_{j-1}.
                        for (j, _) in vm.iter().enumerate().filter(|(_, &m)| m > 1e-3) {
                            let x = j + 1;
                            let rough = x >= 2 && q.connectable[x - 1] && !q.glossy[x - 1];
                            hybrid_sides[usize::from(!rough)] += 1;
                        }
                    }
                    if gather.clamps() {
                        // Merge-only UPG (000 sec. 5.2): the merges of a path that has any
                        // share it among themselves.
                        let only = VcmWeights::clamped_merges_only(power, radius, setup.n());
                        let (_, only_vm) = vcm_weights(&only, gather, path, &q, &[]);
                        let sum: f32 = only_vm.iter().sum();
                        let merges = only_vm.iter().filter(|&&m| m > 0.0).count();
                        assert!(
                            merges == 0 || (sum - 1.0).abs() < 1e-4,
                            "{name}: merge-only {gather:?} weights of a {}-segment path sum \
                             to {sum} (beta {beta}, r {radius}): {only_vm:?}",
                            q.k
                        );
                        if merges > 1 {
                            shared_merges += 1;
                        }
                        // The same techniques without the clamp: where the weights differ,
                        // min(p pi r^2, 1) was 1 somewhere.
                        let free = VcmWeights::new(power, radius, setup.n(), true, true);
                        let (free_vc, free_vm) = vcm_weights(&free, gather, path, &q, &[]);
                        let differs = |a: &[f32], b: &[f32]| {
                            a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-3)
                        };
                        if differs(&vc, &free_vc) || differs(&vm, &free_vm) {
                            clamped += 1;
                        }
                    }
                }
            }
            // 002's heuristics with a random, fixed density: 1 / k per vertex in [1e-3, 1].
            let mut rng = Rng::for_sample(q.k as u64, beta as u64, 0, Stream::Light);
            let inv_k: Vec<f32> = (0..=q.k)
                .map(|_| 10f32.powf(-3.0 * rng.next_f32()))
                .collect();
            // UPG's clamped merges take them too, at radii up to where the clamp binds.
            for mode in [DensityMis::Plus, DensityMis::Star] {
                for (label, gather, radii) in [
                    ("vcm", Gather::Density, [1e-3, 1e-2, 0.1]),
                    ("upg", Gather::UpgLight, [1e-2, 0.1, 1.0]),
                    ("upg-camera", Gather::UpgCamera, [1e-2, 0.1, 1.0]),
                    ("upg-hybrid", Gather::Hybrid, [1e-2, 0.1, 1.0]),
                ] {
                    for radius in radii {
                        let plain = if gather == Gather::Density {
                            VcmWeights::new(power, radius, setup.n(), true, true)
                        } else {
                            VcmWeights::clamped(power, radius, setup.n())
                        };
                        let w = plain.with_density(mode);
                        let (vc, vm) = vcm_weights(&w, gather, path, &q, &inv_k);
                        let sum: f32 = vc.iter().sum::<f32>() + vm.iter().sum::<f32>();
                        assert!(
                            (sum - 1.0).abs() < 1e-4,
                            "{name}: {label} {mode:?} weights of a {}-segment path sum to \
                             {sum} (beta {beta}, r {radius}): VC {vc:?} VM {vm:?}",
                            q.k
                        );
                        let (plain_vc, plain_vm) = vcm_weights(&plain, gather, path, &q, &[]);
                        let differs = |a: &[f32], b: &[f32]| {
                            a.iter().zip(b).any(|(x, y)| (x - y).abs() > 1e-3)
                        };
                        if differs(&vc, &plain_vc) || differs(&vm, &plain_vm) {
                            *reweighted.entry((label, mode.name())).or_insert(0) += 1;
                        }
                        if gather != Gather::Density {
                            // Merge-only UPG: the merges share the path by their density
                            // factors alone.
                            let only = VcmWeights::clamped_merges_only(power, radius, setup.n())
                                .with_density(mode);
                            let (_, only_vm) = vcm_weights(&only, gather, path, &q, &inv_k);
                            let sum: f32 = only_vm.iter().sum();
                            let merges = only_vm.iter().filter(|&&m| m > 0.0).count();
                            assert!(
                                merges == 0 || (sum - 1.0).abs() < 1e-4,
                                "{name}: merge-only {label} {mode:?} weights of a {}-segment \
                                 path sum to {sum} (beta {beta}, r {radius}): {only_vm:?}",
                                q.k
                            );
                        }
                    }
                }
            }
            // 001 sec. 6.1: every path's eye sub-path merges at its own radius, drawn at
            // random over three decades; the light sub-path knows none of them.
            for gather_radius in [1e-2, 0.1] {
                let light_w =
                    VcmWeights::new(power, gather_radius, setup.n(), true, true).radius_free();
                let radius = 10f32.powf(-3.0 * rng.next_f32());
                let eye_w = light_w.at_radius(radius);
                let (vc, vm) = vcm_weights_with(
                    LightSide::Resolved(&light_w),
                    &eye_w,
                    Gather::Density,
                    path,
                    &q,
                    &|_, _| None,
                );
                let sum: f32 = vc.iter().sum::<f32>() + vm.iter().sum::<f32>();
                assert!(
                    (sum - 1.0).abs() < 1e-4,
                    "{name}: per-pixel radius weights of a {}-segment path sum to {sum} \
                     (beta {beta}, eye r {radius}): VC {vc:?} VM {vm:?}",
                    q.k
                );
                if vm.iter().any(|&m| m > 1e-3) && vc.iter().any(|&c| c > 1e-3) {
                    per_pixel_mixed += 1;
                }
            }
            // 001 sec. 6.1 where a light sub-path cannot carry radius-free sums: UPG's clamp and
            // 002's density factors. The light sub-path is traced at a global radius; every
            // technique re-runs its steps at the eye sub-path's own radius, drawn at random over
            // three decades up to radii where the clamp binds. 1 / k follows a fixed density
            // per vertex, clamped to [1, n_VM] as the density map's lookup is.
            let density: Vec<f32> = (0..=q.k)
                .map(|_| 10f32.powf(2.0 + 5.0 * rng.next_f32()))
                .collect();
            let n = setup.n();
            let inv_k_at = |i: usize, r: f32| {
                let k = density[i] * std::f32::consts::PI * r * r;
                Some(1.0 / k.clamp(1.0, n))
            };
            for (mode, gather, density) in PER_PIXEL {
                for gather_radius in [1e-2, 0.1] {
                    let plain = if gather == Gather::Density {
                        VcmWeights::new(power, gather_radius, n, true, true)
                    } else {
                        VcmWeights::clamped(power, gather_radius, n)
                    };
                    let light_w = match density {
                        Some(d) => plain.with_density(d),
                        None => plain,
                    };
                    let radius = 10f32.powf(-3.0 * rng.next_f32());
                    let eye_w = light_w.at_radius(radius);
                    let inv_k: &dyn Fn(usize, f32) -> Option<f32> = match density {
                        Some(_) => &inv_k_at,
                        None => &|_, _| None,
                    };
                    let sum = |side| {
                        let (vc, vm) = vcm_weights_with(side, &eye_w, gather, path, &q, inv_k);
                        let sum = vc.iter().sum::<f32>() + vm.iter().sum::<f32>();
                        (sum, vc, vm)
                    };
                    let (replayed, vc, vm) = sum(LightSide::Replayed(&light_w));
                    assert!(
                        (replayed - 1.0).abs() < 1e-4,
                        "{name}: per-pixel {mode} weights of a {}-segment path sum to \
                         {replayed} (beta {beta}, light r {gather_radius}, eye r {radius}): \
                         VC {vc:?} VM {vm:?}",
                        q.k
                    );
                    if vm.iter().any(|&m| m > 1e-3) && vc.iter().any(|&c| c > 1e-3) {
                        *replay_mixed.entry(mode).or_insert(0) += 1;
                    }
                    // Re-run at the radius it was traced with, the light sub-path gives the
                    // weights it gives as traced.
                    let (traced, traced_vc, traced_vm) = {
                        let (vc, vm) =
                            vcm_weights_with(LightSide::Same, &light_w, gather, path, &q, inv_k);
                        (vc.iter().sum::<f32>() + vm.iter().sum::<f32>(), vc, vm)
                    };
                    let (again_vc, again_vm) = vcm_weights_with(
                        LightSide::Replayed(&light_w),
                        &light_w,
                        gather,
                        path,
                        &q,
                        inv_k,
                    );
                    let same = |a: &[f32], b: &[f32]| {
                        a.iter()
                            .zip(b)
                            .all(|(x, y)| (x - y).abs() <= 1e-6 * x.abs().max(1.0))
                    };
                    assert!(
                        (traced - 1.0).abs() < 1e-4
                            && same(&traced_vc, &again_vc)
                            && same(&traced_vm, &again_vm),
                        "{name}: {mode} re-run at its own radius: VC {again_vc:?} VM \
                         {again_vm:?}, traced VC {traced_vc:?} VM {traced_vm:?}"
                    );
                    // The light sub-path as traced, at the global radius, does not sum to 1.
                    let (stored, _, _) = sum(LightSide::Stored(&light_w));
                    if (stored - 1.0).abs() > 1e-3 {
                        *replay_needed.entry(mode).or_insert(0) += 1;
                    }
                }
            }
            // VC alone is BPT: the two recursions give the same weights.
            let w = VcmWeights::new(power, 0.01, setup.n(), true, false);
            let (vc, _) = vcm_weights(&w, Gather::Density, path, &q, &[]);
            for (s, (a, b)) in vc.iter().zip(&bpt).enumerate() {
                assert!(
                    (a - b).abs() < 1e-4,
                    "{name}: s = {s}: VCM without merging {a}, BPT {b}"
                );
            }
        }
    }
    assert!(
        per_pixel_mixed > 0,
        "{name}: no per-pixel radius weighed merges against connections"
    );
    for (mode, _, _) in PER_PIXEL {
        let (mixed, needed) = (
            replay_mixed.get(mode).copied().unwrap_or(0),
            replay_needed.get(mode).copied().unwrap_or(0),
        );
        assert!(
            mixed > 0,
            "{name}: no per-pixel {mode} radius weighed merges against connections"
        );
        assert!(
            needed > 0,
            "{name}: per-pixel {mode}: the stored light sub-path always summed to 1"
        );
    }
    assert!(clamped > 0, "{name}: the clamp never bound");
    assert!(
        hybrid_sides.iter().all(|&n| n > 0),
        "{name}: upg-hybrid's merges from the light and the camera side: {hybrid_sides:?}"
    );
    for label in ["vcm", "upg", "upg-camera", "upg-hybrid"] {
        for mode in [DensityMis::Plus, DensityMis::Star] {
            assert!(
                reweighted.get(&(label, mode.name())).copied().unwrap_or(0) > 0,
                "{name}: {label} {mode:?} never changed a weight"
            );
        }
    }
    assert!(
        shared_merges > 0,
        "{name}: no path had two merge-only UPG techniques"
    );
    (specular, merged)
}

#[test]
fn weights_sum_to_one_in_the_furnace() {
    check_scene("furnace", Aim::Disc);
}

#[test]
fn weights_sum_to_one_with_phong() {
    let (_, merged) = check_scene("cornell-glossy", Aim::Disc);
    assert!(merged > 0, "no path gave a merge any weight");
}

#[test]
fn weights_sum_to_one_with_mirror_and_glass() {
    let (specular, _) = check_scene("cornell-spheres", Aim::Disc);
    assert!(specular > 20, "only {specular} paths had a specular vertex");
}

#[test]
fn weights_sum_to_one_with_microfacet_conductors_and_dielectrics() {
    let (specular, merged) = check_scene("microfacets", Aim::Disc);
    assert!(specular > 10, "only {specular} paths had a specular vertex");
    assert!(merged > 0, "no path gave a merge any weight");
    // The same paths (check_scene's seed and count): enough of them scatter on a rough lobe.
    let (scene, all) = paths("microfacets", 7, 40, Aim::Disc);
    let rough = |v: &Vertex| match *v {
        Vertex::Surface {
            material,
            delta: false,
            ..
        } => matches!(
            scene.material(material).kind,
            MaterialKind::Conductor { .. } | MaterialKind::Dielectric { .. }
        ),
        _ => false,
    };
    let through = all.iter().filter(|p| p.vertices.iter().any(rough)).count();
    assert!(through > 20, "only {through} paths scatter on a rough lobe");
}

#[test]
fn weights_sum_to_one_with_point_directional_and_sky_lights() {
    for name in ["cornell-point", "cornell-sun", "cornell-sky", "caustic"] {
        for aim in [Aim::Disc, Aim::Silhouette] {
            check_scene(name, aim);
        }
    }
}

/// A shipped scene by its name, or a test scene by its folder under tests/ (`fixtures/...`).
fn load_scene(name: &str) -> Scene {
    if !name.starts_with("fixtures/") {
        return common::load(name);
    }
    let path = format!("{}/tests/{name}/scene.toml", env!("CARGO_MANIFEST_DIR"));
    let options = vmerge::scene::LoadOptions {
        accel: vmerge::accel::AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    };
    vmerge::scene::load(path.as_ref(), &options).unwrap_or_else(|e| panic!("{e}"))
}

/// Paths that start at a spot light: its falloff in the light-sampling radiance and its cone
/// sampling in the emission pdf.
#[test]
fn weights_sum_to_one_with_a_spot_light() {
    check_scene("fixtures/lights/spot", Aim::Disc);
}

/// Paths that start on either side of two-sided emitters, whose emission pdf is halved.
#[test]
fn weights_sum_to_one_with_two_sided_lights() {
    check_scene("fixtures/lights/twosided", Aim::Disc);
}

/// pbrt-v4's diffuse transmission, rough coated diffuse, coated conductor and a mix of coated
/// diffuses: paths through their lobes (sampled non-delta) have weights that sum to 1.
#[test]
fn weights_sum_to_one_with_layered_and_mixed_materials() {
    let (_, merged) = check_scene("layered", Aim::Disc);
    assert!(merged > 0, "no path gave a merge any weight");
}
