//! Lights: emissive triangles and spheres (area lights, one- or two-sided), point, spot
//! (`spot.rs`), directional and the sky (a gradient, or an environment image: `env.rs`).
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
mod spot;

pub use bounds::{Aim, SceneBounds};
pub use env::{EnvLight, EnvMapDesc};
pub use spot::{SpotCone, SpotError};

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
    /// An emissive triangle, radiating `radiance` on the side of its normal, or on both
    /// sides when `two_sided`, where its `alpha`, if any, does not cut it out.
    Triangle {
        vertices: [Vec3; 3],
        normal: Vec3,
        area: f32,
        radiance: Rgb,
        two_sided: bool,
        alpha: Option<Arc<TriangleAlpha>>,
    },
    /// An emissive sphere, radiating outwards (and inwards too when `two_sided`).
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Rgb,
        two_sided: bool,
    },
    /// `intensity` in W/sr, uniform in all directions.
    Point { position: Vec3, intensity: Rgb },
    /// `intensity` in W/sr along the axis of `cone`, falling off towards its edge.
    Spot {
        position: Vec3,
        intensity: Rgb,
        cone: SpotCone,
    },
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
            Light::Spot { .. } => "a spot light",
            Light::Directional { .. } => "a directional light",
            Light::Sky { .. } => "the sky",
            Light::Env { .. } => "the environment image",
        }
    }

    /// A delta light cannot be hit by a ray (point, spot, directional).
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point { .. } | Light::Spot { .. } | Light::Directional { .. }
        )
    }

    /// A finite light has a position (area, point, spot); directional and sky lights do not.
    pub fn is_finite(&self) -> bool {
        !matches!(
            self,
            Light::Directional { .. } | Light::Sky { .. } | Light::Env { .. }
        )
    }

    /// Total emitted power (approximate for the sky), for light selection.
    pub fn power(&self) -> f32 {
        match self {
            Light::Triangle {
                area,
                radiance,
                two_sided,
                ..
            } => radiance.average() * area * PI * sides(*two_sided),
            Light::Sphere {
                radius,
                radiance,
                two_sided,
                ..
            } => radiance.average() * 4.0 * PI * radius * radius * PI * sides(*two_sided),
            Light::Point { intensity, .. } => intensity.average() * 4.0 * PI,
            Light::Spot {
                intensity, cone, ..
            } => intensity.average() * cone.solid_angle(),
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

    /// A uniform point on an area light. Always inlined: out of line, the point came back
    /// through memory in pieces that its caller's wider loads straddled (a store-forwarding
    /// stall at every light sample).
    #[inline(always)]
    fn area_point(&self, u: [f32; 2]) -> Option<AreaPoint> {
        match *self {
            Light::Triangle {
                vertices,
                normal,
                area,
                radiance,
                two_sided,
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
                (!radiance.is_black()).then_some(AreaPoint {
                    position: p,
                    normal,
                    pdf_a: 1.0 / area,
                    radiance,
                    two_sided,
                })
            }
            Light::Sphere {
                center,
                radius,
                radiance,
                two_sided,
            } => {
                let n = sampling::uniform_sphere(u);
                Some(AreaPoint {
                    position: center + radius * n,
                    normal: n,
                    pdf_a: 1.0 / (4.0 * PI * radius * radius),
                    radiance,
                    two_sided,
                })
            }
            _ => None,
        }
    }

    /// A point on the light as seen from `receiver`, for random numbers `u`; an infinite
    /// light's `emission_pdf_w` is that of sub-paths started as `aim` says.
    pub fn illuminate(&self, receiver: Vec3, u: [f32; 2], aim: Aim) -> Option<Illumination> {
        match *self {
            Light::Triangle { .. } | Light::Sphere { .. } => {
                area_illumination(receiver, self.area_point(u)?)
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
            Light::Spot {
                position,
                intensity,
                cone,
            } => {
                let to_light = position - receiver;
                let dist2 = to_light.length_squared();
                let distance = dist2.sqrt();
                if distance <= 0.0 {
                    return None;
                }
                let dir_from_light = -to_light / distance;
                let falloff = cone.falloff(dir_from_light);
                (falloff > 0.0).then(|| Illumination {
                    dir_to_light: to_light / distance,
                    distance,
                    position,
                    normal: dir_from_light,
                    radiance: intensity * falloff,
                    direct_pdf_w: dist2,
                    emission_pdf_w: cone.pdf_w(dir_from_light),
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
                area_emission(self.area_point(u_pos)?, u_dir)
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
            Light::Spot {
                position,
                intensity,
                cone,
            } => {
                // The position is fixed: its random number picks the cone's part instead.
                let (dir, falloff, pdf_w) = cone.sample(u_pos[0], u_dir);
                (pdf_w > 0.0).then_some(Emission {
                    position,
                    dir,
                    normal: dir,
                    energy: intensity * falloff,
                    direct_pdf_a: 1.0,
                    emission_pdf_w: pdf_w,
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
    /// `None` for the back side of a one-sided light and for lights a ray cannot hit.
    pub fn radiance(&self, ray_dir: Vec3, normal: Vec3) -> Option<Received> {
        let (pdf_a, radiance, two_sided) = match *self {
            Light::Triangle {
                area,
                radiance,
                two_sided,
                ..
            } => (1.0 / area, radiance, two_sided),
            Light::Sphere {
                radius,
                radiance,
                two_sided,
                ..
            } => (1.0 / (4.0 * PI * radius * radius), radiance, two_sided),
            _ => return None,
        };
        let cos = normal.dot(-ray_dir);
        let cos = if two_sided { cos.abs() } else { cos };
        (cos > 0.0).then_some(Received {
            radiance,
            direct_pdf_a: pdf_a,
            emission_pdf_w: pdf_a * cos * FRAC_1_PI / sides(two_sided),
        })
    }
}

/// A point on an area light: its normal, density per area, radiance and sidedness.
struct AreaPoint {
    position: Vec3,
    normal: Vec3,
    pdf_a: f32,
    radiance: Rgb,
    two_sided: bool,
}

/// How many sides of an area light emit: a two-sided light emits twice the power, and its
/// sub-paths choose a side with probability 1/2, halving their direction density.
fn sides(two_sided: bool) -> f32 {
    if two_sided {
        2.0
    } else {
        1.0
    }
}

fn area_illumination(receiver: Vec3, a: AreaPoint) -> Option<Illumination> {
    let to_light = a.position - receiver;
    let dist2 = to_light.length_squared();
    let distance = dist2.sqrt();
    if distance <= 0.0 {
        return None;
    }
    let dir_to_light = to_light / distance;
    let mut normal = a.normal;
    let mut cos_at_light = normal.dot(-dir_to_light);
    if a.two_sided && cos_at_light < 0.0 {
        // The back side faces the receiver: its normal is the one a shadow ray stops short of.
        normal = -normal;
        cos_at_light = -cos_at_light;
    }
    if cos_at_light <= 0.0 {
        return None;
    }
    Some(Illumination {
        dir_to_light,
        distance,
        position: a.position,
        normal,
        radiance: a.radiance,
        // Area to solid angle at the receiver.
        direct_pdf_w: a.pdf_a * dist2 / cos_at_light,
        emission_pdf_w: a.pdf_a * cos_at_light * FRAC_1_PI / sides(a.two_sided),
        cos_at_light,
    })
}

fn area_emission(a: AreaPoint, u: [f32; 2]) -> Option<Emission> {
    let (normal, u) = if !a.two_sided {
        (a.normal, u)
    } else if u[0] < 0.5 {
        // pbrt-v4's choice of side: the first number, stretched back to [0, 1).
        (a.normal, [(2.0 * u[0]).min(ONE_MINUS_EPSILON), u[1]])
    } else {
        (
            -a.normal,
            [(2.0 * (u[0] - 0.5)).min(ONE_MINUS_EPSILON), u[1]],
        )
    };
    let local = sampling::cosine_hemisphere(u);
    if local.z <= 0.0 {
        return None;
    }
    Some(Emission {
        position: a.position,
        dir: Frame::from_z(normal).to_world(local),
        normal,
        energy: a.radiance * local.z,
        direct_pdf_a: a.pdf_a,
        emission_pdf_w: a.pdf_a * local.z * FRAC_1_PI / sides(a.two_sided),
        cos_at_light: local.z,
    })
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

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
                two_sided: materials[m as usize].two_sided,
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
                two_sided: materials[m as usize].two_sided,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    fn triangle(two_sided: bool) -> Light {
        let vertices = [Vec3::ZERO, Vec3::X, Vec3::Y];
        Light::Triangle {
            vertices,
            normal: Vec3::Z,
            area: 0.5,
            radiance: Rgb::splat(2.0),
            two_sided,
            alpha: None,
        }
    }

    /// Light sampling, a ray that hits the light and emission give one pdf each for the same
    /// point and direction, on either side of a two-sided light and on the front of a
    /// one-sided one; the back of a one-sided light gives nothing.
    #[test]
    fn area_light_pdfs_agree_between_strategies_on_both_sides() {
        let mut rng = Rng::for_sample(1, 0, 0, Stream::Light);
        for two_sided in [false, true] {
            let light = triangle(two_sided);
            for z in [0.7f32, -0.7] {
                let receiver = Vec3::new(0.2, 0.3, z);
                let il = light.illuminate(receiver, rng.next_2d(), Aim::Disc);
                if !two_sided && z < 0.0 {
                    assert!(il.is_none());
                    assert!(light.radiance(Vec3::Z, Vec3::Z).is_none());
                    continue;
                }
                let il = il.unwrap();
                assert!(il.normal.dot(receiver - il.position) > 0.0);
                let received = light.radiance(il.dir_to_light, Vec3::Z).unwrap();
                assert_eq!(received.radiance, il.radiance);
                assert_eq!(received.direct_pdf_a, 2.0);
                assert!((received.emission_pdf_w - il.emission_pdf_w).abs() < 1e-6);
                let cos = il.dir_to_light.z.abs();
                let sides = if two_sided { 2.0 } else { 1.0 };
                assert!((il.emission_pdf_w - 2.0 * cos / PI / sides).abs() < 1e-6);
            }
        }
        assert_eq!(triangle(true).power(), 2.0 * triangle(false).power());
    }

    /// Emission leaves each side of a two-sided light half the time, with half the one-sided
    /// direction density, which is what a ray arriving along the emitted direction is told.
    #[test]
    fn two_sided_emission_picks_each_side_half_the_time() {
        let mut rng = Rng::for_sample(2, 0, 0, Stream::Light);
        let light = triangle(true);
        let n = 100_000;
        let mut front = 0;
        for _ in 0..n {
            let e = light.emit(rng.next_2d(), rng.next_2d(), Aim::Disc).unwrap();
            assert!(e.dir.dot(e.normal) > 0.0);
            if e.dir.z > 0.0 {
                front += 1;
            }
            let expected = 2.0 * e.cos_at_light / PI / 2.0;
            assert!((e.emission_pdf_w - expected).abs() < 1e-5);
            let received = light.radiance(-e.dir, Vec3::Z).unwrap();
            assert!((received.emission_pdf_w - e.emission_pdf_w).abs() < 1e-5);
        }
        let sd = (n as f64 * 0.25).sqrt();
        assert!(
            (front as f64 - 0.5 * n as f64).abs() < 5.0 * sd,
            "{front} of {n}"
        );
    }

    /// A spot light sends intensity times its falloff towards a receiver, and emission's
    /// direction density is the one light sampling reports for that direction.
    #[test]
    fn spot_light_sampling_and_emission_agree() {
        let cone = SpotCone::new(Vec3::new(0.0, -1.0, 0.3), 35.0, 10.0).unwrap();
        let light = Light::Spot {
            position: Vec3::new(0.1, 2.0, 0.0),
            intensity: Rgb::splat(3.0),
            cone,
        };
        let mut rng = Rng::for_sample(3, 0, 0, Stream::Light);
        for _ in 0..1000 {
            let e = light.emit(rng.next_2d(), rng.next_2d(), Aim::Disc).unwrap();
            let receiver = e.position + 1.7 * e.dir;
            let il = light
                .illuminate(receiver, rng.next_2d(), Aim::Disc)
                .unwrap();
            assert!((il.emission_pdf_w - e.emission_pdf_w).abs() <= 1e-4 * e.emission_pdf_w);
            assert!((il.radiance.r - e.energy.r).abs() <= 1e-4 * e.energy.r);
            assert!((il.direct_pdf_w - 1.7f32 * 1.7).abs() < 1e-4);
            assert_eq!(e.energy.r, 3.0 * cone.falloff(e.dir));
        }
        // Behind the light, outside the cone: nothing.
        assert!(light
            .illuminate(Vec3::new(0.1, 3.0, 0.0), [0.5; 2], Aim::Disc)
            .is_none());
        assert!(light.is_delta() && light.is_finite());
        assert_eq!(light.power(), 3.0 * cone.solid_angle());
    }
}
