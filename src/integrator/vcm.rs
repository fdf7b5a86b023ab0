//! Vertex connection and merging (001), and the techniques that are special cases of it: light
//! tracing (`lt`), bidirectional photon mapping (`bpm`, VM only: 001 sec. 5.6) and progressive
//! photon mapping (`ppm`, one merge at the first non-specular eye vertex). With `--no-vm` it is
//! BPT (001 sec. 5.5, eta_VCM = 0), which `bpt.rs` implements separately as its cross-check.
//!
//! The structure follows SmallVCM's VertexCM: an iteration traces one light sub-path per pixel
//! (n_light = n_VM = pixel count, 001 sec. 2.3), stores its non-specular vertices with the MIS
//! quantities d_vcm, d_vc, d_vm (001 eqs. 31-36) and connects them to the camera; builds the
//! hash grid over them; then traces one eye sub-path per pixel that at every non-specular vertex
//! takes emission, a light sample, connections to its pixel's light sub-path and merges with
//! nearby light vertices, each weighted by 001 eqs. 37-47. Every quantity is SmallVCM's "with
//! the power already applied" form: `mis(x) = x^beta`.
//!
//! Unbiased photon gathering (`upg`, `upg-camera`; 000 secs. 2.4.3-2.4.6) is the same family
//! with another merge: instead of a density estimate, an explicit connection from the merge
//! vertex's neighbour on the gathering side, divided by the acceptance probability that
//! tentative rays estimate (`upg/acceptance.rs`), weighted with the clamped acceptance.
//!
//! Russian roulette is left out of the pdfs the weights use: weights only need to sum to one
//! over the techniques, and every technique evaluates the same pdfs.

use super::connection::{Connection, LightSample};
use super::mis::{Power, VcmVertex, VcmWeights, VmHere};
use super::upg::acceptance::{
    AngularBound, Estimator, Outcome, PacketWidth, StoredVerticesOnly, TentativeTracer,
};
use super::{Integrator, IterationStats, RenderContext, Technique, UpgCounters};
use crate::accel::Ray;
use crate::bsdf::{Bsdf, Normals, TransportMode};
use crate::color::Rgb;
use crate::film::add_sample;
use crate::hashgrid::HashGrid;
use crate::sampling::{Rng, Stream};
use crate::scene::{Scene, SurfaceHit};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Light paths traced by one parallel task. Fixed, so results do not depend on threads.
const LIGHT_CHUNK: usize = 256;

/// Which techniques run and are weighted against each other.
#[derive(Clone, Copy, Debug)]
struct Modes {
    /// Vertex connection: light sampling, light-to-camera and sub-path connections.
    vc: bool,
    /// Vertex merging.
    vm: bool,
    /// Progressive photon mapping: merge only at the first non-specular eye vertex.
    ppm: bool,
    /// Light tracing alone: light vertices splatted to the camera with weight 1.
    light_trace: bool,
    /// How a merge is made.
    merge: Merge,
}

/// Vertex merging by density estimation (001), or unbiased photon gathering from either side
/// (000 sec. 2.4.3): an explicit connection whose pdf holds the estimated 1/p_acc.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Merge {
    Density,
    /// `upg`: the light vertex's predecessor is connected to the eye vertex.
    UpgLight,
    /// `upg-camera`: the eye vertex's predecessor is connected to the light vertex.
    UpgCamera,
}

impl Modes {
    fn for_technique(technique: Technique, no_vc: bool, no_vm: bool) -> Self {
        let (vc, vm, ppm, light_trace) = match technique {
            Technique::Lt => (false, false, false, true),
            Technique::Ppm => (false, true, true, false),
            Technique::Bpm => (false, true, false, false),
            Technique::Upg | Technique::UpgCamera => (true, true, false, false),
            _ => (!no_vc, !no_vm, false, false),
        };
        let merge = match technique {
            Technique::Upg => Merge::UpgLight,
            Technique::UpgCamera => Merge::UpgCamera,
            _ => Merge::Density,
        };
        Modes {
            vc,
            vm,
            ppm,
            light_trace,
            merge,
        }
    }

    /// Whether merging at the vertex a sub-path scatters from is a technique. UPG's tentative
    /// rays leave from the merge vertex's neighbour on the gathering side, which must be a
    /// non-delta surface vertex: on the light side for `upg` (known: the previous vertex),
    /// on the eye side for `upg-camera` (known for the eye sub-path, the next vertex for the
    /// light sub-path).
    fn merge_here(&self, light_side: bool, prev_surface: bool) -> VmHere {
        let known = |ok: bool| if ok { VmHere::Valid } else { VmHere::Invalid };
        match (self.merge, light_side) {
            (Merge::Density, _) => VmHere::Valid,
            (Merge::UpgLight, true) | (Merge::UpgCamera, false) => known(prev_surface),
            (Merge::UpgLight, false) | (Merge::UpgCamera, true) => VmHere::Deferred,
        }
    }
}

