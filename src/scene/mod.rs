//! Scenes: the TOML scene file with its OBJ/MTL meshes and spheres, validated and turned into
//! geometry for the ray queries, materials, lights and cameras.

use crate::accel::{self, Accel, AccelKind, Geometry, Hit, Primitive, Ray, PACKET};
use crate::bsdf::Material;
use crate::light::{Lights, SkyDesc};
use glam::Vec3;
use std::path::PathBuf;

mod camera;
mod error;
mod load;
pub mod pbrt;
mod wavefront;

pub use camera::{Camera, CameraDesc, FovAxis};
pub use error::SceneError;
pub use load::{load, load_parts, LoadOptions};

/// The largest coordinate a scene may have: f32 positions there are still 1/16 apart, so a
/// scene of ordinary size keeps its detail, while beyond it areas, distances and the default
/// merge radius lose their meaning (and their squares overflow).
pub const MAX_COORDINATE: f32 = 1e8;

/// The `[render]` table: per-scene defaults, each overridable on the command line.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderDefaults {
    pub resolution: [u32; 2],
    /// Segments of a full path, light to eye; 0 = unbounded.
    pub max_path_length: u32,
    /// Merge radius in world units; `None` = 0.003 x the bounding-sphere diameter.
    pub radius: Option<f32>,
}

impl Default for RenderDefaults {
    fn default() -> Self {
        RenderDefaults {
            resolution: [512, 512],
            max_path_length: 10,
            radius: None,
        }
    }
}

/// A surface point found by a ray.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub hit: Hit,
    pub position: Vec3,
    /// Unit geometric normal (outward for spheres, counter-clockwise side for triangles).
    pub ng: Vec3,
    pub material: u32,
    /// Index into `Scene::lights` when the primitive emits.
    pub light: Option<u32>,
}

/// A loaded, validated scene, ready to render.
pub struct Scene {
    /// The scene file, and a hash of its bytes and of every file it references.
    pub source: PathBuf,
    pub source_hash: String,
    pub geometry: Geometry,
    pub triangle_materials: Vec<u32>,
    pub sphere_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub lights: Lights,
    pub cameras: Vec<CameraDesc>,
    pub defaults: RenderDefaults,
    pub accel: Box<dyn Accel>,
    /// Centre and radius of the bounding sphere of all geometry.
    pub bounding_sphere: (Vec3, f32),
    /// Degenerate triangles dropped while loading.
    pub dropped_triangles: usize,
    /// Every file the scene was read from (the scene file first).
    pub inputs: Vec<PathBuf>,
}

/// Everything but the ray-query structure, from which [`Scene::build`] makes a scene; the
/// loader fills it from files and tests fill it by hand.
pub struct SceneParts {
    pub source: PathBuf,
    pub source_hash: String,
    pub geometry: Geometry,
    pub triangle_materials: Vec<u32>,
    pub sphere_materials: Vec<u32>,
    pub materials: Vec<Material>,
    pub point_and_directional: Vec<crate::light::Light>,
    pub sky: Option<SkyDesc>,
    pub cameras: Vec<CameraDesc>,
    pub defaults: RenderDefaults,
    pub dropped_triangles: usize,
    pub inputs: Vec<PathBuf>,
}

impl Scene {
    /// Builds the lights (emissive primitives, the given point and directional lights, the sky)
    /// and the chosen ray-query backend.
    pub fn build(parts: SceneParts, accel_kind: AccelKind) -> Result<Scene, SceneError> {
        let (min, max) = parts.geometry.bounds().ok_or(SceneError::NoGeometry {
            file: parts.source.clone(),
        })?;
        let center = 0.5 * (min + max);
        let radius = (0.5 * (max - min).length()).max(1e-6);
        let lights = Lights::new(
            &parts.geometry,
            &parts.triangle_materials,
            &parts.sphere_materials,
            &parts.materials,
            parts.point_and_directional,
            parts.sky,
            (center, radius),
        );
        if let Some(message) = lights.power_overflow() {
            return Err(SceneError::LightPower {
                file: parts.source.clone(),
                message,
            });
        }
        if lights.is_empty() {
            return Err(SceneError::NoLights {
                file: parts.source.clone(),
            });
        }
        let accel =
            accel::build(accel_kind, &parts.geometry).map_err(|source| SceneError::Accel {
                file: parts.source.clone(),
                source,
            })?;
        Ok(Scene {
            source: parts.source,
            source_hash: parts.source_hash,
            geometry: parts.geometry,
            triangle_materials: parts.triangle_materials,
            sphere_materials: parts.sphere_materials,
            materials: parts.materials,
            lights,
            cameras: parts.cameras,
            defaults: parts.defaults,
            accel,
            bounding_sphere: (center, radius),
            dropped_triangles: parts.dropped_triangles,
            inputs: parts.inputs,
        })
    }

    /// Closest surface along `ray`.
    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        self.accel
            .intersect(ray)
            .map(|hit| self.surface_hit(ray, hit))
    }

    /// Closest backend hits of up to 8 rays, bit `i` of `active` selecting `rays[i]` (see
    /// [`Accel::intersect8`]); [`Scene::surface_hit`] turns a hit into a surface point.
    pub fn intersect8(&self, rays: &[Ray; PACKET], active: u8, hits: &mut [Option<Hit>; PACKET]) {
        self.accel.intersect8(rays, active, hits)
    }

    /// Whether a backend hit lies on a mirror or glass surface.
    pub fn hits_delta_surface(&self, hit: &Hit) -> bool {
        let material = match hit.primitive {
            Primitive::Triangle(i) => self.triangle_materials[i as usize],
            Primitive::Sphere(i) => self.sphere_materials[i as usize],
        };
        self.material(material).kind.is_delta()
    }

    /// Turns a backend hit into a surface point with its material and light.
    pub fn surface_hit(&self, ray: &Ray, hit: Hit) -> SurfaceHit {
        let (material, light) = match hit.primitive {
            Primitive::Triangle(i) => (
                self.triangle_materials[i as usize],
                self.lights.triangle_light(i),
            ),
            Primitive::Sphere(i) => (
                self.sphere_materials[i as usize],
                self.lights.sphere_light(i),
            ),
        };
        SurfaceHit {
            hit,
            position: ray.at(hit.t),
            ng: hit.ng.normalize(),
            material,
            light,
        }
    }

    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }

    pub fn material(&self, index: u32) -> &Material {
        &self.materials[index as usize]
    }

    /// The default merge radius: 0.003 x the bounding-sphere diameter (SmallVCM's choice).
    pub fn default_radius(&self) -> f32 {
        self.defaults
            .radius
            .unwrap_or(0.003 * 2.0 * self.bounding_sphere.1)
    }

    /// Finds a camera by name or by index.
    pub fn camera(&self, selector: Option<&str>) -> Result<&CameraDesc, SceneError> {
        let Some(selector) = selector else {
            return self.cameras.first().ok_or(SceneError::NoCamera {
                file: self.source.clone(),
            });
        };
        let by_name = self.cameras.iter().find(|c| c.name == selector);
        let by_index = selector
            .parse::<usize>()
            .ok()
            .and_then(|i| self.cameras.get(i));
        by_name
            .or(by_index)
            .ok_or_else(|| SceneError::UnknownCamera {
                file: self.source.clone(),
                camera: selector.to_string(),
                available: self.cameras.iter().map(|c| c.name.clone()).collect(),
            })
    }
}
