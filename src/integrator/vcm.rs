//! Vertex connection and merging (001), and the techniques that are special cases of it: light
//! tracing (`lt`), bidirectional photon mapping (`bpm`, VM only: 001 sec. 5.6) and progressive
//! photon mapping (`ppm`, one merge at the first non-specular eye vertex). With `--no-vm` it is
//! BPT (001 sec. 5.5, eta_VCM = 0), which `bpt.rs` implements separately as its cross-check.
//! Unbiased photon gathering (`upg`, `upg-camera`, `upg-hybrid`) is the same family with another
//! merge, made in `upg/merge.rs`.
//!
//! The structure follows SmallVCM's VertexCM, read top to bottom:
//! 1. the light pass ([`VertexCm::trace_light_path`]): one light sub-path per pixel (n_light =
//!    n_VM = pixel count, 001 sec. 2.3; `light_paths` sets another count) from
//!    [`VertexCm::light_sample`]; its non-specular
//!    vertices are stored with the MIS quantities d^VCM, d^VC, d^VM and connected to the camera;
//! 2. the hash grid over the stored vertices;
//! 3. the eye pass ([`VertexCm::trace_eye_path`]): one eye sub-path per pixel that at every
//!    non-specular vertex takes emission, a light sample, connections to its pixel's light
//!    sub-path and merges with the light vertices around it.
//!
//! With `memory = one-stage` the three run per pixel instead, merging with the previous
//! iteration's light vertices (001 sec. 6.2): `onestage.rs`, which reuses the passes here.
//!
//! The weights themselves are in `mis.rs` (001 eqs. 31-47), in SmallVCM's "power already
//! applied" form, mis(x) = x^beta. Russian roulette is left out of the pdfs the weights use:
//! weights only need to sum to one over the techniques, and every technique evaluates the same
//! pdfs.

use super::camera_rays::CameraRays;
use super::connection::{Connection, LightSample};
use super::density::DensityMap;
use super::mis::{
    ConnectionPdfs, Gather, Neighbour, Power, Side, VcmVertex, VcmWeights, VmHere, NO_DENSITY,
};
use super::scatter::continue_sub_path;
use super::subpath::{self, EyeVertex, MergeVertex, MisStep, PendingMis};
use super::upg::acceptance::{Estimator, PacketWidth};
use super::upg::blend::{Blend, Ramp};
use super::upg::hybrid::{self, Rule};
use super::upg::merge::{Gathered, Reweigh, Tentative, UpgMerges};
use super::upg::{Deferred, UpgCounters};
use super::{Counters, Integrator, IterationStats, RenderContext};
use crate::accel::{Ray, PACKET};
use crate::bsdf::{Bsdf, TransportMode};
use crate::color::Rgb;
use crate::film::add_sample;
use crate::hashgrid::{HashGrid, LocatedQuery, Within};
use crate::light::Aim;
use crate::options::{MemoryLayout, RenderOptions, Technique};
use crate::sampling::Sampler;
use crate::scene::{Scene, SurfaceHit};
use glam::Vec3;
use onestage::{MergeMis, MergeRecords, MergeVertices, Narrow, NarrowVertices, OneStage};
use rayon::prelude::*;
use std::ops::ControlFlow;
use std::time::Duration;

#[path = "onestage.rs"]
mod onestage;

/// Light paths traced by one parallel task. Fixed, so results do not depend on threads.
const LIGHT_CHUNK: usize = 256;
/// Most pixels one parallel task of the eye pass traces.
const EYE_TASK: usize = 256;

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
    gather: Gather,
    /// `upg-hybrid`'s rule of which surfaces are glossy.
    rule: Option<Rule>,
}

impl Modes {
    fn for_options(o: &RenderOptions) -> Self {
        let (vc, vm) = (o.connects(), o.merges());
        let ppm = o.technique == Technique::Ppm;
        let light_trace = o.technique == Technique::Lt;
        let gather = match o.technique {
            Technique::Upg => Gather::UpgLight,
            Technique::UpgCamera => Gather::UpgCamera,
            Technique::UpgHybrid => Gather::Hybrid,
            Technique::VcmUpg => Gather::Blend,
            _ => Gather::Density,
        };
        Modes {
            vc,
            vm,
            ppm,
            light_trace,
            gather,
            rule: (gather == Gather::Hybrid).then_some(Rule {
                threshold: o.hybrid_roughness,
            }),
        }
    }

    /// Where the light sub-paths of infinite lights start: where no eye vertex connects to
    /// them, every vertex that reaches the scene is worth its cost, and the box's silhouette
    /// wastes fewer sub-paths than the bounding sphere's disc (`light/bounds.rs`).
    fn aim(&self) -> Aim {
        if self.vc {
            Aim::Disc
        } else {
            Aim::Silhouette
        }
    }

    /// Whether merging is a technique at a vertex a sub-path scatters from: its neighbour back
    /// along the sub-path is known, the one on the other side is not traced yet.
    fn merge_leaving(&self, light_side: bool, state: &SubPath) -> VmHere {
        if light_side {
            let known = Neighbour::towards_light(state.path_length, state.prev_surface)
                .glossy_if(state.prev_glossy);
            self.gather.merge_at(known, Neighbour::Unknown)
        } else {
            let known = Neighbour::surface_if(state.prev_surface);
            self.gather.merge_at(Neighbour::Unknown, known)
        }
    }

    /// Whether a merge deferred at the eye sub-path's previous vertex is a technique, now that
    /// the vertex reached, that merge's neighbour towards the light, is known to be a non-delta
    /// surface vertex (`surface`) or a delta one. (Light sub-paths keep theirs at non-delta
    /// surface vertices, [`MisStep::Arrive`]: only `upg-camera` defers there, and its rule is
    /// that.)
    fn keeps_deferred(&self, surface: bool) -> bool {
        let reached = Neighbour::surface_if(surface);
        self.gather.merge_at(reached, Neighbour::Surface) == VmHere::Valid
    }
}