/// A stored light sub-path vertex: everything a connection or a merge needs (100 bytes).
#[derive(Clone, Copy, Debug)]
pub struct LightVertex {
    pub position: Vec3,
    /// Geometric normal.
    pub ng: Vec3,
    /// Shading normal and texture coordinates, for the BSDF there.
    pub ns: Vec3,
    pub uv: Vec2,
    /// Unit direction back towards the previous vertex of the light sub-path.
    pub wo: Vec3,
    pub throughput: Rgb,
    pub material: u32,
    /// Segments from the light to this vertex.
    pub path_length: u32,
    pub mis: VcmVertex,
    /// The previous vertex of the sub-path is a non-delta surface vertex, stored just before
    /// this one.
    pub after_surface: bool,
}

/// What one task of the light pass produces: vertices and where each path's end, camera
/// splats, counters.
#[derive(Default)]
struct LightChunk {
    vertices: Vec<LightVertex>,
    ends: Vec<u32>,
    splats: Vec<(usize, Rgb)>,
    stats: IterationStats,
}

/// The state of a sub-path being traced (SmallVCM's SubPathState).
#[derive(Clone, Copy, Debug)]
struct SubPath {
    ray: Ray,
    throughput: Rgb,
    path_length: u32,
    /// Light sub-paths: started on a finite light (distance terms apply to the first segment).
    finite_light: bool,
    /// Eye sub-paths: every scattering so far was a delta lobe.
    specular: bool,
    /// The vertex the ray left from is a non-delta surface vertex.
    prev_surface: bool,
    mis: VcmVertex,
}

/// The last eye vertex, kept for `upg-camera`'s merges at the next one.
#[derive(Clone)]
struct EyeVertex<'b> {
    hit: SurfaceHit,
    bsdf: Bsdf<'b>,
    /// Throughput and MIS quantities on arrival, before scattering on.
    throughput: Rgb,
    mis: VcmVertex,
    prev_surface: bool,
    path_length: u32,
}

pub struct VertexCm<'a> {
    ctx: RenderContext<'a>,
    modes: Modes,
    base_radius: f32,
    alpha: f32,
    /// UPG's estimator of 1/p_acc.
    estimator: Estimator,
    /// Light vertices stored in the last iteration, for the statistics.
    stored_vertices: usize,
    /// UPG's counters over all iterations so far.
    upg: UpgCounters,
}

impl<'a> VertexCm<'a> {
    pub fn new(ctx: RenderContext<'a>) -> Self {
        let o = ctx.options;
        let modes = Modes::for_technique(o.technique, o.no_vc, o.no_vm);
        let base_radius = o.radius.unwrap_or_else(|| ctx.scene.default_radius());
        // UPG is unbiased at any radius: it keeps its radius (000 sec. 2.4.6).
        let alpha = if modes.vm && modes.merge == Merge::Density {
            o.alpha.unwrap_or(0.75)
        } else {
            1.0
        };
        let estimator = Estimator {
            packet: if o.upg_packet == 8 {
                PacketWidth::Eight
            } else {
                PacketWidth::One
            },
            max_trials: o.upg_max_trials,
        };
        VertexCm {
            ctx,
            modes,
            base_radius,
            alpha,
            estimator,
            stored_vertices: 0,
            upg: UpgCounters::default(),
        }
    }

    /// The constants of iteration `iteration` (0-based): 000 eq. 2.85's radius
    /// r_i = r_1 sqrt(i^(alpha - 1)) for i = iteration + 1.
    fn weights(&self, iteration: u64) -> VcmWeights {
        let i = (iteration + 1) as f32;
        let radius = (self.base_radius * i.powf(0.5 * (self.alpha - 1.0))).max(1e-7);
        let (power, paths) = (
            Power(self.ctx.options.beta),
            self.ctx.camera.pixel_count() as f32,
        );
        if self.modes.merge == Merge::Density {
            VcmWeights::new(power, radius, paths, self.modes.vc, self.modes.vm)
        } else {
            VcmWeights::clamped(power, radius, paths)
        }
    }

    fn scene(&self) -> &Scene {
        self.ctx.scene
    }

