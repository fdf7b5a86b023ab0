//! The camera rays of neighbouring pixels, traced together. They start at the camera and part
//! little, so Embree traces them as one packet for less than as many single rays cost (the first
//! rays are the longest: they cross the scene from outside its surfaces). Each pixel keeps its own
//! sampler, and a packet's hits are those of single rays, so the images are the same bit for bit.

use super::RenderContext;
use crate::accel::{Hit, Ray, PACKET};
use crate::sampling::Sampler;
use crate::scene::SurfaceHit;

/// The camera rays of pixels `first..first + len` (row-major indices; `len` at most
/// [`PACKET`]) with their samplers and closest hits.
pub struct CameraRays {
    /// Each pixel's eye sampler, its pixel jitter drawn.
    pub samplers: [Sampler; PACKET],
    pub rays: [Ray; PACKET],
    hits: [Option<Hit>; PACKET],
}

impl CameraRays {
    /// Draws each pixel's jitter, makes its camera ray and traces the rays as one packet.
    pub fn trace(ctx: &RenderContext, iteration: u64, first: usize, len: usize) -> Self {
        debug_assert!((1..=PACKET).contains(&len));
        // Lanes past `len` repeat the last pixel and stay inactive.
        let pixel = |lane: usize| first + lane.min(len - 1);
        let mut samplers: [Sampler; PACKET] =
            std::array::from_fn(|lane| eye_sampler(ctx, iteration, pixel(lane)));
        let rays: [Ray; PACKET] =
            std::array::from_fn(|lane| camera_ray(ctx, pixel(lane), &mut samplers[lane]));
        let mut hits = [None; PACKET];
        ctx.scene
            .intersect8(&rays, u8::MAX >> (PACKET - len), &mut hits);
        CameraRays {
            samplers,
            rays,
            hits,
        }
    }

    /// The surface point the camera ray of lane `lane` hit first.
    pub fn first_hit(&self, ctx: &RenderContext, lane: usize) -> Option<SurfaceHit> {
        self.hits[lane].map(|hit| ctx.scene.surface_hit(&self.rays[lane], hit))
    }
}

/// The eye sampler of `pixel` (a row-major index) in `iteration`, its camera ray and that ray's
/// closest hit: one lane of [`CameraRays::trace`], traced alone.
pub fn camera_ray_traced(
    ctx: &RenderContext,
    iteration: u64,
    pixel: usize,
) -> (Sampler, Ray, Option<SurfaceHit>) {
    let mut sampler = eye_sampler(ctx, iteration, pixel);
    let ray = camera_ray(ctx, pixel, &mut sampler);
    let hit = ctx.scene.intersect(&ray);
    (sampler, ray, hit)
}

/// The eye sampler of `pixel` (a row-major index) in `iteration`.
fn eye_sampler(ctx: &RenderContext, iteration: u64, pixel: usize) -> Sampler {
    Sampler::eye(
        ctx.options.sampler,
        ctx.options.seed,
        iteration,
        pixel as u64,
    )
}

/// The camera ray of `pixel` (a row-major index), through the point of it that the pixel's eye
/// sampler's first draw picks.
pub fn camera_ray(ctx: &RenderContext, pixel: usize, sampler: &mut Sampler) -> Ray {
    let width = ctx.camera.width as usize;
    let [jx, jy] = sampler.next_2d();
    ctx.camera
        .generate_ray((pixel % width) as f32 + jx, (pixel / width) as f32 + jy)
}
