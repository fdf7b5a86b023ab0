//! Bidirectional path tracing (000 sec. 2.3), its own code path so it can cross-check `vcm`
//! (000 ch. 3.1): per pixel and iteration one light sub-path and one eye sub-path, every
//! connection (s, t) with s light vertices and t eye vertices, the camera z_0 included:
//!
//! - s = 0: the eye sub-path reaches a light (or the sky);
//! - s = 1: light sampling at an eye vertex (a fresh light point, as in SmallVCM);
//! - t = 1: a light vertex connected to the camera and splatted into the film;
//! - s, t >= 2: a light vertex connected to an eye vertex.
//!
//! The power-heuristic weights come from the partial sums of 000 eqs. (2.50)-(2.51)
//! ([`BptVertex`]), updated in O(1) per vertex, so each weight costs O(1).
//! Paths of one segment (the camera sees a light) are only found by s = 0 and take weight 1.
//!
//! Light-tracing splats of a fixed chunk of pixels are collected and added in chunk order (on
//! all threads, a band of pixels each: `film::add_splats`), so the image does not depend on the
//! thread count. Each chunk's buffers (its splats, its light sub-path) are kept from one
//! iteration to the next: the steady state allocates nothing.

use super::camera_rays::CameraRays;
use super::connection::{Connection, LightSample};
use super::mis::{self, BptStep, BptVertex, Power};
use super::scatter::continue_sub_path;
use super::{Integrator, IterationStats, RenderContext};
use crate::accel::{Ray, PACKET};
use crate::bsdf::{Bsdf, TransportMode};
use crate::color::Rgb;
use crate::film::{add_sample, add_splats, Splats};
use crate::light::Aim;
use crate::sampling::Sampler;
use crate::scene::{Scene, SurfaceHit};
use glam::Vec3;
use rayon::prelude::*;

/// Pixels traced by one parallel task. Fixed, so results do not depend on threads.
const CHUNK: usize = 256;
/// Every eye vertex connects to every vertex of its light sub-path: the infinite lights'
/// sub-paths start on the bounding sphere's disc (`light/bounds.rs`).
const BPT_AIM: Aim = Aim::Disc;

/// What one parallel task keeps: its light-tracing splats, its counters, and the light
/// sub-path of the pixel it is tracing.
#[derive(Default)]
struct Chunk<'a> {
    splats: Splats,
    stats: IterationStats,
    light_path: Vec<LightVertex<'a>>,
}

/// A connectable (non-delta) light sub-path vertex.
#[derive(Clone, Debug)]
struct LightVertex<'a> {
    position: Vec3,
    ng: Vec3,
    /// The BSDF there, as the sub-path scattered: built once, where every eye vertex of the
    /// pixel connects to it.
    bsdf: Bsdf<'a>,
    throughput: Rgb,
    /// Index i of y_i: the light point is y_0, so s = i + 1 light vertices end here.
    index: u32,
    mis: BptVertex,
}

/// The step that leaves the current end of a sub-path, waiting for the vertex it reaches.
#[derive(Clone, Copy, Debug)]
struct Pending {
    pdf_w: f32,
    rev_pdf_w: f32,
    /// |cos| at the vertex the step leaves (for g_rev).
    cos_out: f32,
    connectable: bool,
    /// The step leaves an infinite light: no distance terms (001 sec. 5.1).
    from_infinity: bool,
}

/// A sub-path being traced.
#[derive(Clone, Copy, Debug)]
struct SubPath {
    ray: Ray,
    throughput: Rgb,
    /// Index of the vertex the ray will reach (1 for the first surface vertex).
    index: u32,
    mis: BptVertex,
    pending: Pending,
}

impl SubPath {
    /// 000 eq. (2.51) at the vertex `hit` just reached; a `None` hit is the sky, at infinity.
    fn arrive(&mut self, power: Power, hit: Option<&SurfaceHit>) {
        let p = self.pending;
        let (g, g_rev) = match hit {
            Some(h) => {
                let dir = self.ray.dir.normalize();
                let cos_in = h.ng.dot(dir).abs();
                if p.from_infinity {
                    (cos_in, 1.0)
                } else {
                    let d2 = (h.hit.t * self.ray.dir.length()).powi(2);
                    (cos_in / d2, p.cos_out / d2)
                }
            }
            None => (1.0, p.cos_out),
        };
        self.mis = self.mis.next(
            power,
            &BptStep {
                pdf_w: p.pdf_w,
                rev_pdf_w: p.rev_pdf_w,
                g,
                g_rev,
                prev_connectable: p.connectable,
            },
        );
    }
}

