//! Lights: emissive triangles and spheres (area lights), point, directional and the sky (a
//! gradient, or an environment image: `env.rs`).
//!
//! Every light answers the three questions the integrators ask (SmallVCM's interface, 001
//! sec. 5.1 for the infinite ones):
//! - [`Light::illuminate`]: a point on the light seen from a receiver (next-event estimation),
//! - [`Light::emit`]: a position and direction to start a light sub-path,
//! - [`Light::radiance`] / [`Lights::background`]: what a ray that hits the light receives,
//!
//! each with the pdfs the MIS weights need: `direct_pdf_a` (of choosing the point by
//! `illuminate`, per area; per solid angle for infinite lights) and `emission_pdf_w` (of
//! emitting that point and direction, per area times solid angle). Light selection
//! probabilities are not included; [`Lights`] picks lights in proportion to their power.

use crate::accel::{Geometry, Ray, TriangleAlpha};
use crate::bsdf::Material;
use crate::color::Rgb;
use crate::frame::Frame;
use crate::sampling::{self, Distribution1D};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, PI};
use std::sync::Arc;

mod bounds;
mod env;

pub use bounds::{Aim, SceneBounds};
pub use env::{EnvLight, EnvMapDesc};

/// Background radiance L(w) = horizon + (zenith - horizon) * max(0, w . up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkyDesc {
    pub horizon: Rgb,
    pub zenith: Rgb,
    pub up: Vec3,
}

/// Marks a primitive that emits nothing in the primitive-to-light tables.
const NO_LIGHT: u32 = u32::MAX;

#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// An emissive triangle, radiating `radiance` on the side of its normal where its
    /// `alpha`, if any, does not cut it out.
    Triangle {
        vertices: [Vec3; 3],
        normal: Vec3,
        area: f32,
        radiance: Rgb,
        alpha: Option<Arc<TriangleAlpha>>,
    },
    /// An emissive sphere, radiating outwards.
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Rgb,
    },
    /// `intensity` in W/sr, uniform in all directions.
    Point { position: Vec3, intensity: Rgb },
    /// Parallel light travelling along the unit `direction`; `irradiance` in W/m^2 on a
    /// perpendicular surface. `scene` is where its light sub-paths start.
    Directional {
        direction: Vec3,
        irradiance: Rgb,
        scene: SceneBounds,
    },
    /// The gradient sky, an infinite light around the scene.
    Sky { sky: SkyDesc, scene: SceneBounds },
    /// An environment image as the sky, likewise infinite.
    Env {
        env: Arc<EnvLight>,
        scene: SceneBounds,
    },
}

/// Light seen from a receiver (next-event estimation).
#[derive(Clone, Copy, Debug)]
pub struct Illumination {
    /// Unit direction from the receiver to the light.
    pub dir_to_light: Vec3,
    /// Distance to the light point (infinite lights: `f32::INFINITY`).
    pub distance: f32,
    /// The light point and its normal (for a shadow ray that stops short of the surface);
    /// meaningless for infinite lights.
    pub position: Vec3,
    pub normal: Vec3,
    /// Radiance arriving at the receiver (point light: intensity).
    pub radiance: Rgb,
    /// pdf of choosing this light point by `illuminate`, per solid angle at the receiver
    /// (point and directional lights: the factor that turns intensity into irradiance).
    pub direct_pdf_w: f32,
    /// pdf of `emit` producing this point and direction.
    pub emission_pdf_w: f32,
    /// Cosine at the light between its normal and the emitted direction (1 for point,
    /// directional and sky).
    pub cos_at_light: f32,
}

impl Illumination {
    /// The shadow ray from the receiver `p` (geometric normal `ng`) to this light point:
    /// towards the light for infinite lights, to the point itself for a point light, and
    /// stopping short of the surface for area lights.
    pub fn shadow_ray(&self, p: Vec3, ng: Vec3, delta: bool) -> Ray {
        if !self.distance.is_finite() {
            Ray::spawn(p, ng, self.dir_to_light)
        } else if delta {
            Ray::spawn_to(p, ng, self.position)
        } else {
            Ray::spawn_between(p, ng, self.position, self.normal)
        }
    }
}

