//! Scenes: the TOML scene file with its OBJ/MTL meshes and spheres, validated and turned into
//! geometry for the ray queries, materials, lights and cameras. Both formats (`load` for
//! TOML, `pbrt`) hand what they read to one `builder`; loading returns its warnings with the
//! scene and prints nothing.

use crate::accel::{self, Accel, AccelKind, Geometry, Hit, Primitive, Ray, PACKET};
use crate::bsdf::{Albedo, Bsdf, Bxdf, Material, Normals, TransportMode};
use crate::frame::{Azimuth, Frame};
use crate::light::{EnvMapDesc, Lights, SceneBounds, SkyDesc};
use crate::texture::Texture;
use glam::{Vec2, Vec3};
use groups::MaterialGroups;
use std::path::PathBuf;
use std::sync::Arc;

mod alpha;
mod builder;
mod camera;
mod error;
mod groups;
mod load;
mod mix;
pub mod pbrt;
mod warning;
mod wavefront;

pub use camera::{Camera, CameraDesc, FovAxis};
pub use error::SceneError;
pub use load::{load, load_parts, LoadOptions};
pub use mix::Mix;
pub use warning::Warning;

/// The largest coordinate a scene may have: f32 positions there are still 1/16 apart, so a
/// scene of ordinary size keeps its detail, while beyond it areas, distances and the default
/// merge radius lose their meaning (and their squares overflow).
pub const MAX_COORDINATE: f32 = 1e8;

/// Per-vertex shading data of the triangles: normals and uvs with their own index triples
/// (OBJ indexes them apart from positions). A list is empty when no triangle has that data.
/// And the spheres' parameterisation, which orients anisotropic materials on them.
#[derive(Clone, Debug, Default)]
pub struct MeshShading {
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    /// Per sphere, the unit axis its longitude u turns about (right-handed), so that dp/du is
    /// `pole x n` at the outward normal n: pbrt's object z axis in world space. Empty for
    /// spheres whose u runs as the scene file's texture coordinates (`sphere_uv`: about -y).
    pub sphere_poles: Vec<Vec3>,
    /// Per triangle, indices into `normals`, or [`MeshShading::NONE`] for a flat triangle.
    pub triangle_normals: Vec<[u32; 3]>,
    /// Per triangle, indices into `uvs`, or [`MeshShading::NONE`].
    pub triangle_uvs: Vec<[u32; 3]>,
}

impl MeshShading {
    pub const NONE: [u32; 3] = [u32::MAX; 3];

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        (self.normals.len() + self.sphere_poles.len()) * 12
            + self.uvs.len() * 8
            + (self.triangle_normals.len() + self.triangle_uvs.len()) * 12
    }
}

/// Which textures a material's albedos come from (indices into `Scene::textures`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MaterialTextures {
    pub kd: Option<u32>,
    pub ks: Option<u32>,
    /// Roughness of a microfacet type (the texel's first channel), on both axes unless
    /// `vroughness` gives the v axis's.
    pub roughness: Option<u32>,
    pub vroughness: Option<u32>,
}

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
    /// Unit shading normal, on the side of `ng`; equal to `ng` where the mesh has none.
    pub ns: Vec3,
    /// Texture coordinates (zero where the mesh has none or the material has no texture).
    pub uv: Vec2,
    /// The surface's dp/du (unnormalised, as pbrt-v4's), which orients anisotropic materials
    /// ([`SurfaceHit::azimuth`]); zero where the material is isotropic, which ignores it.
    pub dpdu: Vec3,
    pub material: u32,
    /// Index into `Scene::lights` when the primitive emits.
    pub light: Option<u32>,
}

impl SurfaceHit {
    /// The direction of dp/du about the shading normal, which orients an anisotropic BSDF:
    /// what a light vertex keeps of it, so that every BSDF built here has the same frame.
    pub fn azimuth(&self) -> Azimuth {
        Azimuth::of(self.dpdu, self.ns)
    }

    pub fn normals(&self) -> Normals {
        Normals {
            ng: self.ng,
            ns: self.ns,
        }
    }
}