/// Which (s, t) contributions reach the image, and how they are weighted.
#[derive(Clone, Copy, Debug)]
struct Filter {
    strategy: Option<(u32, u32)>,
    unweighted: bool,
    /// Paths of fewer segments (s + t - 1) are left out.
    min_length: u32,
}

impl Filter {
    fn allows(&self, s: u32, t: u32) -> bool {
        self.strategy.is_none_or(|st| st == (s, t)) && s + t > self.min_length
    }

    /// The light sub-path can be skipped when the one strategy shown does not use it.
    fn needs_light_path(&self) -> bool {
        self.strategy.is_none_or(|(s, _)| s >= 2)
    }

    fn weight(&self, weight: impl FnOnce() -> f32) -> f32 {
        if self.unweighted {
            1.0
        } else {
            weight()
        }
    }
}

pub struct Bpt<'a> {
    ctx: RenderContext<'a>,
    power: Power,
    filter: Filter,
    light_paths: f32,
    chunks: Vec<Chunk<'a>>,
}

impl<'a> Bpt<'a> {
    pub fn new(ctx: RenderContext<'a>) -> Self {
        let o = ctx.options;
        Bpt {
            power: Power(o.beta),
            filter: Filter {
                strategy: o.strategy.map(|[s, t]| (s, t)),
                unweighted: o.unweighted,
                min_length: o.min_path_length,
            },
            light_paths: ctx.camera.pixel_count() as f32,
            chunks: Vec::new(),
            ctx,
        }
    }