/// The median pixel footprint (distance times the pixel's angular size) over a grid of primary
/// rays, where a quarter of them or more hit the scene: with `--radius-pixels`, the radius the
/// hash grid's cells are sized for (queries of other radii visit the cells theirs need).
fn median_footprint(scene: &Scene, camera: &crate::scene::Camera) -> Option<f32> {
    const GRID: u32 = 16;
    let mut footprints: Vec<f32> = (0..GRID * GRID)
        .filter_map(|i| {
            let x = ((i % GRID) as f32 + 0.5) * camera.width as f32 / GRID as f32;
            let y = ((i / GRID) as f32 + 0.5) * camera.height as f32 / GRID as f32;
            let ray = camera.generate_ray(x, y);
            let hit = scene.intersect(&ray)?;
            let footprint = hit.hit.t * ray.dir.length() / camera.pdf_w(ray.dir).sqrt();
            (footprint.is_finite() && footprint > 0.0).then_some(footprint)
        })
        .collect();
    if footprints.len() < (GRID * GRID / 4) as usize {
        return None;
    }
    let middle = footprints.len() / 2;
    let (_, &mut median, _) = footprints.select_nth_unstable_by(middle, f32::total_cmp);
    Some(median)
}

/// The sub-path state of this family: its pending MIS terms are UPG's deferred merges (none
/// for the density-estimate merges).
type SubPath = subpath::SubPath<Deferred>;
/// The light vertex this family stores (its size bounds the memory a render needs).
pub type LightVertex = subpath::LightVertex<Deferred>;
/// The bytes of a light vertex `memory = one-stage` stores for the next iteration's merges.
pub const ONE_STAGE_VERTEX_BYTES: usize = onestage::STORED_BYTES;
type LightChunk = subpath::LightChunk<Deferred>;
type LightPaths = subpath::LightPaths<Deferred>;

/// Storage kept from one iteration to the next, so the steady state allocates nothing.
#[derive(Default)]
struct Buffers {
    chunks: Vec<LightChunk>,
    light: LightPaths,
    /// The stored light vertices' positions: the grid's and the density map's input.
    positions: Vec<Vec3>,
    /// The light vertices as a density-estimate merge reads them, in the grid's order.
    merge_vertices: Vec<MergeVertex>,
    /// The same where the merges read fewer MIS quantities ([`Narrow`]).
    narrow_vertices: Vec<Narrow>,
    grid: HashGrid,
    /// The bytes of the light vertices' buffers after the light pass (the grid's own left
    /// out), the most over the iterations so far.
    peak_bytes: usize,
    /// The light vertices of `memory = one-stage`, which uses none of the above.
    one_stage: OneStage,
}

/// The BSDFs of the light vertices an eye sub-path connects to, each built at its first
/// connection and kept for the sub-path's later vertices, as `bpt` builds each once: rebuilding
/// them at every eye vertex (material, albedo, frame) was most of what connecting cost beyond
/// `bpt`. Its storage is reused from pixel to pixel.
type LightBsdfs<'s> = Vec<Option<Bsdf<'s>>>;

/// What the eye sub-paths of one iteration share.
struct EyePass<'i> {
    w: VcmWeights,
    light: &'i LightPaths,
    grid: Option<&'i HashGrid>,
    merge_vertices: MergeVertices<'i>,
}

pub struct VertexCm<'a> {
    ctx: RenderContext<'a>,
    modes: Modes,
    /// The first iteration's radius: the global one, or with `--radius-pixels` the median
    /// of the pixels' (the grid's cell size and the statistics' figure).
    base_radius: f32,
    /// `--radius-pixels`: each eye sub-path's radius from its pixel footprint (001 sec. 6.1).
    radius_pixels: Option<f32>,
    alpha: f32,
    /// The merges of `upg` and `upg-camera`.
    upg_merges: Option<UpgMerges<'a>>,
    /// `vcm-upg`'s merges: density estimates or UPG's, chosen per merge.
    blend: Option<Blend<'a>>,
    /// 002's density map, for `--density-mis`.
    density: Option<DensityMap>,
    /// Light vertices stored in the last iteration, for the statistics.
    stored_vertices: usize,
    /// UPG's counters over all iterations so far.
    upg: UpgCounters,
    buffers: Buffers,
}

impl<'a> VertexCm<'a> {
    pub fn new(ctx: RenderContext<'a>) -> Self {
        let o = ctx.options;
        let modes = Modes::for_options(o);
        let base_radius = match o.radius_pixels {
            Some(k) => {
                k * median_footprint(ctx.scene, &ctx.camera)
                    .unwrap_or_else(|| ctx.scene.default_radius(&ctx.camera) / k)
            }
            None => o
                .radius
                .unwrap_or_else(|| ctx.scene.default_radius(&ctx.camera)),
        };
        let estimator = Estimator {
            packet: if o.upg_packet == 8 {
                PacketWidth::Eight
            } else {
                PacketWidth::One
            },
            max_trials: o.upg_max_trials,
        };
        let bounds = [o.min_path_length, ctx.max_path_length()];
        let upg_merges = modes.gather.clamps().then(|| {
            let merges = UpgMerges::new(ctx.scene, modes.gather, estimator, bounds, o.roulette);
            match modes.rule {
                Some(rule) => merges.with_rule(rule),
                None => merges,
            }
        });
        let blend = (modes.gather == Gather::Blend).then(|| {
            let ramp = Ramp {
                near: o.blend_near,
                far: o.blend_far,
            };
            Blend::new(ctx.scene, estimator, bounds, o.roulette, ramp)
        });
        let density = o
            .density_mis
            .map(|_| DensityMap::new(base_radius, o.density_map_iterations));
        VertexCm {
            modes,
            base_radius,
            radius_pixels: o.radius_pixels,
            alpha: o.alpha(),
            upg_merges,
            blend,
            density,
            ctx,
            stored_vertices: 0,
            upg: UpgCounters::default(),
            buffers: Buffers::default(),
        }
    }

