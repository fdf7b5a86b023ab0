//! Path tracing with next-event estimation, combined with BSDF sampling by multiple importance
//! sampling (power heuristic with exponent `beta`; 000 sec. 2.2, Veach's thesis ch. 9).

use super::camera_rays::CameraRays;
use super::connection::LightSample;
use super::{Integrator, IterationStats, RenderContext};
use crate::accel::{Ray, PACKET};
use crate::bsdf::{Bsdf, TransportMode};
use crate::color::Rgb;
use crate::film::add_sample;
use crate::light::Aim;
use crate::sampling::{mis_power, Sampler};
use crate::scene::SurfaceHit;
use rayon::prelude::*;

/// The path tracer weighs nothing against light sub-paths, so where they would start is moot.
const PT_AIM: Aim = Aim::Disc;

pub struct PathTracer<'a> {
    ctx: RenderContext<'a>,
}

impl<'a> PathTracer<'a> {
    pub fn new(ctx: RenderContext<'a>) -> Self {
        PathTracer { ctx }
    }

    /// Power-heuristic weight of a strategy with density `pdf` against one with `other`.
    fn mis(&self, pdf: f32, other: f32) -> f32 {
        let beta = self.ctx.options.beta;
        let a = mis_power(pdf, beta);
        a / (a + mis_power(other, beta))
    }

    /// Radiance arriving at the camera along the camera ray `ray`, whose closest hit `first`
    /// has been found already, and the rays traced (the camera ray's included).
    fn radiance(
        &self,
        mut ray: Ray,
        first: Option<SurfaceHit>,
        sampler: &mut Sampler,
    ) -> (Rgb, u64) {
        let scene = self.ctx.scene;
        let max_length = self.ctx.max_path_length();
        let roulette = self.ctx.options.roulette;
        // Paths of fewer segments are left out (`min_path_length`).
        let min_length = self.ctx.options.min_path_length;
        let mut radiance = Rgb::BLACK;
        let mut throughput = Rgb::WHITE;
        let mut rays = 1u64;
        let mut found = first;
        // pdf (solid angle) of the BSDF sample that produced `ray`, and whether it was a delta
        // lobe (or the camera), in which case light sampling could not have produced it.
        let mut last_pdf_w = 1.0f32;
        let mut last_delta = true;
        // Segments of the path so far, camera included.
        let mut length = 1u32;
        loop {
            sampler.start_vertex(length);
            let Some(hit) = found else {
                if let Some(received) = scene
                    .lights
                    .background(ray.dir, PT_AIM)
                    .filter(|_| length >= min_length)
                {
                    let weight = if last_delta {
                        1.0
                    } else {
                        let pick = scene.lights.pick_pdf(scene.lights.sky().unwrap_or(0));
                        self.mis(last_pdf_w, received.direct_pdf_a * pick)
                    };
                    radiance += throughput * received.radiance * weight;
                }
                break;
            };
            if length >= min_length {
                radiance += throughput * self.emitted(&ray, &hit, last_pdf_w, last_delta);
            }
            if length >= max_length {
                break;
            }
            let Some(bsdf) = scene.bsdf_at(&hit, -ray.dir, TransportMode::Radiance) else {
                break;
            };
            if !bsdf.is_delta() && length + 1 >= min_length {
                let (light, shadow_rays) = self.sample_light(&hit, &bsdf, sampler);
                radiance += throughput * light;
                rays += shadow_rays;
            }
            let roulette_here = length >= roulette;
            let (u, u_roulette) = sampler.next_scatter(roulette_here);
            let Some(sample) = bsdf.sample(u) else {
                break;
            };
            throughput *= sample.f * (bsdf.cos_theta(sample.wi) / sample.pdf_w);
            if roulette_here {
                let continue_probability = bsdf.continuation_probability();
                if u_roulette >= continue_probability {
                    break;
                }
                throughput /= continue_probability;
            }
            if throughput.is_black() {
                break;
            }
            last_pdf_w = sample.pdf_w;
            last_delta = sample.delta;
            ray = Ray::spawn(hit.position, hit.ng, sample.wi);
            length += 1;
            rays += 1;
            found = scene.intersect(&ray);
        }
        (radiance, rays)
    }

    /// Emission of the surface hit by `ray`, weighted against light sampling.
    fn emitted(&self, ray: &Ray, hit: &SurfaceHit, last_pdf_w: f32, last_delta: bool) -> Rgb {
        let lights = &self.ctx.scene.lights;
        let Some(index) = hit.light else {
            return Rgb::BLACK;
        };
        let Some(received) = lights.get(index).radiance(ray.dir, hit.ng) else {
            return Rgb::BLACK;
        };
        if last_delta {
            return received.radiance;
        }
        // The light-sampling density of this point, per solid angle at the previous vertex (on
        // either side of a two-sided light).
        let distance = hit.hit.t * ray.dir.length();
        let cos_at_light = hit.ng.dot(-ray.dir.normalize()).abs();
        let direct_pdf_w =
            received.direct_pdf_a * lights.pick_pdf(index) * distance * distance / cos_at_light;
        received.radiance * self.mis(last_pdf_w, direct_pdf_w)
    }

    /// Next-event estimation: one light sample, weighted against BSDF sampling.
    fn sample_light(&self, hit: &SurfaceHit, bsdf: &Bsdf, sampler: &mut Sampler) -> (Rgb, u64) {
        let scene = self.ctx.scene;
        let Some(ls) = LightSample::draw(scene, hit, bsdf, sampler, PT_AIM) else {
            return (Rgb::BLACK, 0);
        };
        if !ls.visible(scene, hit) {
            return (Rgb::BLACK, 1);
        }
        let weight = if ls.light.is_delta() {
            1.0
        } else {
            self.mis(ls.pdf_w(), ls.eval.pdf_w)
        };
        (ls.contribution(weight), 1)
    }
}

impl Integrator for PathTracer<'_> {
    fn render_iteration(&mut self, iteration: u64, frame: &mut [Rgb]) -> IterationStats {
        let width = self.ctx.camera.width as usize;
        let this = &*self;
        frame
            .par_chunks_mut(width)
            .enumerate()
            // A task per row: no thread waits long at the iteration's end for another's last.
            .with_max_len(1)
            .map(|(y, row)| {
                let mut stats = IterationStats::default();
                for (packet, pixels) in row.chunks_mut(PACKET).enumerate() {
                    let first = y * width + packet * PACKET;
                    let mut camera = CameraRays::trace(&this.ctx, iteration, first, pixels.len());
                    for (lane, pixel) in pixels.iter_mut().enumerate() {
                        let (radiance, rays) = this.radiance(
                            camera.rays[lane],
                            camera.first_hit(&this.ctx, lane),
                            &mut camera.samplers[lane],
                        );
                        stats.rays += rays;
                        add_sample(pixel, radiance, &mut stats.dropped_samples);
                    }
                }
                stats
            })
            .reduce(IterationStats::default, |a, b| a + b)
    }
}