    fn scene(&self) -> &'a Scene {
        self.ctx.scene
    }

    /// Samples the BSDF to continue a sub-path; `None` ends it.
    fn scatter(
        &self,
        state: &mut SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        sampler: &mut Sampler,
    ) -> Option<()> {
        let (s, q) = continue_sub_path(bsdf, sampler, state.index, self.ctx.options.roulette)?;
        state.throughput /= q;
        let cos_out = bsdf.cos_theta(s.wi);
        state.throughput *= s.f * (cos_out / s.pdf_w);
        if state.throughput.is_black() {
            return None;
        }
        // Delta pdfs cancel between the two directions at the vertex (001 sec. 5.3).
        state.pending = Pending {
            pdf_w: if s.delta { 1.0 } else { s.pdf_w },
            rev_pdf_w: if s.delta { 1.0 } else { s.rev_pdf_w },
            cos_out,
            connectable: !s.delta,
            from_infinity: false,
        };
        state.ray = Ray::spawn(hit.position, hit.ng, s.wi);
        state.index += 1;
        Some(())
    }

    /// Traces the light sub-path of one pixel: stores its connectable vertices and splats their
    /// connections to the camera (t = 1).
    fn trace_light_path(
        &self,
        sampler: &mut Sampler,
        vertices: &mut Vec<LightVertex<'a>>,
        splats: &mut Splats,
        stats: &mut IterationStats,
    ) {
        vertices.clear();
        let lights = &self.scene().lights;
        let Some((light_index, pick)) = lights.pick(sampler.next_f32()) else {
            return;
        };
        let light = lights.get(light_index);
        let [u_pos, u_dir] = sampler.next_4d();
        let Some(e) = light.emit(u_pos, u_dir, BPT_AIM) else {
            return;
        };
        if e.emission_pdf_w.is_nan() || e.emission_pdf_w <= 0.0 {
            return;
        }
        let origin = if light.is_finite() && !light.is_delta() {
            Ray::spawn(e.position, e.normal, e.dir).origin
        } else {
            e.position
        };
        let mut state = SubPath {
            ray: Ray::new(origin, e.dir),
            throughput: e.energy / (e.emission_pdf_w * pick),
            index: 1,
            mis: BptVertex::light_origin(self.power, e.direct_pdf_a * pick, !light.is_delta()),
            pending: Pending {
                pdf_w: e.emission_pdf_w / e.direct_pdf_a,
                rev_pdf_w: 1.0,
                cos_out: e.cos_at_light,
                connectable: true,
                from_infinity: !light.is_finite(),
            },
        };
        let max_length = self.ctx.max_path_length();
        loop {
            sampler.start_vertex(state.index);
            stats.rays += 1;
            let Some(hit) = self.scene().intersect(&state.ray) else {
                break;
            };
            state.arrive(self.power, Some(&hit));
            let wo = -state.ray.dir.normalize();
            let Some(bsdf) = self.scene().bsdf_at(&hit, wo, TransportMode::Importance) else {
                break;
            };
            if !bsdf.is_delta() {
                let vertex = LightVertex {
                    position: hit.position,
                    ng: hit.ng,
                    bsdf: bsdf.clone(),
                    throughput: state.throughput,
                    index: state.index,
                    mis: state.mis,
                };
                if self.filter.allows(state.index + 1, 1) {
                    self.connect_to_camera(&vertex, splats, stats);
                }
                vertices.push(vertex);
            }
            if state.index.saturating_add(2) > max_length {
                break;
            }
            if self.scatter(&mut state, &hit, &bsdf, sampler).is_none() {
                break;
            }
        }
    }

    /// t = 1: the light vertex seen by the camera, splatted to its pixel.
    fn connect_to_camera(&self, lv: &LightVertex, splats: &mut Splats, stats: &mut IterationStats) {
        let (camera, bsdf) = (&self.ctx.camera, &lv.bsdf);
        let Some((x, y)) = camera.raster(lv.position) else {
            return;
        };
        let to_camera = camera.position - lv.position;
        let dist2 = to_camera.length_squared();
        let dir = to_camera / dist2.sqrt();
        let eval = bsdf.eval(dir);
        if eval.f.is_black() {
            return;
        }
        let camera_pdf_a = camera.pdf_w(-dir) * bsdf.cos_theta(dir) / dist2;
        let weight = self.filter.weight(|| {
            mis::bpt_to_camera(
                self.power,
                &lv.mis,
                eval.rev_pdf_w,
                camera_pdf_a,
                self.light_paths,
            )
        });
        stats.rays += 1;
        if self
            .scene()
            .occluded(&Ray::spawn_to(lv.position, lv.ng, camera.position))
        {
            return;
        }
        let value = lv.throughput * eval.f * (weight * camera_pdf_a / self.light_paths);
        splats.push(camera.pixel_index(x, y), value);
    }

    /// s = 0: emission reached by the eye sub-path `state` at `hit` (the sky when `None`).
    fn emission(&self, state: &SubPath, hit: Option<&SurfaceHit>) -> Rgb {
        let t = state.index + 1;
        if !self.filter.allows(0, t) {
            return Rgb::BLACK;
        }
        let lights = &self.scene().lights;
        let dir = state.ray.dir.normalize();
        let Some((received, index)) = lights.received(dir, hit.map(|h| (h.light, h.ng)), BPT_AIM)
        else {
            return Rgb::BLACK;
        };
        if t == 2 {
            return received.radiance;
        }
        let pick = lights.pick_pdf(index);
        let weight = self.filter.weight(|| {
            mis::bpt_hit_light(
                self.power,
                &state.mis,
                received.direct_pdf_a * pick,
                received.emission_pdf_w * pick,
            )
        });
        received.radiance * weight
    }

    /// s = 1: light sampling at the eye vertex `hit`.
    fn light_sampling(
        &self,
        state: &SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        sampler: &mut Sampler,
        stats: &mut IterationStats,
    ) -> Rgb {
        let sample = LightSample::draw(self.scene(), hit, bsdf, sampler, BPT_AIM);
        let Some(ls) = sample.filter(|_| self.filter.allows(1, state.index + 1)) else {
            return Rgb::BLACK;
        };
        let weight = self
            .filter
            .weight(|| mis::bpt_light_sample(self.power, &state.mis, &ls.pdfs()));
        stats.rays += 1;
        if !ls.visible(self.scene(), hit) {
            return Rgb::BLACK;
        }
        ls.contribution(weight)
    }

    /// s, t >= 2: the eye vertex `hit` connected to the light vertex `lv`.
    fn connect(
        &self,
        state: &SubPath,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        lv: &LightVertex,
        stats: &mut IterationStats,
    ) -> Rgb {
        let Some(c) = Connection::new(bsdf, hit.position, &lv.bsdf, lv.position) else {
            return Rgb::BLACK;
        };
        let weight = self
            .filter
            .weight(|| mis::bpt_connect(self.power, &lv.mis, &state.mis, &c.eye_to_light_pdfs()));
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

    /// Traces the eye sub-path that starts with the camera ray `ray`, whose closest hit `first`
    /// has been found already, against the pixel's light sub-path `light_path`.
    fn trace_eye_path(
        &self,
        sampler: &mut Sampler,
        ray: Ray,
        first: Option<SurfaceHit>,
        light_path: &[LightVertex],
        stats: &mut IterationStats,
    ) -> Rgb {
        let camera = &self.ctx.camera;
        let mut state = SubPath {
            ray,
            throughput: Rgb::WHITE,
            index: 1,
            mis: BptVertex::camera_origin(),
            // The camera's per-pixel pdf shared by the light sub-paths of every pixel, as
            // `bpt_to_camera` counts it.
            pending: Pending {
                pdf_w: camera.pdf_w(ray.dir) / self.light_paths,
                rev_pdf_w: 1.0,
                cos_out: 1.0,
                connectable: true,
                from_infinity: false,
            },
        };
        let max_length = self.ctx.max_path_length();
        let mut color = Rgb::BLACK;
        // The camera ray's, then one per later vertex.
        stats.rays += 1;
        let mut found = first;
        loop {
            sampler.start_vertex(state.index);
            state.arrive(self.power, found.as_ref());
            color += state.throughput * self.emission(&state, found.as_ref());
            let Some(hit) = found else {
                break;
            };
            if state.index >= max_length {
                break;
            }
            let wo = -state.ray.dir.normalize();
            let Some(bsdf) = self.scene().bsdf_at(&hit, wo, TransportMode::Radiance) else {
                break;
            };
            if !bsdf.is_delta() {
                color +=
                    state.throughput * self.light_sampling(&state, &hit, &bsdf, sampler, stats);
                for lv in light_path {
                    let s = lv.index + 1;
                    if lv.index + state.index + 1 > max_length {
                        break;
                    }
                    if self.filter.allows(s, state.index + 1) {
                        color += state.throughput * self.connect(&state, &hit, &bsdf, lv, stats);
                    }
                }
            }
            if self.scatter(&mut state, &hit, &bsdf, sampler).is_none() {
                break;
            }
            stats.rays += 1;
            found = self.scene().intersect(&state.ray);
        }
        color
    }
}