    /// The constants of iteration `iteration` (0-based): 000 eq. 2.85's radius
    /// r_i = r_1 sqrt(i^(alpha - 1)) for i = iteration + 1.
    /// With per-pixel radii, the light sub-paths' weights leave eta_VCM out
    /// ([`VcmWeights::radius_free`]) and each eye sub-path takes its own
    /// ([`Self::eye_weights`]).
    fn weights(&self, iteration: u64) -> VcmWeights {
        let radius = self.shrunk(iteration, self.base_radius);
        let (power, paths) = (Power(self.ctx.options.beta), self.light_paths() as f32);
        let w = if !self.modes.gather.clamps() {
            let w = VcmWeights::new(power, radius, paths, self.modes.vc, self.modes.vm);
            if self.resolves() {
                return w.radius_free();
            }
            w
        } else if self.modes.vc {
            VcmWeights::clamped(power, radius, paths)
        } else {
            VcmWeights::clamped_merges_only(power, radius, paths)
        };
        // UPG's clamped merges take 002's factors as VCM's do (VcmWeights::with_density).
        match (self.ctx.options.density_mis, &self.density) {
            (Some(mode), Some(map)) if map.iterations() > 0 => w.with_density(mode),
            _ => w,
        }
    }

    /// 000 eq. 2.85's r_i = r_1 sqrt(i^(alpha - 1)) for i = iteration + 1.
    fn shrunk(&self, iteration: u64, first: f32) -> f32 {
        let i = (iteration + 1) as f32;
        (first * i.powf(0.5 * (self.alpha - 1.0))).max(1e-7)
    }

    /// The weights of a full path whose first non-specular eye vertex lies `distance` (along
    /// the sub-path, specular vertices unfolded) from the camera, the primary ray leaving in
    /// `dir` (001 sec. 6.1): its radius is `--radius-pixels` pixel footprints there, a
    /// pixel's angular size being sqrt(1 / camera pdf_w), shrunk as the iteration's weights
    /// `w` shrink the base radius. `None` with one global radius.
    ///
    /// Every technique of a full path takes its radius from here, with the same arguments,
    /// so their weights sum to one: eye sub-paths at their first non-specular vertex
    /// ([`Self::trace_eye_path`]), the light tracer's splat at the light vertex it sees
    /// ([`Self::connect_to_camera`]). Techniques whose eye sub-path ends before that vertex
    /// would need none: eye sub-paths hold no merge term before it. What an eye sub-path
    /// joins takes its weights too: the light sub-paths' quantities (resolved, or re-run:
    /// [`Self::replays`]), the density map's lookups ([`Self::inv_k`]), and UPG's grid query
    /// and tentative rays (`upg/merge.rs`, at `w.radius`). UPG's radius does not shrink.
    fn eye_weights(&self, w: &VcmWeights, distance: f32, dir: Vec3) -> Option<VcmWeights> {
        let k = self.radius_pixels?;
        let pixel = (1.0 / self.ctx.camera.pdf_w(dir)).sqrt();
        let shrink = w.radius / self.base_radius;
        Some(w.at_radius((k * distance * pixel * shrink).max(1e-7)))
    }

    /// With per-pixel radii, whether light sub-paths carry VCM's c^VC and c^VM, which a use
    /// resolves at the eye sub-path's radius ([`Self::light_mis`]). Where UPG's clamp or 002's
    /// density factors make the sums non-linear in eta_VCM, light sub-paths keep their MIS
    /// steps instead and every use re-runs them at that radius ([`Self::replays`]).
    fn resolves(&self) -> bool {
        self.radius_pixels.is_some() && !self.replays()
    }

    /// With per-pixel radii under UPG's clamp or 002's density factors: light sub-paths keep
    /// their MIS steps ([`MisStep`]), and each connection, merge and camera splat re-runs them
    /// with the weights of the eye sub-path that joins them (001 sec. 6.1). Costs a walk along
    /// the light sub-path per use and the steps' memory, paid only here.
    fn replays(&self) -> bool {
        self.radius_pixels.is_some()
            && (self.modes.gather != Gather::Density || self.density.is_some())
    }

    /// A light vertex's MIS quantities as weights `w` of an eye sub-path take them: with
    /// per-pixel radii and VCM's weights they carry c^VC and c^VM, resolved at the eye
    /// sub-path's radius (001 eqs. (62)-(63)).
    fn light_mis(&self, w: &VcmWeights, v: VcmVertex) -> VcmVertex {
        if self.resolves() {
            w.resolve(&v)
        } else {
            v
        }
    }