/// Texture coordinates on a sphere from its outward normal: longitude around y, latitude from
/// the bottom (v = 0) to the top (v = 1).
fn sphere_uv(n: Vec3) -> Vec2 {
    Vec2::new(
        0.5 + n.x.atan2(-n.z) * (0.5 * std::f32::consts::FRAC_1_PI),
        1.0 - n.y.clamp(-1.0, 1.0).acos() * std::f32::consts::FRAC_1_PI,
    )
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
    /// Parallel to `materials`.
    pub material_textures: Vec<MaterialTextures>,
    /// Parallel to `materials` where any is a mix, which hits resolve to one of its two;
    /// empty when none is.
    pub mixes: Vec<Option<Mix>>,
    pub textures: Vec<Arc<Texture>>,
    pub shading: MeshShading,
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
    /// What the load approximated, skipped or replaced, for the caller to show.
    pub warnings: Vec<Warning>,
    /// Parallel to `materials`: what every hit asks of its material, answered once here.
    facts: Vec<MaterialFacts>,
    /// The material of each group of triangles ([`Geometry::group_starts`]: the runs of
    /// triangles with one material), or [`MaterialGroups::MIXED`].
    group_materials: Vec<u32>,
}

/// What each hit asks of its material, from `materials` and `material_textures` when the
/// scene is built.
#[derive(Clone, Copy, Debug)]
struct MaterialFacts {
    /// Any texture: the hit needs its uv, and the albedos come from the texels.
    textured: bool,
    /// Its BSDF needs the surface's tangent.
    anisotropic: bool,
    /// The albedos where it has no texture.
    albedo: Albedo,
    /// It emits: its primitives may be lights.
    emits: bool,
}

/// Everything but the ray-query structure, from which [`Scene::build`] makes a scene; the
/// loader fills it from files and tests fill it by hand.
#[derive(Default)]
pub struct SceneParts {
    pub source: PathBuf,
    pub source_hash: String,
    pub geometry: Geometry,
    pub triangle_materials: Vec<u32>,
    pub sphere_materials: Vec<u32>,
    pub materials: Vec<Material>,
    /// Parallel to `materials`.
    pub material_textures: Vec<MaterialTextures>,
    /// As [`Scene::mixes`].
    pub mixes: Vec<Option<Mix>>,
    /// One decoded copy per file.
    pub textures: Vec<Arc<Texture>>,
    pub shading: MeshShading,
    pub point_and_directional: Vec<crate::light::Light>,
    pub sky: Option<SkyDesc>,
    /// An environment image in place of the gradient sky.
    pub env_map: Option<EnvMapDesc>,
    pub cameras: Vec<CameraDesc>,
    pub defaults: RenderDefaults,
    pub dropped_triangles: usize,
    pub inputs: Vec<PathBuf>,
    pub warnings: Vec<Warning>,
}