    /// Starts a light sub-path (SmallVCM's GenerateLightSample; 001 eqs. 31-33).
    fn light_sample(&self, w: &VcmWeights, rng: &mut Rng) -> Option<SubPath> {
        let lights = &self.scene().lights;
        let (index, pick) = lights.pick(rng.next_f32())?;
        let light = lights.get(index);
        let (u_pos, u_dir) = (rng.next_2d(), rng.next_2d());
        let e = light.emit(u_pos, u_dir)?;
        let emission_pdf_w = e.emission_pdf_w * pick;
        let direct_pdf_a = e.direct_pdf_a * pick;
        if emission_pdf_w.is_nan() || emission_pdf_w <= 0.0 {
            return None;
        }
        let cos_at_light = if light.is_finite() {
            e.cos_at_light
        } else {
            1.0
        };
        let origin = if light.is_finite() && !light.is_delta() {
            Ray::spawn(e.position, e.normal, e.dir).origin
        } else {
            e.position
        };
        Some(SubPath {
            ray: Ray::new(origin, e.dir),
            throughput: e.energy / emission_pdf_w,
            path_length: 1,
            finite_light: light.is_finite(),
            specular: false,
            prev_surface: false,
            mis: w.light_origin(direct_pdf_a, emission_pdf_w, cos_at_light, light.is_delta()),
        })
    }