    /// 1 / k at a position for merges of weights `w` (002 eq. (6)): the density map's lookup
    /// at `w`'s radius, so the path's radius; `None` without the map.
    fn inv_k(&self, w: &VcmWeights) -> impl Fn(Vec3) -> Option<f32> + '_ {
        let (radius, paths) = (w.radius, w.light_paths);
        move |x| {
            self.density
                .as_ref()
                .and_then(|map| map.inv_expected_count(x, radius, paths))
        }
    }

    /// The density factor rho = mis(1 / k) of a merge at `x` and its 1 / k (002 eq. (6)),
    /// with `x` joining the sub-path's VCM* mean; [`NO_DENSITY`] without the density map.
    fn density_at(&self, w: &VcmWeights, x: Vec3, state: &mut SubPath) -> (f32, f32) {
        w.density_at(&mut state.mis, self.inv_k(w)(x))
    }

    /// The light sub-path state `state` with its MIS quantities re-run with weights `w` from
    /// `steps`, the sub-path's so far, whose surface vertices are `vertices`.
    fn replayed(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        (steps, vertices): (&[MisStep], &[LightVertex]),
    ) -> SubPath {
        let mut replayed = *state;
        let inv_k = self.inv_k(w);
        let at = |i: usize| inv_k(vertices.get(i)?.position);
        subpath::replay(w, steps, at, |mis, pending, density| {
            replayed.mis = *mis;
            replayed.pending = *pending;
            replayed.density = density;
            ControlFlow::Continue(())
        });
        replayed
    }

    fn scene(&self) -> &'a Scene {
        self.ctx.scene
    }

    /// Light sub-paths per iteration: n_VM, and the light tracer's n_light (001 sec. 2.3).
    fn light_paths(&self) -> usize {
        match self.ctx.options.light_paths {
            Some(n) => n as usize,
            None => self.ctx.camera.pixel_count(),
        }
    }

    /// Whether a full path of `segments` is short of `--min-path-length` and left out.
    fn too_short(&self, segments: u32) -> bool {
        segments < self.ctx.options.min_path_length
    }

    /// Starts a light sub-path (SmallVCM's GenerateLightSample; 001 eqs. 31-33), with the
    /// step that started its MIS quantities.
    fn light_sample(&self, w: &VcmWeights, sampler: &mut Sampler) -> Option<(SubPath, MisStep)> {
        let lights = &self.scene().lights;
        let (index, pick) = lights.pick(sampler.next_f32())?;
        let light = lights.get(index);
        let [u_pos, u_dir] = sampler.next_4d();
        let e = light.emit(u_pos, u_dir, self.modes.aim())?;
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
        let origin_point = if light.is_finite() && !light.is_delta() {
            Ray::spawn(e.position, e.normal, e.dir).origin
        } else {
            e.position
        };
        let origin = MisStep::Origin {
            direct_pdf_a,
            emission_pdf_w,
            cos_at_light,
            delta: light.is_delta(),
        };
        let mut state = SubPath {
            ray: Ray::new(origin_point, e.dir),
            throughput: e.energy / emission_pdf_w,
            path_length: 1,
            finite_light: light.is_finite(),
            specular: false,
            prev_surface: false,
            prev_glossy: false,
            mis: VcmVertex::default(),
            pending: Deferred::NONE,
            density: NO_DENSITY,
        };
        origin.apply(
            w,
            &mut state.mis,
            &mut state.pending,
            &mut state.density,
            || None,
        );
        Some((state, origin))
    }

    /// The segment that reached a newly found vertex: its length, |cos| at the vertex, and
    /// whether the distance enters the pdfs (001 sec. 5.1).
    fn arrival(&self, state: &SubPath, hit: &SurfaceHit, light_side: bool) -> (f32, f32, bool) {
        let distance = hit.hit.t * state.ray.dir.length();
        let with_distance = !light_side || state.path_length > 1 || state.finite_light;
        let cos = hit.ng.dot(-state.ray.dir.normalize()).abs();
        (distance, cos, with_distance)
    }

    /// Distance and cosine updates at a newly found vertex (001 eqs. 34-36, the geometry part).
    fn arrive(&self, w: &VcmWeights, state: &mut SubPath, hit: &SurfaceHit, light_side: bool) {
        let (distance, cos, with_distance) = self.arrival(state, hit, light_side);
        let arrival = w.arrive(&mut state.mis, distance, cos, with_distance);
        state.pending.arrive(arrival);
    }

    /// Continues a sub-path by sampling the BSDF (SmallVCM's SampleScattering; 001 eqs. 34-36,
    /// the sampling part), returning the MIS step it applied. `None` ends the path.
    fn scatter(
        &self,
        w: &VcmWeights,
        state: &mut SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        sampler: &mut Sampler,
        light_side: bool,
    ) -> Option<MisStep> {
        let roulette = self.ctx.options.roulette;
        let (s, q) = continue_sub_path(bsdf, sampler, state.path_length, roulette)?;
        state.throughput /= q;
        let cos_out = bsdf.cos_theta(s.wi);
        let here = self.modes.merge_leaving(light_side, state);
        // A merge deferred at the previous vertex settles as the vertex is left, which the
        // step does for non-delta lobes. `vcm-upg`'s stays a technique whatever lobe the
        // vertex samples, a delta one too, and its eta needs no pdf.
        if s.delta && self.modes.gather == Gather::Blend {
            state.mis = state.mis_at(w, s.rev_pdf_w);
        }
        // `upg-hybrid`'s eye sub-path: a vertex left through a delta lobe sends no tentative
        // rays, so the deferred merge before it is the camera side's; a merge here may be too,
        // with the pdf of this vertex known now, where the vertex before is a surface vertex.
        let hybrid_eye = !light_side && self.modes.gather == Gather::Hybrid;
        let own = if state.prev_surface {
            state.mis.d_vcm
        } else {
            0.0
        };
        if s.delta && hybrid_eye {
            state.mis = state.pending.settle_own(w, state.mis);
        }
        let step = MisStep::Leave {
            cos_out,
            pdf_w: s.pdf_w,
            rev_pdf_w: s.rev_pdf_w,
            delta: s.delta,
            here,
        };
        step.apply(
            w,
            &mut state.mis,
            &mut state.pending,
            &mut state.density,
            || None,
        );
        if hybrid_eye && !s.delta {
            state.pending = state.pending.with_own(own);
        }
        state.prev_surface = !s.delta;
        state.prev_glossy = !s.delta && hybrid::glossy(self.modes.rule, bsdf);
        if !s.delta {
            state.specular = false;
        }
        state.throughput *= s.f * (cos_out / s.pdf_w);
        if state.throughput.is_black() {
            return None;
        }
        state.ray = Ray::spawn(hit.position, hit.ng, s.wi);
        state.path_length += 1;
        Some(step)
    }

    /// Traces the light sub-path `index`; stores its vertices and returns its camera splats.
    fn trace_light_path(
        &self,
        w: &VcmWeights,
        iteration: u64,
        index: usize,
        chunk: &mut LightChunk,
    ) {
        let o = self.ctx.options;
        let mut sampler = Sampler::light(
            o.sampler,
            o.seed,
            iteration,
            index as u64,
            self.light_paths() as u64,
        );
        let Some((mut state, origin)) = self.light_sample(w, &mut sampler) else {
            return;
        };
        // Where the path's MIS steps are kept (per-pixel radii re-run them), this path's
        // begin here.
        let replays = self.replays();
        let first = [chunk.steps.len(), chunk.vertices.len()];
        if replays {
            chunk.steps.push(origin);
        }
        let max_length = self.ctx.max_path_length();
        loop {
            sampler.start_vertex(state.path_length);
            chunk.stats.rays += 1;
            let Some(hit) = self.scene().intersect(&state.ray) else {
                break;
            };
            let dir = state.ray.dir.normalize();
            let (distance, cos, with_distance) = self.arrival(&state, &hit, true);
            let Some(bsdf) = self.scene().bsdf_at(&hit, -dir, TransportMode::Importance) else {
                break;
            };
            let arrive = MisStep::Arrive {
                distance,
                cos,
                with_distance,
                surface: !bsdf.is_delta(),
            };
            arrive.apply(
                w,
                &mut state.mis,
                &mut state.pending,
                &mut state.density,
                || self.inv_k(w)(hit.position),
            );
            if replays {
                chunk.steps.push(arrive);
            }
            if !bsdf.is_delta() {
                if self.modes.vc || self.modes.vm {
                    chunk.vertices.push(LightVertex {
                        position: hit.position,
                        ng: hit.ng,
                        ns: hit.ns,
                        uv: hit.uv,
                        azimuth: hit.azimuth(),
                        wo: -dir,
                        throughput: state.throughput,
                        material: hit.material,
                        path_length: state.path_length,
                        mis: state.mis,
                        pending: state.pending,
                        rho: state.density.0,
                        after_surface: state.prev_surface,
                        after_glossy: state.prev_glossy,
                    });
                }
                if self.modes.vc || self.modes.light_trace {
                    self.connect_to_camera(w, (&state, first), &hit, &bsdf, chunk);
                }
            }
            if state.path_length.saturating_add(2) > max_length {
                break;
            }
            match self.scatter(w, &mut state, &hit, &bsdf, &mut sampler, true) {
                Some(leave) if replays => chunk.steps.push(leave),
                Some(_) => {}
                None => break,
            }
        }
    }

    /// Traces the light sub-paths of one iteration into `chunks`: fixed chunks of paths, in
    /// order.
    fn light_pass(
        &self,
        w: &VcmWeights,
        iteration: u64,
        paths: usize,
        chunks: &mut Vec<LightChunk>,
    ) {
        chunks.resize_with(paths.div_ceil(LIGHT_CHUNK), LightChunk::default);
        // One task per chunk (rayon would otherwise run a thread's share of chunks as one task
        // nobody can take over): no thread waits long at the pass's end.
        chunks
            .par_iter_mut()
            .enumerate()
            .with_max_len(1)
            .for_each(|(c, chunk)| {
                chunk.clear();
                let start = c * LIGHT_CHUNK;
                for index in start..(start + LIGHT_CHUNK).min(paths) {
                    self.trace_light_path(w, iteration, index, chunk);
                    chunk.ends.push(chunk.vertices.len() as u32);
                    if self.replays() {
                        chunk.step_ends.push(chunk.steps.len() as u32);
                    }
                }
            });
    }

    /// A continued render starts with an empty density map: the light passes of the
    /// iterations that filled it are traced again (their vertices depend only on the seed).
    fn rebuild_density_map(&mut self, iteration: u64, paths: usize, buffers: &mut Buffers) {
        loop {
            let next = match &self.density {
                Some(map) if map.is_filling() && u64::from(map.iterations()) < iteration => {
                    u64::from(map.iterations())
                }
                _ => return,
            };
            let w = self.weights(next);
            self.light_pass(&w, next, paths, &mut buffers.chunks);
            buffers.positions.clear();
            buffers.positions.extend(
                buffers
                    .chunks
                    .iter()
                    .flat_map(|chunk| chunk.vertices.iter().map(|v| v.position)),
            );
            if let Some(map) = &mut self.density {
                map.insert(&buffers.positions);
            }
        }
    }

    /// Connects a light vertex to the camera and splats it (t = 1; 001 eqs. 46-47).
    /// `first` is where the sub-path's kept MIS steps and its stored vertices begin in
    /// `chunk`.
    fn connect_to_camera(
        &self,
        w: &VcmWeights,
        (state, [first_step, first_vertex]): (&SubPath, [usize; 2]),
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        chunk: &mut LightChunk,
    ) {
        let camera = &self.ctx.camera;
        if self.too_short(state.path_length + 1) {
            return;
        }
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
            // The path's radius: this vertex is its first non-specular one from the camera.
            let own = self.eye_weights(w, dist2.sqrt(), -dir);
            let w = own.as_ref().unwrap_or(w);
            let replayed;
            let state = if self.replays() {
                let path = (&chunk.steps[first_step..], &chunk.vertices[first_vertex..]);
                replayed = self.replayed(w, state, path);
                &replayed
            } else {
                state
            };
            // Towards the eye lies the camera, which tentative rays cannot leave from.
            let here = self.modes.gather.merge_at(
                Neighbour::towards_light(state.path_length, state.prev_surface)
                    .glossy_if(state.prev_glossy),
                Neighbour::Other,
            );
            let eta = w.eta_if(here == VmHere::Valid, state.mis.d_vcm) * state.density.0;
            w.to_camera(
                &self.light_mis(w, state.mis_at(w, eval.rev_pdf_w)),
                eta,
                camera_pdf_a,
                eval.rev_pdf_w,
            )
        };
        let contribution = state.throughput * eval.f * (weight * camera_pdf_a / w.light_paths);
        chunk.stats.rays += 1;
        if !self
            .scene()
            .occluded(&Ray::spawn_to(hit.position, hit.ng, camera.position))
        {
            chunk.splats.push(camera.pixel_index(x, y), contribution);
        }
    }

    /// Emission reached by an eye sub-path: an area light at `hit`, or the sky when `hit` is
    /// `None` (s = 0; 001 eqs. 42-43). No merge is gathered from a light point, so a deferred
    /// one is not counted.
    fn emission(&self, w: &VcmWeights, state: &SubPath, hit: Option<&SurfaceHit>) -> Rgb {
        if self.too_short(state.path_length) {
            return Rgb::BLACK;
        }
        let lights = &self.scene().lights;
        let dir = state.ray.dir.normalize();
        let Some((received, index)) =
            lights.received(dir, hit.map(|h| (h.light, h.ng)), self.modes.aim())
        else {
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
        // `upg-hybrid` gathers the merge before the light point from the camera side.
        let mis = if self.modes.gather == Gather::Hybrid {
            state.pending.settle_own(w, state.mis)
        } else {
            state.mis
        };
        received.radiance
            * w.hit_light(
                &mis,
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
        sampler: &mut Sampler,
        stats: &mut IterationStats,
    ) -> Rgb {
        if self.too_short(state.path_length + 1) {
            return Rgb::BLACK;
        }
        let Some(ls) = LightSample::draw(self.scene(), hit, bsdf, sampler, self.modes.aim()) else {
            return Rgb::BLACK;
        };
        // Towards the light lies the light point, which tentative rays cannot leave from.
        let here = self
            .modes
            .gather
            .merge_at(Neighbour::Light, Neighbour::surface_if(state.prev_surface));
        let weight = w.light_sample(
            &state.mis_at(w, ls.eval.rev_pdf_w),
            w.eta_if(here == VmHere::Valid, state.mis.d_vcm) * state.density.0,
            &ls.pdfs(),
        );
        stats.rays += 1;
        if !ls.visible(self.scene(), hit) {
            return Rgb::BLACK;
        }
        ls.contribution(weight)
    }

    /// Connects an eye vertex to a light vertex `lv` (s, t > 1; 001 eqs. 40-41), whose BSDF is
    /// `light_bsdf` (`None` where it has none).
    fn connect(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        (hit, bsdf): (&SurfaceHit, &Bsdf),
        (lv, light_bsdf): (&LightVertex, Option<&Bsdf>),
        stats: &mut IterationStats,
    ) -> Rgb {
        if self.too_short(lv.path_length + state.path_length + 1) {
            return Rgb::BLACK;
        }
        let Some(light_bsdf) = light_bsdf else {
            return Rgb::BLACK;
        };
        let Some(c) = Connection::new(bsdf, hit.position, light_bsdf, lv.position) else {
            return Rgb::BLACK;
        };
        let p: ConnectionPdfs = c.eye_to_light_pdfs();
        // Merging at either end: each end's neighbour across the connection is a non-delta
        // surface vertex. The gathering side's pdf of the merge vertex is the end's own sub-path
        // (its d^VCM) or, when the other side gathers, the other end's across the connection.
        // Each end's neighbour towards the light decides its side under `upg-hybrid`'s rule.
        let gather = self.modes.gather;
        let light_behind =
            Neighbour::towards_light(lv.path_length, lv.after_surface).glossy_if(lv.after_glossy);
        let eye_behind = Neighbour::Surface.glossy_if(hybrid::glossy(self.modes.rule, light_bsdf));
        let light_here = gather.merge_at(light_behind, Neighbour::Surface);
        let eye_here = gather.merge_at(eye_behind, Neighbour::surface_if(state.prev_surface));
        let light_eta = w.end_eta(
            gather,
            light_here == VmHere::Valid,
            (Side::Light, light_behind),
            lv.mis.d_vcm,
            p.light_pdf_a,
        ) * lv.rho;
        let eye_eta = w.end_eta(
            gather,
            eye_here == VmHere::Valid,
            (Side::Camera, eye_behind),
            state.mis.d_vcm,
            p.eye_pdf_a,
        ) * state.density.0;
        let weight = w.connect(
            &self.light_mis(w, lv.mis_at(w, p.light_rev_pdf_w)),
            light_eta,
            &state.mis_at(w, p.eye_rev_pdf_w),
            eye_eta,
            &p,
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

    /// Merges an eye vertex with the light vertices around it by density estimation (001
    /// eqs. 38-39), not yet normalised by 1 / (pi r^2 n_VM): those `query` (begun at the
    /// vertex, of the eye sub-path's radius, and located) finds. `gathered` gives the grid and,
    /// where the light vertices' MIS quantities are not kept for the eye sub-path's radius,
    /// re-runs them.
    fn merge(
        &self,
        w: &VcmWeights,
        state: &SubPath,
        bsdf: &Bsdf,
        query: &LocatedQuery,
        gathered: Gathered,
        vertices: &(impl MergeRecords + ?Sized),
    ) -> Rgb {
        let grid = gathered.grid;
        let max_length = self.ctx.max_path_length();
        let mut sum = Rgb::BLACK;
        let within_bounds = |slot: u32| {
            let segments = vertices.path_length(slot).saturating_add(state.path_length);
            segments <= max_length && !self.too_short(segments)
        };
        grid.query_kept_slot_batches_located(query, within_bounds, |batch| {
            for &slot in batch {
                let lv = vertices.vertex(slot);
                let eval = bsdf.eval(lv.wo);
                if eval.f.is_black() {
                    continue;
                }
                // PPM takes its one merge per eye path unweighted: no other technique competes.
                let weight = if self.modes.ppm {
                    1.0
                } else {
                    let light = match gathered.reweigh {
                        Some(reweigh) => reweigh(w, grid.index_of(slot as usize) as usize).mis,
                        None => self.light_mis(w, lv.mis),
                    };
                    w.merge(
                        &light,
                        &state.mis,
                        (eval.pdf_w, eval.rev_pdf_w),
                        w.vm_factor,
                        state.density,
                    )
                };
                sum += eval.f * lv.throughput * weight;
            }
        });
        sum
    }

    /// Traces the eye sub-path of `pixel` and returns its estimate. It starts with the camera
    /// ray `ray`, drawn from `sampler`, whose closest hit `first` has been found already.
    fn trace_eye_path(
        &self,
        pass: &EyePass,
        pixel: usize,
        (sampler, ray, first): (&mut Sampler, Ray, Option<SurfaceHit>),
        (tentative, light_bsdfs): (&mut Tentative<'a>, &mut LightBsdfs<'a>),
        stats: &mut IterationStats,
    ) -> Rgb {
        // With per-pixel radii, replaced by the sub-path's own at its first non-specular
        // vertex, before any technique of the sub-path weighs a merge.
        let mut w = pass.w;
        let camera = &self.ctx.camera;
        let light_path = pass.light.for_pixel(pixel);
        let reweigh = |w: &VcmWeights, index: usize| pass.light.reweighed(w, index, self.inv_k(w));
        let reweigh: Option<&Reweigh> = self.replays().then_some(&reweigh);
        let inv_k = |w: &VcmWeights, x: Vec3| self.inv_k(w)(x);
        let gathered = pass.grid.map(|grid| Gathered {
            vertices: &pass.light.vertices,
            grid,
            reweigh,
            inv_k: &inv_k,
        });
        tentative.start_pixel(pixel);
        let camera_pdf_w = camera.pdf_w(ray.dir);
        let primary = ray.dir;
        // Along the sub-path to the current vertex, while all vertices before it are specular.
        let mut travelled = 0.0;
        let mut state = SubPath {
            ray,
            throughput: Rgb::WHITE,
            path_length: 1,
            finite_light: true,
            specular: true,
            prev_surface: false,
            prev_glossy: false,
            mis: w.camera_origin(camera_pdf_w),
            pending: Deferred::NONE,
            density: NO_DENSITY,
        };
        let max_length = self.ctx.max_path_length();
        let mut color = Rgb::BLACK;
        let mut prev: Option<EyeVertex<Deferred>> = None;
        light_bsdfs.clear();
        // The camera ray's, then one per later vertex.
        stats.rays += 1;
        let mut found = first;
        loop {
            sampler.start_vertex(state.path_length);
            let Some(hit) = found.take() else {
                color += state.throughput * self.emission(&w, &state, None);
                break;
            };
            let dir = state.ray.dir.normalize();
            self.arrive(&w, &mut state, &hit, false);
            travelled += hit.hit.t * state.ray.dir.length();
            // `upg-camera` (and `upg-hybrid`'s camera side) merges wherever the sub-path lands:
            // what is merged is the light vertex, reached from the previous eye vertex.
            if let (Some(upg), Some(gathered), Some(prev)) =
                (&self.upg_merges, gathered, prev.as_ref())
            {
                color += upg.from_camera(&w, prev, hit.position, gathered, tentative, stats)
                    * (1.0 / w.light_paths);
            }
            color += state.throughput * self.emission(&w, &state, Some(&hit));
            // Light tracing renders everything else from the light side.
            if self.modes.light_trace || state.path_length >= max_length {
                break;
            }
            let Some(bsdf) = self.scene().bsdf_at(&hit, -dir, TransportMode::Radiance) else {
                break;
            };
            if self.modes.gather == Gather::Hybrid {
                let reached = Neighbour::surface_if(!bsdf.is_delta())
                    .glossy_if(hybrid::glossy(self.modes.rule, &bsdf));
                hybrid::decide(&w, &mut state.mis, &mut state.pending, reached);
            } else {
                state
                    .pending
                    .keep_if(self.modes.keeps_deferred(!bsdf.is_delta()));
            }
            state.density = NO_DENSITY;
            if !bsdf.is_delta() {
                if state.specular {
                    if let Some(own) = self.eye_weights(&pass.w, travelled, primary) {
                        w = own;
                    }
                }
                state.density = self.density_at(&w, hit.position, &mut state);
                // The merge's reads start here, so their chain of dependent cache misses
                // overlaps the shadow rays instead of being waited for in the merge: the table
                // slots are prefetched now, the points and records once the light sample's
                // shadow ray is traced.
                let merge_query = match (gathered, self.modes.gather) {
                    (Some(gathered), Gather::Density) => Some(
                        gathered
                            .grid
                            .begin_query(hit.position, Within::radius(w.radius)),
                    ),
                    _ => None,
                };
                if self.modes.vc {
                    color += state.throughput
                        * self.light_sampling(&w, &state, &hit, &bsdf, sampler, stats);
                }
                let merge_query = merge_query.zip(gathered).map(|(query, gathered)| {
                    gathered
                        .grid
                        .locate(&query, |slots| pass.merge_vertices.prefetch(slots))
                });
                if self.modes.vc {
                    let mut index = 0;
                    let connect = |lv: &LightVertex| {
                        if lv.path_length + state.path_length + 1 > max_length {
                            return ControlFlow::Break(());
                        }
                        // Visited in order along the sub-path: the ones before are built.
                        while light_bsdfs.len() <= index {
                            let stored = &light_path[light_bsdfs.len()];
                            light_bsdfs.push(stored.bsdf(self.scene()));
                        }
                        let light_bsdf = light_bsdfs[index].as_ref();
                        index += 1;
                        color += state.throughput
                            * self.connect(&w, &state, (&hit, &bsdf), (lv, light_bsdf), stats);
                        ControlFlow::Continue(())
                    };
                    if self.replays() {
                        pass.light
                            .reweighed_for_pixel(pixel, &w, self.inv_k(&w), connect);
                    } else {
                        let _ = light_path.iter().try_for_each(connect);
                    }
                }
                match (gathered, self.modes.gather, &merge_query) {
                    (Some(gathered), Gather::Density, Some(query)) => {
                        let merged = match pass.merge_vertices {
                            MergeVertices::Whole(v) => {
                                self.merge(&w, &state, &bsdf, query, gathered, v)
                            }
                            MergeVertices::Narrow(v) => {
                                self.merge(&w, &state, &bsdf, query, gathered, &v)
                            }
                            MergeVertices::Packed(v) => {
                                self.merge(&w, &state, &bsdf, query, gathered, &v)
                            }
                        };
                        color += state.throughput * merged * w.vm_normalization;
                        if self.modes.ppm {
                            break;
                        }
                    }
                    (Some(gathered), Gather::Blend, _) => {
                        if let Some(blend) = &self.blend {
                            let merged =
                                blend.merge(&w, (&state, &hit, &bsdf), gathered, tentative, stats);
                            color += state.throughput * merged;
                        }
                    }
                    (Some(gathered), Gather::UpgLight | Gather::Hybrid, _) => {
                        if let Some(upg) = &self.upg_merges {
                            let merged = upg.from_light(
                                &w,
                                (&state, &hit, &bsdf),
                                gathered,
                                tentative,
                                stats,
                            );
                            color += state.throughput * merged * (1.0 / w.light_paths);
                        }
                    }
                    _ => {}
                }
            }
            let camera_side = matches!(self.modes.gather, Gather::UpgCamera | Gather::Hybrid);
            let before = (!bsdf.is_delta() && camera_side).then(|| EyeVertex {
                hit,
                bsdf: bsdf.clone(),
                throughput: state.throughput,
                mis: state.mis,
                pending: state.pending,
                density: state.density,
                prev_surface: state.prev_surface,
                path_length: state.path_length,
            });
            if self
                .scatter(&w, &mut state, &hit, &bsdf, sampler, false)
                .is_none()
            {
                break;
            }
            prev = before;
            stats.rays += 1;
            found = self.scene().intersect(&state.ray);
        }
        color
    }
}

impl Integrator for VertexCm<'_> {
    fn render_iteration(&mut self, iteration: u64, frame: &mut [Rgb]) -> IterationStats {
        let mut buffers = std::mem::take(&mut self.buffers);
        if self.ctx.options.memory == MemoryLayout::OneStage {
            let stats = buffers.one_stage.render_iteration(self, iteration, frame);
            self.stored_vertices = buffers.one_stage.stored_vertices();
            self.buffers = buffers;
            return stats;
        }
        self.rebuild_density_map(iteration, frame.len(), &mut buffers);
        let w = self.weights(iteration);
        let paths = self.light_paths();
        self.light_pass(&w, iteration, paths, &mut buffers.chunks);
        let mut stats = IterationStats::default();
        let Buffers {
            chunks,
            light,
            positions,
            merge_vertices,
            narrow_vertices,
            grid,
            peak_bytes,
            ..
        } = &mut buffers;
        light.refill(chunks, frame, &mut stats);
        self.stored_vertices = light.vertices.len();
        positions.clear();
        if self.modes.vm {
            positions.par_extend(light.vertices.par_iter().map(|v| v.position));
            grid.rebuild(positions, w.radius);
        }
        let grid = self.modes.vm.then_some(&*grid);
        merge_vertices.clear();
        narrow_vertices.clear();
        // Per-pixel radii and the density map read every MIS quantity of a merged vertex.
        let narrow = self.radius_pixels.is_none() && self.density.is_none();
        let form = MergeMis::of(&w);
        if let (Some(grid), Gather::Density) = (grid, self.modes.gather) {
            let vertices = &light.vertices;
            if narrow {
                narrow_vertices.par_extend(
                    grid.indices()
                        .map(|i| Narrow::new(&vertices[i as usize], form)),
                );
            } else {
                merge_vertices.par_extend(
                    grid.indices()
                        .map(|i| MergeVertex::from(&vertices[i as usize])),
                );
            }
        }
        let light_vertex = std::mem::size_of::<LightVertex>();
        let bytes = chunks
            .iter()
            .map(|c| c.vertices.capacity() * light_vertex)
            .sum::<usize>()
            + light.vertices.capacity() * light_vertex
            + positions.capacity() * std::mem::size_of::<Vec3>()
            + merge_vertices.capacity() * std::mem::size_of::<MergeVertex>()
            + narrow_vertices.capacity() * std::mem::size_of::<Narrow>()
            + chunks
                .iter()
                .map(|c| c.steps.capacity() * std::mem::size_of::<MisStep>())
                .sum::<usize>()
            + light.step_bytes();
        *peak_bytes = (*peak_bytes).max(bytes);
        // Eye pass: one sub-path per pixel, each connecting to its own light sub-path.
        let pass = EyePass {
            w,
            light,
            grid,
            merge_vertices: if narrow {
                MergeVertices::Narrow(NarrowVertices {
                    records: narrow_vertices,
                    form,
                })
            } else {
                MergeVertices::Whole(merge_vertices)
            },
        };
        let (eye_stats, upg) = frame
            .par_chunks_mut(PACKET)
            .enumerate()
            .with_max_len(EYE_TASK / PACKET)
            // One list of pending UPG merges per task, its storage reused for the task's pixels.
            .map_init(
                || (Tentative::new(self.ctx.options.seed, iteration), Vec::new()),
                |(tentative, light_bsdfs), (packet, values)| {
                    let mut stats = IterationStats::default();
                    let first = packet * PACKET;
                    let mut camera = CameraRays::trace(&self.ctx, iteration, first, values.len());
                    for (lane, value) in values.iter_mut().enumerate() {
                        let hit = camera.first_hit(&self.ctx, lane);
                        let start = (&mut camera.samplers[lane], camera.rays[lane], hit);
                        let scratch = (&mut *tentative, &mut *light_bsdfs);
                        let color =
                            self.trace_eye_path(&pass, first + lane, start, scratch, &mut stats);
                        add_sample(value, color, &mut stats.dropped_samples);
                    }
                    (stats, tentative.take_counters())
                },
            )
            .reduce(Default::default, |(a, u), (b, v)| (a + b, u + v));
        let stats = stats + eye_stats;
        self.upg = self.upg + upg;
        // Filled after the eye pass, so every technique of this iteration saw the same map.
        if let Some(map) = &mut self.density {
            if map.is_filling() && u64::from(map.iterations()) == iteration {
                map.insert(positions);
            }
        }
        self.buffers = buffers;
        stats
    }

    fn statistics(&self, elapsed: Duration) -> Vec<(String, String)> {
        let paths = self.light_paths().max(1);
        let mut stats = vec![(
            "light_vertices_per_path".into(),
            format!("{:.3}", self.stored_vertices as f64 / paths as f64),
        )];
        let layout = self.ctx.options.memory;
        if self.modes.vm {
            let one_stage = &self.buffers.one_stage;
            let (vertex_bytes, peak_vertices, peak_bytes) = match layout {
                MemoryLayout::TwoStage => (
                    std::mem::size_of::<LightVertex>(),
                    self.stored_vertices,
                    self.buffers.peak_bytes,
                ),
                MemoryLayout::OneStage => (
                    onestage::STORED_BYTES,
                    one_stage.peak_vertices,
                    one_stage.peak_bytes,
                ),
            };
            stats.push(("memory_layout".into(), layout.name().into()));
            stats.push(("light_vertex_bytes".into(), vertex_bytes.to_string()));
            stats.push(("light_vertices_peak".into(), peak_vertices.to_string()));
            stats.push(("light_vertex_memory_peak".into(), peak_bytes.to_string()));
        } else {
            stats.push((
                "light_vertex_bytes".into(),
                std::mem::size_of::<LightVertex>().to_string(),
            ));
        }
        if self.modes.vm {
            let mode = match self.radius_pixels {
                Some(k) => format!("per-pixel, {k} pixel footprints"),
                None => "global".into(),
            };
            stats.push(("radius_mode".into(), mode));
            stats.push(("base_radius".into(), self.base_radius.to_string()));
            stats.push(("alpha".into(), self.alpha.to_string()));
        }
        if self.modes.gather.clamps() {
            stats.extend(self.upg.statistics());
        }
        if self.modes.gather == Gather::Hybrid {
            stats.extend(hybrid::statistics(&self.upg));
        }
        if let Some(blend) = &self.blend {
            stats.extend(blend.statistics(&self.upg));
        }
        if let Some(map) = &self.density {
            stats.extend(map.statistics());
        }
        stats.extend(self.upg.rates(elapsed));
        stats
    }

    fn counters(&self) -> Counters {
        if self.modes.gather == Gather::Density {
            Counters::default()
        } else {
            self.upg.named()
        }
    }
}