/// The start of a light sub-path.
#[derive(Clone, Copy, Debug)]
pub struct Emission {
    pub position: Vec3,
    /// Unit direction of travel.
    pub dir: Vec3,
    /// Surface normal at the light point (the direction itself for non-area lights).
    pub normal: Vec3,
    /// Radiance times the cosine at the light (point: intensity, directional: irradiance).
    pub energy: Rgb,
    /// Per area for finite lights (1 for point lights); per solid angle for infinite lights.
    pub direct_pdf_a: f32,
    pub emission_pdf_w: f32,
    pub cos_at_light: f32,
}

/// What a ray that reaches a light receives.
#[derive(Clone, Copy, Debug)]
pub struct Received {
    pub radiance: Rgb,
    /// Per area for area lights, per solid angle for the sky.
    pub direct_pdf_a: f32,
    pub emission_pdf_w: f32,
}

impl Light {
    /// What kind of light it is, in words.
    pub fn kind(&self) -> &'static str {
        match self {
            Light::Triangle { .. } => "an emissive triangle",
            Light::Sphere { .. } => "an emissive sphere",
            Light::Point { .. } => "a point light",
            Light::Directional { .. } => "a directional light",
            Light::Sky { .. } => "the sky",
            Light::Env { .. } => "the environment image",
        }
    }

    /// A delta light cannot be hit by a ray (point, directional).
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. } | Light::Directional { .. })
    }

    /// A finite light has a position (area, point); directional and sky lights do not.
    pub fn is_finite(&self) -> bool {
        !matches!(
            self,
            Light::Directional { .. } | Light::Sky { .. } | Light::Env { .. }
        )
    }

    /// Total emitted power (approximate for the sky), for light selection.
    pub fn power(&self) -> f32 {
        match self {
            Light::Triangle { area, radiance, .. } => radiance.average() * area * PI,
            Light::Sphere {
                radius, radiance, ..
            } => radiance.average() * 4.0 * PI * radius * radius * PI,
            Light::Point { intensity, .. } => intensity.average() * 4.0 * PI,
            Light::Directional {
                direction,
                irradiance,
                scene,
            } => irradiance.average() * scene.projected_area(*direction),
            // The power entering the box: the mean radiance, times pi (the cosine-weighted
            // hemisphere), times the mean silhouette.
            Light::Sky { sky, scene } => {
                let mean = 0.5 * (sky.horizon + (sky.horizon + sky.zenith) * 0.5);
                mean.average() * PI * scene.mean_projected_area()
            }
            Light::Env { env, scene } => {
                env.integral() / (4.0 * PI) * PI * scene.mean_projected_area()
            }
        }
    }

    /// A uniform point on an area light: position, normal, density per area, radiance.
    fn area_point(&self, u: [f32; 2]) -> Option<(Vec3, Vec3, f32, Rgb)> {
        match *self {
            Light::Triangle {
                vertices,
                normal,
                area,
                radiance,
                ref alpha,
            } => {
                let (b1, b2) = sampling::uniform_triangle(u);
                let p = (1.0 - b1 - b2) * vertices[0] + b1 * vertices[1] + b2 * vertices[2];
                // A ray meets a cut-out point with probability alpha (clamped, `accel::alpha`),
                // so that is the share of the radiance a sampled point carries.
                let radiance = match alpha {
                    Some(a) => radiance * a.value(b1, b2).clamp(0.0, 1.0),
                    None => radiance,
                };
                (!radiance.is_black()).then_some((p, normal, 1.0 / area, radiance))
            }
            Light::Sphere {
                center,
                radius,
                radiance,
            } => {
                let n = sampling::uniform_sphere(u);
                Some((
                    center + radius * n,
                    n,
                    1.0 / (4.0 * PI * radius * radius),
                    radiance,
                ))
            }
            _ => None,
        }
    }

    /// A point on the light as seen from `receiver`, for random numbers `u`; an infinite
    /// light's `emission_pdf_w` is that of sub-paths started as `aim` says.
    pub fn illuminate(&self, receiver: Vec3, u: [f32; 2], aim: Aim) -> Option<Illumination> {
        match *self {
            Light::Triangle { .. } | Light::Sphere { .. } => {
                let (p, normal, pdf_a, radiance) = self.area_point(u)?;
                area_illumination(receiver, p, normal, pdf_a, radiance)
            }
            Light::Point {
                position,
                intensity,
            } => {
                let to_light = position - receiver;
                let dist2 = to_light.length_squared();
                let distance = dist2.sqrt();
                (distance > 0.0).then(|| Illumination {
                    dir_to_light: to_light / distance,
                    distance,
                    position,
                    normal: -to_light / distance,
                    radiance: intensity,
                    direct_pdf_w: dist2,
                    emission_pdf_w: sampling::UNIFORM_SPHERE_PDF,
                    cos_at_light: 1.0,
                })
            }
            Light::Directional {
                direction,
                irradiance,
                scene,
            } => Some(Illumination {
                dir_to_light: -direction,
                distance: f32::INFINITY,
                position: receiver - direction * 2.0 * scene.radius(),
                normal: direction,
                radiance: irradiance,
                direct_pdf_w: 1.0,
                emission_pdf_w: scene.origin_pdf(direction, aim),
                cos_at_light: 1.0,
            }),
            Light::Sky { sky, scene } => {
                let dir = sampling::uniform_sphere(u);
                let direct_pdf_w = sampling::UNIFORM_SPHERE_PDF;
                Some(Illumination {
                    dir_to_light: dir,
                    distance: f32::INFINITY,
                    position: receiver + dir * 2.0 * scene.radius(),
                    normal: -dir,
                    radiance: sky_radiance(&sky, dir),
                    direct_pdf_w,
                    emission_pdf_w: direct_pdf_w * scene.origin_pdf(dir, aim),
                    cos_at_light: 1.0,
                })
            }
            Light::Env { ref env, scene } => {
                let (dir, radiance, direct_pdf_w) = env.sample(u)?;
                Some(Illumination {
                    dir_to_light: dir,
                    distance: f32::INFINITY,
                    position: receiver + dir * 2.0 * scene.radius(),
                    normal: -dir,
                    radiance,
                    direct_pdf_w,
                    emission_pdf_w: direct_pdf_w * scene.origin_pdf(dir, aim),
                    cos_at_light: 1.0,
                })
            }
        }
    }

    /// A position and direction leaving the light: `u_pos` picks the position, `u_dir` the
    /// direction; an infinite light's position lies in the region `aim`.
    pub fn emit(&self, u_pos: [f32; 2], u_dir: [f32; 2], aim: Aim) -> Option<Emission> {
        match *self {
            Light::Triangle { .. } | Light::Sphere { .. } => {
                let (p, normal, pdf_a, radiance) = self.area_point(u_pos)?;
                area_emission(p, normal, pdf_a, radiance, u_dir)
            }
            Light::Point {
                position,
                intensity,
            } => {
                let dir = sampling::uniform_sphere(u_dir);
                Some(Emission {
                    position,
                    dir,
                    normal: dir,
                    energy: intensity,
                    direct_pdf_a: 1.0,
                    emission_pdf_w: sampling::UNIFORM_SPHERE_PDF,
                    cos_at_light: 1.0,
                })
            }
            Light::Directional {
                direction,
                irradiance,
                scene,
            } => Some(Emission {
                position: scene.origin(direction, u_pos, aim),
                dir: direction,
                normal: direction,
                energy: irradiance,
                direct_pdf_a: 1.0,
                emission_pdf_w: scene.origin_pdf(direction, aim),
                cos_at_light: 1.0,
            }),
            Light::Sky { sky, scene } => {
                // 001 sec. 5.1: a direction towards the sky, then a point of the region `aim`
                // facing it; the pdf of the point is per area of the plane.
                let to_sky = sampling::uniform_sphere(u_dir);
                let dir = -to_sky;
                let direct_pdf_w = sampling::UNIFORM_SPHERE_PDF;
                Some(Emission {
                    position: scene.origin(dir, u_pos, aim),
                    dir,
                    normal: dir,
                    energy: sky_radiance(&sky, to_sky),
                    direct_pdf_a: direct_pdf_w,
                    emission_pdf_w: direct_pdf_w * scene.origin_pdf(dir, aim),
                    cos_at_light: 1.0,
                })
            }
            Light::Env { ref env, scene } => {
                // 001 sec. 5.1, as for the gradient sky, the direction drawn from the image.
                let (to_sky, radiance, direct_pdf_w) = env.sample(u_dir)?;
                let dir = -to_sky;
                Some(Emission {
                    position: scene.origin(dir, u_pos, aim),
                    dir,
                    normal: dir,
                    energy: radiance,
                    direct_pdf_a: direct_pdf_w,
                    emission_pdf_w: direct_pdf_w * scene.origin_pdf(dir, aim),
                    cos_at_light: 1.0,
                })
            }
        }
    }

    /// Radiance leaving the area light at `position` (normal `normal`) towards a ray that
    /// arrives travelling along `ray_dir` (unit), with the pdfs of the other strategies.
    /// `None` for the back side and for lights a ray cannot hit.
    pub fn radiance(&self, ray_dir: Vec3, normal: Vec3) -> Option<Received> {
        let (pdf_a, radiance) = match *self {
            Light::Triangle { area, radiance, .. } => (1.0 / area, radiance),
            Light::Sphere {
                radius, radiance, ..
            } => (1.0 / (4.0 * PI * radius * radius), radiance),
            _ => return None,
        };
        let cos = normal.dot(-ray_dir);
        (cos > 0.0).then_some(Received {
            radiance,
            direct_pdf_a: pdf_a,
            emission_pdf_w: pdf_a * cos * FRAC_1_PI,
        })
    }
}