    /// Continues a sub-path by sampling the BSDF (SmallVCM's SampleScattering; 001 eqs. 34-36).
    /// `None` ends the path.
    fn scatter(
        &self,
        w: &VcmWeights,
        state: &mut SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        rng: &mut Rng,
        light_side: bool,
    ) -> Option<()> {
        let s = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()])?;
        if state.path_length >= self.ctx.options.roulette {
            let q = bsdf.continuation_probability();
            if rng.next_f32() >= q {
                return None;
            }
            state.throughput /= q;
        }
        let cos_out = bsdf.cos_theta(s.wi);
        let merge_here = self.modes.merge_here(light_side, state.prev_surface);
        w.scatter(
            &mut state.mis,
            cos_out,
            s.pdf_w,
            s.rev_pdf_w,
            s.delta,
            merge_here,
        );
        state.prev_surface = !s.delta;
        if !s.delta {
            state.specular = false;
        }
        state.throughput *= s.f * (cos_out / s.pdf_w);
        if state.throughput.is_black() {
            return None;
        }
        state.ray = Ray::spawn(hit.position, hit.ng, s.wi);
        state.path_length += 1;
        Some(())
    }

    /// Distance and cosine updates at a newly found vertex (SmallVCM; 001 eqs. 34-36 use the
    /// reverse geometry factor).
    fn arrive(&self, w: &VcmWeights, state: &mut SubPath, hit: &SurfaceHit, light_side: bool) {
        let distance = hit.hit.t * state.ray.dir.length();
        let with_distance = !light_side || state.path_length > 1 || state.finite_light;
        let cos = hit.ng.dot(-state.ray.dir.normalize()).abs();
        w.arrive(&mut state.mis, distance, cos, with_distance);
    }

    /// Traces the light sub-path `index`; stores its vertices and returns its camera splats.
    fn trace_light_path(
        &self,
        w: &VcmWeights,
        iteration: u64,
        index: usize,
        vertices: &mut Vec<LightVertex>,
        splats: &mut Vec<(usize, Rgb)>,
        stats: &mut IterationStats,
    ) {
        let mut rng = Rng::for_sample(
            self.ctx.options.seed,
            iteration,
            index as u64,
            Stream::Light,
        );
        let Some(mut state) = self.light_sample(w, &mut rng) else {
            return;
        };
        let max_length = self.ctx.max_path_length();
        loop {
            stats.rays += 1;
            let Some(hit) = self.scene().intersect(&state.ray) else {
                break;
            };
            let dir = state.ray.dir.normalize();
            self.arrive(w, &mut state, &hit, true);
            let Some(bsdf) = self.scene().bsdf_at(&hit, -dir, TransportMode::Importance) else {
                break;
            };
            w.drop_pending(&mut state.mis, !bsdf.is_delta());
            if !bsdf.is_delta() {
                if self.modes.vc || self.modes.vm {
                    vertices.push(LightVertex {
                        position: hit.position,
                        ng: hit.ng,
                        ns: hit.ns,
                        uv: hit.uv,
                        wo: -dir,
                        throughput: state.throughput,
                        material: hit.material,
                        path_length: state.path_length,
                        mis: state.mis,
                        after_surface: state.prev_surface,
                    });
                }
                if self.modes.vc || self.modes.light_trace {
                    self.connect_to_camera(w, &state, &hit, &bsdf, splats, stats);
                }
            }
            if state.path_length.saturating_add(2) > max_length {
                break;
            }
            if self
                .scatter(w, &mut state, &hit, &bsdf, &mut rng, true)
                .is_none()
            {
                break;
            }
        }
    }

    /// Connects a light vertex to the camera and splats it (t = 1; 001 eqs. 46-47).
    fn connect_to_camera(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        splats: &mut Vec<(usize, Rgb)>,
        stats: &mut IterationStats,
    ) {
        let camera = &self.ctx.camera;
        let Some((x, y)) = camera.raster(hit.position) else {
            return;
        };
        let to_camera = camera.position - hit.position;
        let dist2 = to_camera.length_squared();
        let dir = to_camera / dist2.sqrt();
        let eval = bsdf.eval(dir);
        if eval.f.is_black() {
            return;
        }
        let cos_surface = bsdf.cos_theta(dir);
        // Pixel-area density of the image point, turned into an area density at the vertex.
        let camera_pdf_a = camera.pdf_w(-dir) * cos_surface / dist2;
        let weight = if self.modes.light_trace {
            1.0
        } else {
            // Merging at this vertex: `upg` needs its predecessor, `upg-camera` the camera as
            // the neighbour the tentative rays would leave from, which cannot be.
            let merge_here = match self.modes.merge {
                Merge::Density => true,
                Merge::UpgLight => state.prev_surface,
                Merge::UpgCamera => false,
            };
            let eta = w.eta_if(merge_here, state.mis.d_vcm);
            w.to_camera(&state.mis, eta, camera_pdf_a, eval.rev_pdf_w)
        };
        let contribution = state.throughput * eval.f * (weight * camera_pdf_a / w.light_paths);
        stats.rays += 1;
        if !self
            .scene()
            .occluded(&Ray::spawn_to(hit.position, hit.ng, camera.position))
        {
            splats.push((camera.pixel_index(x, y), contribution));
        }
    }

    /// Emission reached by an eye sub-path: an area light at `hit`, or the sky when `hit` is
    /// `None` (s = 0; 001 eqs. 42-43).
    fn emission(&self, w: &VcmWeights, state: &SubPath, hit: Option<&SurfaceHit>) -> Rgb {
        let lights = &self.scene().lights;
        let dir = state.ray.dir.normalize();
        let Some((received, index)) = lights.received(dir, hit.map(|h| (h.light, h.ng))) else {
            return Rgb::BLACK;
        };
        if state.path_length == 1 {
            return received.radiance;
        }
        // Without connections only purely specular eye paths may take emission: every other
        // path is found by merging (SmallVCM's ppm and bpm).
        if !self.modes.vc {
            return if state.specular {
                received.radiance
            } else {
                Rgb::BLACK
            };
        }
        let pick = lights.pick_pdf(index);
        received.radiance
            * w.hit_light(
                &state.mis,
                received.direct_pdf_a * pick,
                received.emission_pdf_w * pick,
            )
    }

    /// Next-event estimation (s = 1; 001 eqs. 44-45).
    fn light_sampling(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        rng: &mut Rng,
        stats: &mut IterationStats,
    ) -> Rgb {
        let Some(ls) = LightSample::draw(self.scene(), hit, bsdf, rng) else {
            return Rgb::BLACK;
        };
        // Merging here: `upg` would gather from the light point itself, which it does not.
        let merge_here = match self.modes.merge {
            Merge::Density => true,
            Merge::UpgLight => false,
            Merge::UpgCamera => state.prev_surface,
        };
        let weight = w.light_sample(
            &state.mis,
            w.eta_if(merge_here, state.mis.d_vcm),
            ls.eval.pdf_w,
            ls.eval.rev_pdf_w,
            ls.pdf_w(),
            ls.il.direct_pdf_w,
            ls.il.emission_pdf_w,
            ls.cos_at_receiver,
            ls.il.cos_at_light,
            ls.light.is_delta(),
        );
        stats.rays += 1;
        if !ls.visible(self.scene(), hit) {
            return Rgb::BLACK;
        }
        ls.contribution(weight)
    }

    /// Connects an eye vertex to a light vertex (s, t > 1; 001 eqs. 40-41).
    fn connect(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        lv: &LightVertex,
        stats: &mut IterationStats,
    ) -> Rgb {
        let Some(light_bsdf) = self.vertex_bsdf(lv) else {
            return Rgb::BLACK;
        };
        let Some(c) = Connection::new(bsdf, hit.position, &light_bsdf, lv.position) else {
            return Rgb::BLACK;
        };
        // Area pdfs of each end as the other end samples it.
        let (eye_pdf_a, light_pdf_a) = (c.to_pdf_a(), c.from_pdf_a());
        // Merging at either end: each end's neighbour across the connection is a non-delta
        // surface vertex; `upg` also needs the light vertex's predecessor to be one, and
        // `upg-camera` the eye vertex's. The gathering side's pdf of the merge vertex is the
        // sub-path's own (its d^VCM) or, across the connection, the other end's.
        let (light_eta, eye_eta) = match self.modes.merge {
            Merge::Density => (w.vm_factor, w.vm_factor),
            Merge::UpgLight => (
                w.eta_if(lv.after_surface, lv.mis.d_vcm),
                w.eta(w.mis(1.0 / light_pdf_a)),
            ),
            Merge::UpgCamera => (
                w.eta(w.mis(1.0 / eye_pdf_a)),
                w.eta_if(state.prev_surface, state.mis.d_vcm),
            ),
        };
        let weight = w.connect(
            &lv.mis,
            light_eta,
            &state.mis,
            eye_eta,
            c.to_eval.rev_pdf_w,
            c.from_eval.rev_pdf_w,
            light_pdf_a,
            eye_pdf_a,
        );
        stats.rays += 1;
        if self.scene().occluded(&Ray::spawn_between(
            hit.position,
            hit.ng,
            lv.position,
            lv.ng,
        )) {
            return Rgb::BLACK;
        }
        c.value * lv.throughput * weight
    }

    /// Merges an eye vertex with the light vertices around it (001 eqs. 38-39), not yet
    /// normalised by 1 / (pi r^2 n_VM).
    fn merge(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        bsdf: &Bsdf,
        hit: &SurfaceHit,
        grid: &HashGrid,
        vertices: &[LightVertex],
    ) -> Rgb {
        let max_length = self.ctx.max_path_length();
        let mut sum = Rgb::BLACK;
        grid.query(hit.position, |i, _| {
            let lv = &vertices[i];
            if lv.path_length.saturating_add(state.path_length) > max_length {
                return;
            }
            let eval = bsdf.eval(lv.wo);
            if eval.f.is_black() {
                return;
            }
            // PPM takes its one merge per eye path unweighted: no other technique competes.
            let weight = if self.modes.ppm {
                1.0
            } else {
                w.merge(&lv.mis, &state.mis, eval.pdf_w, eval.rev_pdf_w, w.vm_factor)
            };
            sum += eval.f * lv.throughput * weight;
        });
        sum
    }

    /// `upg`: gathers the light vertices within r of the eye vertex `hit` whose predecessor Q is
    /// a non-delta surface vertex, and for each connects Q to the eye vertex explicitly (000
    /// eq. 2.67), the tentative rays from Q estimating 1/p_acc (000 eq. 2.65).
    #[allow(clippy::too_many_arguments)]
    fn merge_upg_light<'s>(
        &'s self,
        w: &VcmWeights,
        state: &SubPath,
        bsdf: &Bsdf,
        hit: &SurfaceHit,
        grid: &HashGrid,
        vertices: &[LightVertex],
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) -> Rgb {
        let max_length = self.ctx.max_path_length();
        grid.query(hit.position, |i, _| {
            let photon = &vertices[i];
            if !photon.after_surface {
                return;
            }
            let q = &vertices[i - 1];
            if q.path_length + 1 + state.path_length > max_length {
                return;
            }
            let Some(q_bsdf) = self.vertex_bsdf(q) else {
                return;
            };
            let Some(link) = self.link(
                (&q_bsdf, q.position, q.ng),
                (bsdf, hit.position, hit.ng),
                stats,
            ) else {
                return;
            };
            let Ok(bound) = AngularBound::new(q.position, q.ng, &q_bsdf, hit.position, w.radius)
            else {
                return;
            };
            // The light sub-path's quantities as they would be at the eye vertex.
            let merge_at_q = self.modes.merge_here(true, q.after_surface);
            let light = carry(w, &link, q.mis, merge_at_q);
            let weight = w.merge(
                &light,
                &state.mis,
                link.to_eval.pdf_w,
                link.to_eval.rev_pdf_w,
                w.eta(light.d_vcm),
            );
            let roulette = self.roulette_probability(&q_bsdf, q.path_length);
            tentative.push(bound, q.throughput * link.value * (weight / roulette));
        });
        self.estimate_merges(tentative, stats)
    }

    /// `upg-camera`: gathers the light vertices within r of the eye vertex the eye sub-path just
    /// reached, and connects each to the previous eye vertex `prev` explicitly, the tentative
    /// rays from `prev` estimating 1/p_acc (000 sec. 2.4.3, UPG*).
    #[allow(clippy::too_many_arguments)]
    fn merge_upg_camera<'s>(
        &'s self,
        w: &VcmWeights,
        prev: &EyeVertex<'s>,
        position: Vec3,
        grid: &HashGrid,
        vertices: &[LightVertex],
        tentative: &mut Tentative<'s>,
        stats: &mut IterationStats,
    ) -> Rgb {
        let max_length = self.ctx.max_path_length();
        grid.query(position, |i, _| {
            let photon = &vertices[i];
            if photon.path_length + 1 + prev.path_length > max_length {
                return;
            }
            let Some(p_bsdf) = self.vertex_bsdf(photon) else {
                return;
            };
            let Some(link) = self.link(
                (&prev.bsdf, prev.hit.position, prev.hit.ng),
                (&p_bsdf, photon.position, photon.ng),
                stats,
            ) else {
                return;
            };
            let Ok(bound) = AngularBound::new(
                prev.hit.position,
                prev.hit.ng,
                &prev.bsdf,
                photon.position,
                w.radius,
            ) else {
                return;
            };
            // The eye sub-path's quantities as they would be at the light vertex.
            let merge_at_prev = self.modes.merge_here(false, prev.prev_surface);
            let eye = carry(w, &link, prev.mis, merge_at_prev);
            // At the merge vertex the eye side samples towards the light vertex's predecessor:
            // the photon's BSDF pdfs, seen the other way round.
            let weight = w.merge(
                &photon.mis,
                &eye,
                link.to_eval.rev_pdf_w,
                link.to_eval.pdf_w,
                w.eta(eye.d_vcm),
            );
            let roulette = self.roulette_probability(&prev.bsdf, prev.path_length);
            tentative.push(
                bound,
                prev.throughput * photon.throughput * link.value * (weight / roulette),
            );
        });
        self.estimate_merges(tentative, stats)
    }

    /// The BSDF at a stored light vertex, for importance.
    fn vertex_bsdf(&self, v: &LightVertex) -> Option<Bsdf<'_>> {
        let normals = Normals { ng: v.ng, ns: v.ns };
        self.scene()
            .bsdf(v.material, normals, v.uv, v.wo, TransportMode::Importance)
    }

    /// The probability that Russian roulette let a sub-path go on from a vertex.
    fn roulette_probability(&self, bsdf: &Bsdf, path_length: u32) -> f32 {
        if path_length >= self.ctx.options.roulette {
            bsdf.continuation_probability()
        } else {
            1.0
        }
    }

    /// The explicit connection of a UPG merge between two vertices (BSDF, position, geometric
    /// normal): both BSDFs, the geometry term and the visibility (000 eq. 2.67).
    fn link(
        &self,
        (from, from_position, from_ng): (&Bsdf, Vec3, Vec3),
        (to, to_position, to_ng): (&Bsdf, Vec3, Vec3),
        stats: &mut IterationStats,
    ) -> Option<Connection> {
        Connection::new(from, from_position, to, to_position).filter(|_| {
            stats.rays += 1;
            !self.scene().occluded(&Ray::spawn_between(
                from_position,
                from_ng,
                to_position,
                to_ng,
            ))
        })
    }

    /// Estimates 1/p_acc for the merges of one gather, together so that packets can take lanes
    /// from all of them, and returns the sum of their contributions. A capped estimate drops its
    /// merge and is counted as capped; an unreachable target drops its merge too.
    fn estimate_merges(&self, tentative: &mut Tentative, stats: &mut IterationStats) -> Rgb {
        // `upg` gathers light vertices, which lie on non-delta surfaces only; `upg-camera`
        // gathers at wherever the eye sub-path lands.
        match self.modes.merge {
            Merge::UpgLight => {
                tentative.estimate(&self.estimator, &StoredVerticesOnly(self.scene()), stats)
            }
            _ => tentative.estimate(&self.estimator, self.scene(), stats),
        }
    }

    /// Traces the eye sub-path of one pixel and returns its estimate.
    #[allow(clippy::too_many_arguments)]
    fn trace_eye_path(
        &self,
        w: &VcmWeights,
        iteration: u64,
        pixel: usize,
        light_path: &[LightVertex],
        grid: Option<&HashGrid>,
        vertices: &[LightVertex],
        stats: &mut IterationStats,
    ) -> Rgb {
        let camera = &self.ctx.camera;
        let seed = self.ctx.options.seed;
        let mut rng = Rng::for_sample(seed, iteration, pixel as u64, Stream::Eye);
        let mut tentative = Tentative::new(seed, iteration, pixel);
        let width = camera.width as usize;
        let [jx, jy] = rng.next_2d();
        let ray = camera.generate_ray((pixel % width) as f32 + jx, (pixel / width) as f32 + jy);
        let camera_pdf_w = camera.pdf_w(ray.dir);
        // 001 eq. (31)-(33) for the eye: p_0^connect = p_0^trace, d_vc = d_vm = 0.
        let mut state = SubPath {
            ray,
            throughput: Rgb::WHITE,
            path_length: 1,
            finite_light: true,
            specular: true,
            prev_surface: false,
            mis: w.camera_origin(camera_pdf_w),
        };
        let max_length = self.ctx.max_path_length();
        let mut color = Rgb::BLACK;
        let mut prev: Option<EyeVertex> = None;
        loop {
            stats.rays += 1;
            let Some(hit) = self.scene().intersect(&state.ray) else {
                color += state.throughput * self.emission(w, &state, None);
                break;
            };
            let dir = state.ray.dir.normalize();
            self.arrive(w, &mut state, &hit, false);
            // `upg-camera` merges wherever the sub-path lands: what is merged is the light
            // vertex, reached from the previous eye vertex.
            if let (Some(grid), Some(prev)) = (grid, prev.as_ref()) {
                color += self.merge_upg_camera(
                    w,
                    prev,
                    hit.position,
                    grid,
                    vertices,
                    &mut tentative,
                    stats,
                ) * (1.0 / w.light_paths);
            }
            color += state.throughput * self.emission(w, &state, Some(&hit));
            // Light tracing renders everything else from the light side.
            if self.modes.light_trace || state.path_length >= max_length {
                break;
            }
            let Some(bsdf) = self.scene().bsdf_at(&hit, -dir, TransportMode::Radiance) else {
                break;
            };
            w.drop_pending(&mut state.mis, !bsdf.is_delta());
            if !bsdf.is_delta() {
                if self.modes.vc {
                    color += state.throughput
                        * self.light_sampling(w, &state, &hit, &bsdf, &mut rng, stats);
                    for lv in light_path {
                        if lv.path_length + state.path_length + 1 > max_length {
                            break;
                        }
                        color += state.throughput * self.connect(w, &state, &hit, &bsdf, lv, stats);
                    }
                }
                match (grid, self.modes.merge) {
                    (Some(grid), Merge::Density) => {
                        let merged = self.merge(w, &state, &bsdf, &hit, grid, vertices);
                        color += state.throughput * merged * w.vm_normalization;
                        if self.modes.ppm {
                            break;
                        }
                    }
                    (Some(grid), Merge::UpgLight) => {
                        let merged = self.merge_upg_light(
                            w,
                            &state,
                            &bsdf,
                            &hit,
                            grid,
                            vertices,
                            &mut tentative,
                            stats,
                        );
                        color += state.throughput * merged * (1.0 / w.light_paths);
                    }
                    _ => {}
                }
            }
            let before =
                (!bsdf.is_delta() && self.modes.merge == Merge::UpgCamera).then(|| EyeVertex {
                    hit,
                    bsdf: bsdf.clone(),
                    throughput: state.throughput,
                    mis: state.mis,
                    prev_surface: state.prev_surface,
                    path_length: state.path_length,
                });
            if self
                .scatter(w, &mut state, &hit, &bsdf, &mut rng, false)
                .is_none()
            {
                break;
            }
            prev = before;
        }
        color
    }
}

