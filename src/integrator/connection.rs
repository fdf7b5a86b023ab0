//! What the integrators compute alike around their MIS weights: a light point sampled for a
//! surface point (next-event estimation), and the deterministic connection of two vertices.

use super::mis::{ConnectionPdfs, LightSamplePdfs};
use crate::bsdf::{Bsdf, BsdfEval};
use crate::color::Rgb;
use crate::light::{Aim, Illumination, Light};
use crate::sampling::Sampler;
use crate::scene::{Scene, SurfaceHit};
use glam::Vec3;

/// A light point chosen by light sampling, as the receiver's BSDF sees it.
pub struct LightSample<'s> {
    pub light: &'s Light,
    /// Probability of having picked this light.
    pub pick: f32,
    pub il: Illumination,
    /// The receiver's BSDF towards the light, and its |cos| there.
    pub eval: BsdfEval,
    pub cos_at_receiver: f32,
}

impl<'s> LightSample<'s> {
    /// Draws the pick and the point (always one choice and a 2D point, so the streams of every
    /// technique stay aligned) and returns the sample when it can contribute; `aim` is where the
    /// technique's light sub-paths of infinite lights start (for `emission_pdf_w`).
    pub fn draw(
        scene: &'s Scene,
        hit: &SurfaceHit,
        bsdf: &Bsdf,
        sampler: &mut Sampler,
        aim: Aim,
    ) -> Option<Self> {
        let [u_pick, u @ ..] = sampler.next_choice_2d();
        let (index, pick) = scene.lights.pick(u_pick)?;
        let light = scene.lights.get(index);
        let il = light.illuminate(hit.position, u, aim)?;
        let eval = bsdf.eval(il.dir_to_light);
        if eval.f.is_black() {
            return None;
        }
        Some(LightSample {
            light,
            pick,
            il,
            eval,
            cos_at_receiver: bsdf.cos_theta(il.dir_to_light),
        })
    }

    /// Pick probability times the light point's solid-angle pdf at the receiver.
    pub fn pdf_w(&self) -> f32 {
        self.pick * self.il.direct_pdf_w
    }

    /// The pdfs the MIS weights of light sampling need.
    pub fn pdfs(&self) -> LightSamplePdfs {
        LightSamplePdfs {
            bsdf_pdf_w: self.eval.pdf_w,
            bsdf_rev_pdf_w: self.eval.rev_pdf_w,
            light_pdf_w: self.pdf_w(),
            direct_pdf_w: self.il.direct_pdf_w,
            emission_pdf_w: self.il.emission_pdf_w,
            cos_at_receiver: self.cos_at_receiver,
            cos_at_light: self.il.cos_at_light,
            delta_light: self.light.is_delta(),
        }
    }

    /// Whether nothing lies between the receiver and the light point.
    pub fn visible(&self, scene: &Scene, hit: &SurfaceHit) -> bool {
        let shadow = self
            .il
            .shadow_ray(hit.position, hit.ng, self.light.is_delta());
        !scene.occluded(&shadow)
    }

    /// The estimate L f |cos| / pdf, weighted.
    pub fn contribution(&self, weight: f32) -> Rgb {
        self.il.radiance * self.eval.f * (weight * self.cos_at_receiver / self.pdf_w())
    }
}

/// Two vertices joined deterministically (a BPT connection, a UPG merge), visibility aside.
pub struct Connection {
    /// f_from G f_to (000 eq. 2.67).
    pub value: Rgb,
    /// The first vertex's pdfs towards the second, and the second's towards the first.
    pub from_eval: BsdfEval,
    pub to_eval: BsdfEval,
    pub cos_from: f32,
    pub cos_to: f32,
    pub distance: f32,
}

impl Connection {
    /// `None` when either BSDF sends nothing along the connecting segment, or it lies in
    /// either vertex's geometric plane.
    pub fn new(from: &Bsdf, from_position: Vec3, to: &Bsdf, to_position: Vec3) -> Option<Self> {
        let d = to_position - from_position;
        let dist2 = d.length_squared();
        if dist2 <= 0.0 {
            return None;
        }
        let distance = dist2.sqrt();
        let dir = d / distance;
        let from_eval = from.eval(dir);
        let to_eval = to.eval(-dir);
        if from_eval.f.is_black() || to_eval.f.is_black() {
            return None;
        }
        let (cos_from, cos_to) = (from.cos_theta(dir), to.cos_theta(-dir));
        // A segment in either surface's geometric plane carries nothing (G = 0), though
        // shading normals can give both BSDFs a value there; the MIS quantities that arrive
        // across it would divide by its zero cosine.
        if cos_from == 0.0 || cos_to == 0.0 {
            return None;
        }
        Some(Connection {
            value: from_eval.f * to_eval.f * (cos_from * cos_to / dist2),
            from_eval,
            to_eval,
            cos_from,
            cos_to,
            distance,
        })
    }

    /// Area pdf of the second vertex when the first samples it.
    pub fn to_pdf_a(&self) -> f32 {
        self.from_eval.pdf_w * self.cos_to / (self.distance * self.distance)
    }

    /// Area pdf of the first vertex when the second samples it.
    pub fn from_pdf_a(&self) -> f32 {
        self.to_eval.pdf_w * self.cos_from / (self.distance * self.distance)
    }

    /// The pdfs the MIS weights need, for a connection made from an eye vertex (the first) to
    /// a light vertex (the second).
    pub fn eye_to_light_pdfs(&self) -> ConnectionPdfs {
        ConnectionPdfs {
            light_rev_pdf_w: self.to_eval.rev_pdf_w,
            eye_rev_pdf_w: self.from_eval.rev_pdf_w,
            light_pdf_a: self.to_pdf_a(),
            eye_pdf_a: self.from_pdf_a(),
        }
    }
}