impl Scene {
    /// Builds the lights (emissive primitives, the given point and directional lights, the sky)
    /// and the chosen ray-query backend, over the triangles grouped by material (replacing any
    /// group starts `parts` has).
    pub fn build(mut parts: SceneParts, accel_kind: AccelKind) -> Result<Scene, SceneError> {
        let (min, max) = parts.geometry.bounds().ok_or(SceneError::NoGeometry {
            file: parts.source.clone(),
            dropped: parts.dropped_triangles,
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
            parts.env_map,
            SceneBounds::new(min, max),
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
        let groups = MaterialGroups::of(&parts.triangle_materials);
        parts.geometry.group_starts = groups.starts;
        let accel =
            accel::build(accel_kind, &parts.geometry).map_err(|source| SceneError::Accel {
                file: parts.source.clone(),
                source,
            })?;
        let facts = parts
            .materials
            .iter()
            .zip(&parts.material_textures)
            .map(|(m, textures)| MaterialFacts {
                textured: *textures != MaterialTextures::default(),
                anisotropic: m.kind.is_anisotropic(),
                albedo: Albedo::of(&m.kind),
                emits: !m.emission.is_black(),
            })
            .collect();
        Ok(Scene {
            source: parts.source,
            source_hash: parts.source_hash,
            geometry: parts.geometry,
            triangle_materials: parts.triangle_materials,
            sphere_materials: parts.sphere_materials,
            materials: parts.materials,
            material_textures: parts.material_textures,
            mixes: parts.mixes,
            textures: parts.textures,
            shading: parts.shading,
            lights,
            cameras: parts.cameras,
            defaults: parts.defaults,
            accel,
            bounding_sphere: (center, radius),
            dropped_triangles: parts.dropped_triangles,
            inputs: parts.inputs,
            warnings: parts.warnings,
            facts,
            group_materials: groups.materials,
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
        let material = self.resolve(self.primitive_material(hit), hit);
        let textures = self.material_textures[material as usize];
        let kind = &self.material(material).kind;
        if textures.roughness.is_none() && textures.vroughness.is_none() {
            return kind.is_delta();
        }
        // A roughness texture may make the surface smooth at some points only.
        kind.with_albedo(self.albedo(material, self.hit_uv(hit)))
            .is_delta()
    }

    /// The material the scene gives the primitive of `hit` (a mix not yet resolved).
    #[inline]
    fn primitive_material(&self, hit: &Hit) -> u32 {
        match hit.primitive {
            Primitive::Triangle(i) => match self.group_materials.get(hit.group as usize) {
                Some(&m) if m != MaterialGroups::MIXED => m,
                _ => self.triangle_materials[i as usize],
            },
            Primitive::Sphere(i) => self.sphere_materials[i as usize],
        }
    }

    /// The material at the point of `hit` for the material `material` of its primitive: a
    /// mix resolved (module `mix`), any other as it is.
    #[inline]
    pub fn resolve(&self, material: u32, hit: &Hit) -> u32 {
        // Most materials are no mix: answered without a call, on every hit.
        match self.mixes.get(material as usize) {
            Some(Some(_)) => self.resolve_mix(material, hit),
            _ => material,
        }
    }

    /// [`Scene::resolve`] of a mix.
    fn resolve_mix(&self, mut material: u32, hit: &Hit) -> u32 {
        for _ in 0..mix::MAX_NESTING {
            let Some(Some(m)) = self.mixes.get(material as usize) else {
                return material;
            };
            let amount = match m.amount_texture {
                Some(t) => self.textures[t as usize].lookup(self.hit_uv(hit)).average(),
                None => m.amount,
            };
            material = m.choose(amount, hit);
        }
        material
    }

    /// The texture coordinates of a backend hit.
    fn hit_uv(&self, hit: &Hit) -> Vec2 {
        match hit.primitive {
            Primitive::Triangle(i) => self.triangle_uv(i, hit),
            Primitive::Sphere(_) => sphere_uv(hit.ng.normalize()),
        }
    }

    /// Turns a backend hit into a surface point with its material, light, shading normal and
    /// texture coordinates.
    pub fn surface_hit(&self, ray: &Ray, hit: Hit) -> SurfaceHit {
        let ng = hit.ng.normalize();
        // Only textures read uv: an untextured hit skips the lookups (on a large mesh, two
        // cache misses per hit).
        let textured = |material: u32| self.facts[material as usize].textured;
        // Likewise only anisotropic materials read the tangent.
        let anisotropic = |material: u32| self.facts[material as usize].anisotropic;
        let (material, light, ns, uv, dpdu) = match hit.primitive {
            Primitive::Triangle(i) => {
                let base = self.primitive_material(&hit);
                let material = self.resolve(base, &hit);
                let uv = if textured(material) {
                    self.triangle_uv(i, &hit)
                } else {
                    Vec2::ZERO
                };
                let dpdu = if anisotropic(material) {
                    self.triangle_dpdu(i)
                } else {
                    Vec3::ZERO
                };
                // Only emitting materials have lights: the others skip the per-triangle table.
                let light = if self.facts[base as usize].emits {
                    self.lights.triangle_light(i)
                } else {
                    None
                };
                (
                    material,
                    light,
                    self.triangle_shading_normal(i, &hit, ng),
                    uv,
                    dpdu,
                )
            }
            Primitive::Sphere(i) => {
                let material = self.resolve(self.sphere_materials[i as usize], &hit);
                let uv = if textured(material) {
                    sphere_uv(ng)
                } else {
                    Vec2::ZERO
                };
                let dpdu = if anisotropic(material) {
                    self.sphere_dpdu(i, ng)
                } else {
                    Vec3::ZERO
                };
                (material, self.lights.sphere_light(i), ng, uv, dpdu)
            }
        };
        SurfaceHit {
            hit,
            position: ray.at(hit.t),
            ng,
            ns,
            uv,
            dpdu,
            material,
            light,
        }
    }

    /// A sphere's dp/du at the outward normal `n` (zero at its poles), in the direction pbrt-v4's
    /// (-phimax y, phimax x, 0) takes in object space, scaled to the sphere's size.
    fn sphere_dpdu(&self, sphere: u32, n: Vec3) -> Vec3 {
        let pole = self
            .shading
            .sphere_poles
            .get(sphere as usize)
            .copied()
            .unwrap_or(-Vec3::Y);
        let radius = self.geometry.spheres[sphere as usize].radius;
        std::f32::consts::TAU * radius * pole.cross(n)
    }

    /// A triangle's dp/du from its uvs as pbrt-v4's `Triangle::InteractionFromIntersection`
    /// computes it: from pbrt's default uvs (0,0), (1,0), (1,1) where it has none (dp/du =
    /// p1 - p0, up to its sign where the importer turned the triangle), and along the first
    /// axis of pbrt's frame around (p2 - p0) x (p1 - p0) where the uvs are degenerate.
    fn triangle_dpdu(&self, triangle: u32) -> Vec3 {
        let [p0, p1, p2] =
            self.geometry.triangles[triangle as usize].map(|k| self.geometry.positions[k as usize]);
        let [uv0, uv1, uv2] = match self.shading.triangle_uvs.get(triangle as usize) {
            Some(&indices) if indices != MeshShading::NONE => {
                indices.map(|k| self.shading.uvs[k as usize])
            }
            _ => [Vec2::ZERO, Vec2::X, Vec2::ONE],
        };
        let (duv02, duv12) = (uv0 - uv2, uv1 - uv2);
        let (dp02, dp12) = (p0 - p2, p1 - p2);
        let determinant = duv02.x * duv12.y - duv02.y * duv12.x;
        if determinant.abs() >= 1e-9 {
            let dpdu = (duv12.y * dp02 - duv02.y * dp12) / determinant;
            let dpdv = (duv02.x * dp12 - duv12.x * dp02) / determinant;
            if dpdu.cross(dpdv).length_squared() > 0.0 && dpdu.is_finite() {
                return dpdu;
            }
        }
        Frame::from_z((p2 - p0).cross(p1 - p0).normalize_or_zero()).x
    }

    /// The interpolated vertex normal, turned to the side of `ng`; `ng` itself for a flat
    /// triangle or where the interpolation degenerates.
    fn triangle_shading_normal(&self, triangle: u32, hit: &Hit, ng: Vec3) -> Vec3 {
        let Some(&indices) = self.shading.triangle_normals.get(triangle as usize) else {
            return ng;
        };
        if indices == MeshShading::NONE {
            return ng;
        }
        let [a, b, c] = indices.map(|k| self.shading.normals[k as usize]);
        let n = (1.0 - hit.u - hit.v) * a + hit.u * b + hit.v * c;
        let len = n.length();
        if !(len > 0.0 && len.is_finite()) {
            return ng;
        }
        let n = n / len;
        if n.dot(ng) < 0.0 {
            -n
        } else {
            n
        }
    }

    fn triangle_uv(&self, triangle: u32, hit: &Hit) -> Vec2 {
        match self.shading.triangle_uvs.get(triangle as usize) {
            Some(&indices) if indices != MeshShading::NONE => {
                let [a, b, c] = indices.map(|k| self.shading.uvs[k as usize]);
                (1.0 - hit.u - hit.v) * a + hit.u * b + hit.v * c
            }
            _ => Vec2::ZERO,
        }
    }

    /// The material's albedos at `uv`: textures where it has them (clamped so that kd + ks
    /// <= 1 per channel, which Phong needs to conserve energy), its constants elsewhere.
    #[inline]
    pub fn albedo(&self, material: u32, uv: Vec2) -> Albedo {
        let facts = &self.facts[material as usize];
        if !facts.textured {
            return facts.albedo;
        }
        let kind = &self.material(material).kind;
        let textures = self.material_textures[material as usize];
        let texel = |t: Option<u32>| t.map(|t| self.textures[t as usize].lookup(uv));
        Albedo {
            roughness: texel(textures.roughness).map(|c| c.r),
            vroughness: texel(textures.vroughness).map(|c| c.r),
            ..kind.textured_albedo(texel(textures.kd), texel(textures.ks))
        }
    }

    /// The BSDF of `material` at a surface point with `normals` and texture coordinates `uv`,
    /// seen from `wo`, on a surface without a tangent ([`Scene::oriented_bsdf`] with one).
    pub fn bsdf(
        &self,
        material: u32,
        normals: Normals,
        uv: Vec2,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<Bsdf<'_>> {
        let kind = &self.material(material).kind;
        Bsdf::shaded(kind, self.albedo(material, uv), normals, wo, mode)
    }

    /// [`Scene::bsdf`] on a surface whose tangent lies at `azimuth` about the shading normal,
    /// which orients anisotropic materials ([`Bsdf::oriented`]).
    #[inline]
    pub fn oriented_bsdf(
        &self,
        material: u32,
        normals: Normals,
        azimuth: Azimuth,
        uv: Vec2,
        wo: Vec3,
        mode: TransportMode,
    ) -> Option<Bsdf<'_>> {
        let kind = &self.material(material).kind;
        Bsdf::oriented(kind, self.albedo(material, uv), normals, azimuth, wo, mode)
    }

    /// The BSDF at a hit, oriented by its tangent.
    #[inline]
    pub fn bsdf_at(&self, hit: &SurfaceHit, wo: Vec3, mode: TransportMode) -> Option<Bsdf<'_>> {
        self.oriented_bsdf(hit.material, hit.normals(), hit.azimuth(), hit.uv, wo, mode)
    }

    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }

    pub fn material(&self, index: u32) -> &Material {
        &self.materials[index as usize]
    }

    /// The default merge radius. A radius set in the scene file wins. Otherwise 0.003 x the
    /// bounding-sphere diameter (twice SmallVCM's 0.003 x the scene-sphere radius; pass
    /// `--radius` to match SmallVCM), unless that is more than `VIEW_RULE_FACTOR` times the
    /// same fraction of what `camera` sees: the diagonal of its view at the median distance
    /// of a grid of primary rays. Then the view's value: a room inside a huge ground plane
    /// would otherwise merge at a radius set by the plane, tens of times the room's scale.
    /// The test compares angles, not pixels, so the default does not depend on the
    /// resolution, and scenes whose bounds are what the camera looks at keep the first rule.
    pub fn default_radius(&self, camera: &Camera) -> f32 {
        const FRACTION: f32 = 0.003;
        // Primary rays per axis traced to see what the camera sees.
        const VIEW_GRID: usize = 16;
        // The shipped scenes are within 2.8 of the view's value; a room inside a plane 20
        // times its size is 20 times beyond it.
        const VIEW_RULE_FACTOR: f32 = 4.0;
        if let Some(r) = self.defaults.radius {
            return r;
        }
        let bounding = FRACTION * 2.0 * self.bounding_sphere.1;
        let (w, h) = (camera.width as f32, camera.height as f32);
        let on_plane = |x: f32, y: f32| {
            let dir = camera.generate_ray(x, y).dir;
            dir / dir.dot(camera.forward())
        };
        // The view's diagonal on the plane at distance 1 along the viewing direction.
        let diagonal = (on_plane(0.0, 0.0) - on_plane(w, h)).length();
        let mut distances: Vec<f32> = (0..VIEW_GRID * VIEW_GRID)
            .filter_map(|i| {
                let x = (i % VIEW_GRID) as f32 + 0.5;
                let y = (i / VIEW_GRID) as f32 + 0.5;
                let ray = camera.generate_ray(x * w / VIEW_GRID as f32, y * h / VIEW_GRID as f32);
                let hit = self.intersect(&ray)?;
                // Along the viewing direction, as the diagonal is measured.
                let depth = (hit.position - ray.origin).dot(camera.forward());
                (depth.is_finite() && depth > 0.0).then_some(depth)
            })
            .collect();
        // A view that is mostly sky says little about the scene's scale.
        if distances.len() < VIEW_GRID * VIEW_GRID / 4 {
            return bounding;
        }
        let middle = distances.len() / 2;
        let (_, &mut median, _) = distances.select_nth_unstable_by(middle, f32::total_cmp);
        let view = FRACTION * diagonal * median;
        if view > 0.0 && bounding > VIEW_RULE_FACTOR * view {
            view
        } else {
            bounding
        }
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