/// The MIS quantities of the sub-path that ends at the first vertex of `c` (`at_from`),
/// carried across it to the second (001 eqs. 34-36).
fn carry(w: &VcmWeights, c: &Connection, at_from: VcmVertex, merge_at_from: VmHere) -> VcmVertex {
    let mut v = at_from;
    w.scatter(
        &mut v,
        c.cos_from,
        c.from_eval.pdf_w,
        c.from_eval.rev_pdf_w,
        false,
        merge_at_from,
    );
    w.arrive(&mut v, c.distance, c.cos_to, true);
    v
}

/// The UPG merges of one eye sub-path awaiting their 1/p_acc: each merge's bound, its own
/// random stream (so an estimate does not depend on how many numbers the packets before it
/// drew) and its contribution without the 1/p_acc factor. Reused from gather to gather.
struct Tentative<'s> {
    seed: u64,
    iteration: u64,
    base: u64,
    merges: u64,
    bounds: Vec<AngularBound<'s>>,
    rngs: Vec<Rng>,
    values: Vec<Rgb>,
}

impl<'s> Tentative<'s> {
    fn new(seed: u64, iteration: u64, pixel: usize) -> Self {
        Tentative {
            seed,
            iteration,
            base: (pixel as u64) << 24,
            merges: 0,
            bounds: Vec::new(),
            rngs: Vec::new(),
            values: Vec::new(),
        }
    }