fn area_illumination(
    receiver: Vec3,
    p: Vec3,
    normal: Vec3,
    pdf_a: f32,
    radiance: Rgb,
) -> Option<Illumination> {
    let to_light = p - receiver;
    let dist2 = to_light.length_squared();
    let distance = dist2.sqrt();
    if distance <= 0.0 {
        return None;
    }
    let dir_to_light = to_light / distance;
    let cos_at_light = normal.dot(-dir_to_light);
    if cos_at_light <= 0.0 {
        return None;
    }
    Some(Illumination {
        dir_to_light,
        distance,
        position: p,
        normal,
        radiance,
        // Area to solid angle at the receiver.
        direct_pdf_w: pdf_a * dist2 / cos_at_light,
        emission_pdf_w: pdf_a * cos_at_light * FRAC_1_PI,
        cos_at_light,
    })
}

fn area_emission(
    p: Vec3,
    normal: Vec3,
    pdf_a: f32,
    radiance: Rgb,
    u: [f32; 2],
) -> Option<Emission> {
    let local = sampling::cosine_hemisphere(u);
    if local.z <= 0.0 {
        return None;
    }
    Some(Emission {
        position: p,
        dir: Frame::from_z(normal).to_world(local),
        normal,
        energy: radiance * local.z,
        direct_pdf_a: pdf_a,
        emission_pdf_w: pdf_a * local.z * FRAC_1_PI,
        cos_at_light: local.z,
    })
}