impl Integrator for Bpt<'_> {
    fn render_iteration(&mut self, iteration: u64, frame: &mut [Rgb]) -> IterationStats {
        let (seed, kind) = (self.ctx.options.seed, self.ctx.options.sampler);
        let pixels = frame.len();
        let trace_light = self.filter.needs_light_path();
        let mut chunks = std::mem::take(&mut self.chunks);
        chunks.resize_with(pixels.div_ceil(CHUNK), Chunk::default);
        let this = &*self;
        frame
            .par_chunks_mut(CHUNK)
            .zip(chunks.par_iter_mut())
            .enumerate()
            // A task per chunk: no thread waits long at the iteration's end for another's last.
            .with_max_len(1)
            .for_each(|(c, (colors, chunk))| {
                chunk.splats.clear();
                chunk.stats = IterationStats::default();
                for (packet, colors) in colors.chunks_mut(PACKET).enumerate() {
                    let first = c * CHUNK + packet * PACKET;
                    let mut camera = CameraRays::trace(&this.ctx, iteration, first, colors.len());
                    for (lane, color) in colors.iter_mut().enumerate() {
                        if trace_light {
                            let pixel = (first + lane) as u64;
                            let mut sampler =
                                Sampler::light(kind, seed, iteration, pixel, pixels as u64);
                            this.trace_light_path(
                                &mut sampler,
                                &mut chunk.light_path,
                                &mut chunk.splats,
                                &mut chunk.stats,
                            );
                        }
                        let first_hit = camera.first_hit(&this.ctx, lane);
                        let estimate = this.trace_eye_path(
                            &mut camera.samplers[lane],
                            camera.rays[lane],
                            first_hit,
                            &chunk.light_path,
                            &mut chunk.stats,
                        );
                        add_sample(color, estimate, &mut chunk.stats.dropped_samples);
                    }
                }
            });
        let mut stats = IterationStats::default();
        for chunk in &chunks {
            stats = stats + chunk.stats;
        }
        stats.dropped_samples += add_splats(frame, &mut chunks, |chunk| &mut chunk.splats);
        self.chunks = chunks;
        stats
    }
}