    fn push(&mut self, bound: AngularBound<'s>, value: Rgb) {
        self.merges += 1;
        self.rngs.push(Rng::for_sample(
            self.seed,
            self.iteration,
            self.base + self.merges,
            Stream::Tentative,
        ));
        self.bounds.push(bound);
        self.values.push(value);
    }

    /// Estimates every pending merge, empties the list and returns the merges' sum.
    fn estimate<T: TentativeTracer + ?Sized>(
        &mut self,
        estimator: &Estimator,
        tracer: &T,
        stats: &mut IterationStats,
    ) -> Rgb {
        let values = &mut self.values;
        estimator.estimate_all(tracer, &self.bounds, &mut self.rngs, |i, estimate| {
            stats.upg.merges += 1;
            stats.upg.trials += estimate.trials as u64;
            stats.upg.tentative_rays += estimate.rays as u64;
            stats.rays += estimate.rays as u64;
            values[i] = match estimate.outcome {
                Outcome::Estimate(inv_p_acc) => values[i] * inv_p_acc,
                Outcome::Capped => {
                    stats.upg.capped += 1;
                    Rgb::BLACK
                }
                Outcome::Unreachable => Rgb::BLACK,
            };
        });
        // Summed in gathering order: packets finish merges in another order than single rays,
        // and the image must not depend on it.
        let sum = values.iter().fold(Rgb::BLACK, |sum, &v| sum + v);
        self.bounds.clear();
        self.rngs.clear();
        self.values.clear();
        sum
    }
}