/// The sky's radiance seen looking along the unit direction `w`.
pub fn sky_radiance(sky: &SkyDesc, w: Vec3) -> Rgb {
    sky.horizon + (sky.zenith - sky.horizon) * w.dot(sky.up).max(0.0)
}

/// All lights of a scene, their selection distribution and the primitive-to-light tables.
#[derive(Clone, Debug)]
pub struct Lights {
    lights: Vec<Light>,
    selection: Option<Distribution1D>,
    triangle_lights: Vec<u32>,
    sphere_lights: Vec<u32>,
    sky: Option<u32>,
}

impl Lights {
    /// Collects the emissive triangles and spheres, the explicit lights and the sky: the
    /// environment image `env` when there is one, else the gradient `sky`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        geometry: &Geometry,
        triangle_materials: &[u32],
        sphere_materials: &[u32],
        materials: &[Material],
        explicit: Vec<Light>,
        sky: Option<SkyDesc>,
        env: Option<EnvMapDesc>,
        scene: SceneBounds,
    ) -> Self {
        let mut lights = Vec::new();
        let mut triangle_lights = vec![NO_LIGHT; geometry.triangles.len()];
        for (i, &m) in triangle_materials.iter().enumerate() {
            let emission = materials[m as usize].emission;
            if emission.is_black() {
                continue;
            }
            let vertices = geometry.triangle_vertices(i as u32);
            let cross = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]);
            let area = 0.5 * cross.length();
            if area <= 0.0 {
                continue;
            }
            triangle_lights[i] = lights.len() as u32;
            lights.push(Light::Triangle {
                vertices,
                normal: cross.normalize(),
                area,
                radiance: emission,
                alpha: geometry.cutouts.get(i as u32).cloned().map(Arc::new),
            });
        }
        let mut sphere_lights = vec![NO_LIGHT; geometry.spheres.len()];
        for (i, &m) in sphere_materials.iter().enumerate() {
            let emission = materials[m as usize].emission;
            if emission.is_black() {
                continue;
            }
            let s = geometry.spheres[i];
            sphere_lights[i] = lights.len() as u32;
            lights.push(Light::Sphere {
                center: s.center,
                radius: s.radius,
                radiance: emission,
            });
        }
        for light in explicit {
            lights.push(match light {
                Light::Directional {
                    direction,
                    irradiance,
                    ..
                } => Light::Directional {
                    direction: direction.normalize(),
                    irradiance,
                    scene,
                },
                other => other,
            });
        }
        let sky_light = match env {
            Some(desc) => EnvLight::new(&desc).map(|env| Light::Env {
                env: Arc::new(env),
                scene,
            }),
            None => sky
                .filter(|s| !(s.horizon.is_black() && s.zenith.is_black()))
                .map(|sky| Light::Sky { sky, scene }),
        };
        let sky_index = sky_light.map(|light| {
            lights.push(light);
            lights.len() as u32 - 1
        });
        let selection = Distribution1D::new(lights.iter().map(Light::power).collect());
        Lights {
            lights,
            selection,
            triangle_lights,
            sphere_lights,
            sky: sky_index,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.selection.is_none()
    }

    /// Why light selection is impossible although there are lights: the first light whose
    /// power is not a finite number (the selection's sum is f64 and does not overflow).
    pub fn power_overflow(&self) -> Option<String> {
        let (i, light) = self
            .lights
            .iter()
            .enumerate()
            .find(|(_, l)| !l.power().is_finite())?;
        Some(format!(
            "light {i} ({}) emits {} W",
            light.kind(),
            light.power()
        ))
    }

    pub fn len(&self) -> usize {
        self.lights.len()
    }

    pub fn get(&self, index: u32) -> &Light {
        &self.lights[index as usize]
    }

    /// Picks a light in proportion to its power; returns its index and probability.
    pub fn pick(&self, u: f32) -> Option<(u32, f32)> {
        self.selection.as_ref().map(|d| {
            let (i, p) = d.sample(u);
            (i as u32, p)
        })
    }

    /// Probability that [`Lights::pick`] returns `index`.
    pub fn pick_pdf(&self, index: u32) -> f32 {
        self.selection
            .as_ref()
            .map_or(0.0, |d| d.pmf(index as usize))
    }

    pub fn triangle_light(&self, triangle: u32) -> Option<u32> {
        let l = self.triangle_lights[triangle as usize];
        (l != NO_LIGHT).then_some(l)
    }

    pub fn sphere_light(&self, sphere: u32) -> Option<u32> {
        let l = self.sphere_lights[sphere as usize];
        (l != NO_LIGHT).then_some(l)
    }

    /// The sky light's index, if the scene has one.
    pub fn sky(&self) -> Option<u32> {
        self.sky
    }

    /// What a ray travelling along the unit `dir` receives where it ends: from the emitter
    /// `hit` (its light index and geometric normal) or, leaving the scene (`None`), from the
    /// sky (its `emission_pdf_w` that of sub-paths started as `aim` says); with the index of
    /// the light it came from.
    pub fn received(
        &self,
        dir: Vec3,
        hit: Option<(Option<u32>, Vec3)>,
        aim: Aim,
    ) -> Option<(Received, u32)> {
        match hit {
            Some((light, normal)) => {
                let index = light?;
                Some((self.get(index).radiance(dir, normal)?, index))
            }
            None => Some((self.background(dir, aim)?, self.sky?)),
        }
    }

    /// What a ray leaving the scene along the unit `dir` receives from the sky.
    pub fn background(&self, dir: Vec3, aim: Aim) -> Option<Received> {
        let (radiance, direct_pdf_a, scene) = match self.get(self.sky?) {
            Light::Sky { sky, scene } => {
                (sky_radiance(sky, dir), sampling::UNIFORM_SPHERE_PDF, scene)
            }
            Light::Env { env, scene } => (env.radiance(dir), env.pdf_w(dir), scene),
            _ => return None,
        };
        Some(Received {
            radiance,
            direct_pdf_a,
            emission_pdf_w: direct_pdf_a * scene.origin_pdf(dir, aim),
        })
    }

    /// Bytes held by the environment light's sampling distribution (zero without one).
    pub fn env_distribution_bytes(&self) -> usize {
        match self.sky.map(|i| self.get(i)) {
            Some(Light::Env { env, .. }) => env.distribution_bytes(),
            _ => 0,
        }
    }
}