impl Integrator for VertexCm<'_> {
    fn render_iteration(&mut self, iteration: u64, frame: &mut [Rgb]) -> IterationStats {
        let w = self.weights(iteration);
        let paths = frame.len();
        // Light pass: fixed chunks of paths, concatenated in order.
        let chunks: Vec<LightChunk> = (0..paths)
            .into_par_iter()
            .step_by(LIGHT_CHUNK)
            .map(|start| {
                let mut chunk = LightChunk::default();
                for index in start..(start + LIGHT_CHUNK).min(paths) {
                    self.trace_light_path(
                        &w,
                        iteration,
                        index,
                        &mut chunk.vertices,
                        &mut chunk.splats,
                        &mut chunk.stats,
                    );
                    chunk.ends.push(chunk.vertices.len() as u32);
                }
                chunk
            })
            .collect();
        let mut vertices = Vec::new();
        let mut path_ends = Vec::with_capacity(paths + 1);
        path_ends.push(0usize);
        let mut stats = IterationStats::default();
        for LightChunk {
            vertices: chunk_vertices,
            ends,
            splats,
            stats: chunk_stats,
        } in chunks
        {
            let base = vertices.len();
            path_ends.extend(ends.iter().map(|&e| base + e as usize));
            vertices.extend(chunk_vertices);
            for (pixel, value) in splats {
                add_sample(&mut frame[pixel], value, &mut stats.dropped_samples);
            }
            stats.rays += chunk_stats.rays;
            stats.dropped_samples += chunk_stats.dropped_samples;
        }
        self.stored_vertices = vertices.len();
        let grid = self.modes.vm.then(|| {
            let positions: Vec<Vec3> = vertices.iter().map(|v| v.position).collect();
            HashGrid::build(&positions, w.radius)
        });
        // Eye pass: one sub-path per pixel, each connecting to its own light sub-path.
        let eye_stats = frame
            .par_iter_mut()
            .enumerate()
            .map(|(pixel, value)| {
                let mut stats = IterationStats::default();
                let light_path = &vertices[path_ends[pixel]..path_ends[pixel + 1]];
                let color = self.trace_eye_path(
                    &w,
                    iteration,
                    pixel,
                    light_path,
                    grid.as_ref(),
                    &vertices,
                    &mut stats,
                );
                add_sample(value, color, &mut stats.dropped_samples);
                stats
            })
            .reduce(IterationStats::default, |a, b| a + b);
        let stats = stats + eye_stats;
        self.upg = self.upg + stats.upg;
        stats
    }

    fn statistics(&self) -> Vec<(String, String)> {
        let paths = self.ctx.camera.pixel_count().max(1);
        let mut stats = vec![
            (
                "light_vertices_per_path".into(),
                format!("{:.3}", self.stored_vertices as f64 / paths as f64),
            ),
            (
                "light_vertex_bytes".into(),
                std::mem::size_of::<LightVertex>().to_string(),
            ),
        ];
        if self.modes.vm {
            stats.push(("base_radius".into(), self.base_radius.to_string()));
            stats.push(("alpha".into(), self.alpha.to_string()));
        }
        if self.modes.merge != Merge::Density {
            stats.extend(self.upg.statistics());
        }
        stats
    }
}
