//! The TOML scene file (DESIGN.md "Scene file") and its OBJ/MTL meshes.
//!
//! Everything is validated before anything is built: each problem is one [`SceneError`] naming
//! the file and the entry. OBJ `vn` normals become shading normals (unless turned off per mesh
//! or for the whole load), `vt` texture coordinates; MTL `map_Kd` / `map_Ks` and the tables'
//! `texture` / `ks_texture` name image textures; a mesh's `alpha` (a number or an image) cuts it
//! out. Materials, images, the scene hash and the
//! warnings go through the [`Builder`] the pbrt importer uses too.

use super::builder::{Builder, Contents, MaterialDesc, Origin};
use super::{alpha, wavefront};
use super::{
    CameraDesc, FovAxis, MaterialTextures, MeshShading, Mix, RenderDefaults, Scene, SceneError,
    SceneParts, Warning, MAX_COORDINATE,
};
use crate::accel::{AccelKind, Alpha, Geometry, Sphere};
use crate::bsdf::{BsdfError, Material, MaterialKind, ParamKind, ParamValue, Params};
use crate::color::Rgb;
use crate::files::{self, Kind};
use crate::light::{EnvMapDesc, SceneBounds, SkyDesc};
use crate::light::{Light, SpotCone, SpotError};
use glam::{Mat3, Vec2, Vec3};
use rayon::prelude::*;
use serde::Deserialize;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// The camera's vertical field of view, in degrees: narrower makes the image plane so far
/// that rays lose their direction in f32, wider so near that pixels lose their size.
const MIN_FOV: f32 = 0.01;
const MAX_FOV: f32 = 179.0;

#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    pub accel: AccelKind,
    /// Scale down materials that would create energy (Phong's kd + ks > 1, in either format)
    /// with a warning instead of refusing them, and go on past missing files with a warning
    /// (a material's constant colour for its texture; in pbrt files also meshes and skies).
    pub lenient: bool,
    /// Use the meshes' vertex normals as shading normals (each mesh can still turn them off);
    /// `false` renders every triangle flat, as if the files had none.
    pub shading_normals: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default)]
    render: RenderTable,
    #[serde(default)]
    camera: Vec<CameraTable>,
    #[serde(default)]
    mesh: Vec<MeshTable>,
    #[serde(default)]
    sphere: Vec<SphereTable>,
    #[serde(default)]
    material: BTreeMap<String, MaterialTable>,
    #[serde(default)]
    light: Vec<LightTable>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderTable {
    resolution: Option<[u32; 2]>,
    max_path_length: Option<u32>,
    radius: Option<f32>,
    sky: Option<SkyTable>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SkyTable {
    horizon: Option<[f32; 3]>,
    zenith: Option<[f32; 3]>,
    up: Option<[f32; 3]>,
    /// An equirectangular environment image instead of the gradient.
    image: Option<PathBuf>,
    scale: Option<f32>,
    rotate_deg: Option<[f32; 3]>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraTable {
    name: Option<String>,
    position: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "default_up")]
    up: [f32; 3],
    fov: f32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshTable {
    file: PathBuf,
    transform: Option<TransformTable>,
    material: Option<String>,
    #[serde(default = "yes")]
    shading_normals: bool,
    alpha: Option<AlphaEntry>,
}

/// A mesh's alpha: a constant, or an image read at the mesh's uvs.
#[derive(Deserialize)]
#[serde(untagged)]
enum AlphaEntry {
    Constant(f32),
    Image(PathBuf),
}

fn yes() -> bool {
    true
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TransformTable {
    #[serde(default = "one")]
    scale: f32,
    #[serde(default)]
    rotate_deg: [f32; 3],
    #[serde(default)]
    translate: [f32; 3],
}

fn one() -> f32 {
    1.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereTable {
    center: [f32; 3],
    radius: f32,
    material: String,
}

/// Unknown keys are refused by [`Loader::type_params`] (serde cannot deny them beside a
/// flattened map).
#[derive(Deserialize)]
struct MaterialTable {
    #[serde(rename = "type")]
    kind: Option<String>,
    kd: Option<[f32; 3]>,
    ks: Option<[f32; 3]>,
    exponent: Option<f32>,
    ior: Option<f32>,
    emission: Option<[f32; 3]>,
    /// Emission on both sides of the surface.
    two_sided: Option<bool>,
    /// Image for kd, relative to the scene file.
    texture: Option<PathBuf>,
    /// Image for Phong's ks.
    ks_texture: Option<PathBuf>,
    /// A dielectric's index (a number), or a conductor's per channel.
    eta: Option<NumberOrColor>,
    /// A conductor's absorption per channel.
    k: Option<[f32; 3]>,
    /// A conductor's normal-incidence reflectance, in place of eta and k.
    reflectance: Option<[f32; 3]>,
    /// Microfacet roughness on both axes, or on each.
    roughness: Option<f32>,
    uroughness: Option<f32>,
    vroughness: Option<f32>,
    /// Roughness is remapped to alpha (pbrt-v4's default) unless false.
    remaproughness: Option<bool>,
    /// Image for the roughness (its first channel), relative to the scene file.
    roughness_texture: Option<PathBuf>,
    /// Images for the roughness of one axis each, in place of `roughness_texture`'s there.
    uroughness_texture: Option<PathBuf>,
    vroughness_texture: Option<PathBuf>,
    /// A mix's two materials, by name.
    materials: Option<[String; 2]>,
    /// A mix's probability of its second material.
    amount: Option<f32>,
    /// Image whose mean channel gives a mix's amount per point, relative to the scene file.
    amount_texture: Option<PathBuf>,
    /// The parameters of the other types, by the names of their specs.
    #[serde(flatten)]
    params: BTreeMap<String, toml::Value>,
}

/// A value that is one number or a colour.
#[derive(Deserialize, Clone, Copy)]
#[serde(untagged)]
enum NumberOrColor {
    Number(f32),
    Color([f32; 3]),
}

/// The type name of a material that is one of two others per point.
const MIX: &str = "mix";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightTable {
    #[serde(rename = "type")]
    kind: String,
    position: Option<[f32; 3]>,
    intensity: Option<[f32; 3]>,
    direction: Option<[f32; 3]>,
    irradiance: Option<[f32; 3]>,
    /// A spot light's aim, instead of its `direction`.
    look_at: Option<[f32; 3]>,
    /// Degrees off the axis where a spot light's falloff ends, and its width.
    cone_angle: Option<f32>,
    cone_delta: Option<f32>,
}

/// Loads, validates and builds the scene at `path`.
pub fn load(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let parts = load_parts(path, options)?;
    Scene::build(parts, options.accel)
}

/// Reads and validates the scene file and its meshes, without building the ray queries: a
/// pbrt-v4 file by its extension (`.pbrt`), TOML otherwise.
pub fn load_parts(path: &Path, options: &LoadOptions) -> Result<SceneParts, SceneError> {
    if super::pbrt::is_pbrt(path) {
        return super::pbrt::load_parts(path, options);
    }
    let text = files::read_text(path, Kind::Scene)?;
    let parse_error = |e: toml::de::Error| SceneError::Parse {
        file: path.to_path_buf(),
        // TOML's messages quote the offending line, which may be any length.
        message: files::shorten_lines(&e.to_string(), 200),
    };
    check_array_lengths(path, "", &text.parse::<toml::Table>().map_err(parse_error)?)?;
    let file: SceneFile = toml::from_str(&text).map_err(parse_error)?;
    let mut loader = Loader {
        path: path.to_path_buf(),
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        shading_normals: options.shading_normals,
        builder: Builder::new(path, options.lenient),
        shading: MeshShading::default(),
        by_name: HashMap::new(),
        geometry: Geometry::default(),
        triangle_materials: Vec::new(),
        sphere_materials: Vec::new(),
        dropped_triangles: 0,
    };
    loader.builder.input(path, text.as_bytes());
    loader.build(file)
}

/// The length of every fixed-size array of the scene file, by key.
const ARRAY_LENGTHS: &[(&str, usize)] = &[
    ("resolution", 2),
    ("position", 3),
    ("look_at", 3),
    ("up", 3),
    ("center", 3),
    ("rotate_deg", 3),
    ("translate", 3),
    ("kd", 3),
    ("ks", 3),
    ("emission", 3),
    ("intensity", 3),
    ("direction", 3),
    ("irradiance", 3),
    ("horizon", 3),
    ("zenith", 3),
];

/// Arrays of the wrong length are refused: the TOML reader would fill `[f32; 3]` from the
/// first three numbers of a longer array and drop the rest unseen.
fn check_array_lengths(path: &Path, at: &str, table: &toml::Table) -> Result<(), SceneError> {
    for (key, value) in table {
        let entry = if at.is_empty() {
            key.clone()
        } else {
            format!("{at}.{key}")
        };
        match value {
            toml::Value::Table(t) => check_array_lengths(path, &entry, t)?,
            toml::Value::Array(items) => {
                if let Some(&(_, n)) = ARRAY_LENGTHS.iter().find(|(k, _)| k == key) {
                    if items.len() != n {
                        return Err(SceneError::Invalid {
                            file: path.to_path_buf(),
                            entry,
                            message: format!("expected {n} numbers, found {}", items.len()),
                        });
                    }
                }
                for (i, item) in items.iter().enumerate() {
                    if let toml::Value::Table(t) = item {
                        check_array_lengths(path, &format!("{entry}[{i}]"), t)?;
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// A mesh file as read and parsed, before its contents join the scene.
struct ReadMesh {
    path: PathBuf,
    bytes: Vec<u8>,
    obj: wavefront::Obj,
}

/// Reads and parses the file of `mesh`, the scene file's entry `mesh[i]` (the scene file is
/// `scene_path`, in the folder `dir`).
fn read_mesh(
    scene_path: &Path,
    dir: &Path,
    i: usize,
    mesh: &MeshTable,
) -> Result<ReadMesh, SceneError> {
    let entry = format!("mesh[{i}]");
    let invalid = |message: String| SceneError::Invalid {
        file: scene_path.to_path_buf(),
        entry: format!("{entry}.file"),
        message,
    };
    if mesh.file.as_os_str().is_empty() {
        return Err(invalid("the path is empty".into()));
    }
    let path = dir.join(&mesh.file);
    // Named with the scene's entry: the path may be a typo the mesh file cannot tell.
    let bytes = files::read(&path, Kind::Obj).map_err(|e| invalid(e.to_string()))?;
    let load_options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let obj = wavefront::load_obj(&path, &bytes, &load_options, &entry)?;
    Ok(ReadMesh { path, bytes, obj })
}

struct Loader {
    path: PathBuf,
    dir: PathBuf,
    shading_normals: bool,
    builder: Builder,
    shading: MeshShading,
    by_name: HashMap<String, u32>,
    geometry: Geometry,
    triangle_materials: Vec<u32>,
    sphere_materials: Vec<u32>,
    dropped_triangles: usize,
}

impl Loader {
    fn invalid(&self, entry: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            file: self.path.clone(),
            entry: entry.into(),
            message: message.into(),
        }
    }

    fn vec3(&self, entry: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
        if v.iter().all(|x| x.is_finite()) {
            Ok(Vec3::from_array(v))
        } else {
            Err(self.invalid(entry, format!("{v:?} is not a finite number triple")))
        }
    }

    fn color(&self, entry: &str, v: [f32; 3]) -> Result<Rgb, SceneError> {
        let c = self.vec3(entry, v)?;
        if c.min_element() < 0.0 {
            return Err(self.invalid(entry, format!("{v:?} has a negative component")));
        }
        Ok(Rgb::from_array(v))
    }

    fn positive(&self, entry: &str, x: f32) -> Result<f32, SceneError> {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(self.invalid(entry, format!("{x} must be a positive finite number")))
        }
    }

    fn non_negative(&self, entry: &str, x: f32) -> Result<f32, SceneError> {
        if x.is_finite() && x >= 0.0 {
            Ok(x)
        } else {
            Err(self.invalid(entry, format!("{x} must be a non-negative finite number")))
        }
    }

    /// A position: finite and within +-[`MAX_COORDINATE`].
    fn point(&self, entry: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
        let p = self.vec3(entry, v)?;
        if p.abs().max_element() > MAX_COORDINATE {
            return Err(self.invalid(
                entry,
                format!(
                    "{v:?} lies beyond +-{MAX_COORDINATE:e}, where f32 positions lose their precision"
                ),
            ));
        }
        Ok(p)
    }

    /// A reflectance: each component in [0, 1] (more would create energy).
    fn albedo(&self, entry: &str, v: [f32; 3]) -> Result<Rgb, SceneError> {
        let c = self.color(entry, v)?;
        if c.max_component() > 1.0 {
            return Err(self.invalid(
                entry,
                format!("{v:?} has a component above 1 and would create energy"),
            ));
        }
        Ok(c)
    }

    fn build(mut self, file: SceneFile) -> Result<SceneParts, SceneError> {
        let defaults = self.render_defaults(&file.render)?;
        let (sky, env_map) = match &file.render.sky {
            Some(s) => self.sky(s)?,
            None => (None, None),
        };
        let cameras = file
            .camera
            .iter()
            .enumerate()
            .map(|(i, c)| self.camera(i, c))
            .collect::<Result<Vec<_>, _>>()?;
        if cameras.is_empty() {
            return Err(SceneError::NoCamera {
                file: self.path.clone(),
            });
        }
        // Scene-file materials first, so meshes and spheres can refer to them; MTL materials of
        // the same name are overridden by them.
        for (name, table) in &file.material {
            if table.kind.as_deref() == Some(MIX) {
                continue;
            }
            let material = self.material_from_table(name, table, None)?;
            let entry = format!("material.{name}");
            let origin = Origin {
                file: self.path.clone(),
                line: None,
                entry: entry.clone(),
            };
            let index = self.add_material(&origin, material)?;
            let dir = self.dir.clone();
            let path = self.path.clone();
            let kd = self.texture(&path, &format!("{entry}.texture"), &dir, &table.texture)?;
            let ks = self.texture(
                &path,
                &format!("{entry}.ks_texture"),
                &dir,
                &table.ks_texture,
            )?;
            let (roughness, vroughness) = self.roughness_textures(index, &entry, table)?;
            self.builder.set_textures(
                index,
                MaterialTextures {
                    kd,
                    ks,
                    roughness,
                    vroughness,
                },
            );
        }
        self.mixes(&file.material)?;
        // Reading and parsing the mesh files is most of a large scene's load, and each needs
        // nothing from the others: a batch of them at a time in parallel (so that no more are
        // held at once), their contents then joining the scene in the file's order.
        let batch = 2 * rayon::current_num_threads();
        for (b, meshes) in file.mesh.chunks(batch).enumerate() {
            let read: Vec<Result<ReadMesh, SceneError>> = meshes
                .par_iter()
                .enumerate()
                .map(|(k, mesh)| read_mesh(&self.path, &self.dir, b * batch + k, mesh))
                .collect();
            for (k, (mesh, read)) in meshes.iter().zip(read).enumerate() {
                self.mesh(b * batch + k, mesh, read?)?;
            }
        }
        for (i, s) in file.sphere.iter().enumerate() {
            let entry = format!("sphere[{i}]");
            let center = self.point(&format!("{entry}.center"), s.center)?;
            let radius = self.positive(&format!("{entry}.radius"), s.radius)?;
            self.point(&format!("{entry}.radius"), [radius; 3])?;
            let material = self.material_index(&format!("{entry}.material"), &s.material)?;
            self.geometry.spheres.push(Sphere { center, radius });
            self.sphere_materials.push(material);
        }
        let lights = file
            .light
            .iter()
            .enumerate()
            .map(|(i, l)| self.light(i, l))
            .collect::<Result<Vec<_>, _>>()?;
        self.builder
            .check_geometry(&self.geometry, self.dropped_triangles)?;
        let triangles = self.geometry.triangles.len();
        for list in [
            &mut self.shading.triangle_normals,
            &mut self.shading.triangle_uvs,
        ] {
            if !list.is_empty() {
                list.resize(triangles, MeshShading::NONE);
            }
        }
        Ok(self.builder.finish(Contents {
            geometry: self.geometry,
            triangle_materials: self.triangle_materials,
            sphere_materials: self.sphere_materials,
            shading: self.shading,
            lights,
            sky,
            env_map,
            cameras,
            defaults,
            dropped_triangles: self.dropped_triangles,
        }))
    }

    fn render_defaults(&self, r: &RenderTable) -> Result<RenderDefaults, SceneError> {
        let mut d = RenderDefaults::default();
        if let Some(res) = r.resolution {
            if res[0] == 0 || res[1] == 0 {
                return Err(self.invalid("render.resolution", format!("{res:?} has a zero side")));
            }
            d.resolution = res;
        }
        if let Some(n) = r.max_path_length {
            d.max_path_length = n;
        }
        if let Some(radius) = r.radius {
            d.radius = Some(self.positive("render.radius", radius)?);
        }
        Ok(d)
    }

    /// The `[render] sky` table: a gradient (`horizon`, `zenith`, `up`) or an environment image
    /// (`image`, `scale`, `rotate_deg`), not both.
    fn sky(&mut self, s: &SkyTable) -> Result<(Option<SkyDesc>, Option<EnvMapDesc>), SceneError> {
        let entry = "render.sky";
        let Some(image) = &s.image else {
            if s.scale.is_some() || s.rotate_deg.is_some() {
                return Err(self.invalid(entry, "`scale` and `rotate_deg` need an `image`"));
            }
            let (Some(horizon), Some(zenith)) = (s.horizon, s.zenith) else {
                return Err(self.invalid(
                    entry,
                    "a sky needs `horizon` and `zenith` (a gradient) or `image`",
                ));
            };
            let sky = SkyDesc {
                horizon: self.color("render.sky.horizon", horizon)?,
                zenith: self.color("render.sky.zenith", zenith)?,
                up: self.direction("render.sky.up", s.up.unwrap_or_else(default_up))?,
            };
            return Ok((Some(sky), None));
        };
        if s.horizon.is_some() || s.zenith.is_some() || s.up.is_some() {
            return Err(self.invalid(
                entry,
                "a sky is a gradient (horizon, zenith, up) or an image, not both",
            ));
        }
        let scale = s.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(self.invalid(
                "render.sky.scale",
                format!("{scale} must be a non-negative finite number"),
            ));
        }
        let r = self.vec3("render.sky.rotate_deg", s.rotate_deg.unwrap_or_default())?;
        let path = self.dir.join(image);
        let image = self
            .builder
            .image(&path)
            .map_err(|message| self.invalid("render.sky.image", message))?;
        Ok((
            None,
            Some(EnvMapDesc {
                image,
                scale,
                rotation: rotation_deg(r),
            }),
        ))
    }

    /// The texture named by `name` (relative to `dir`) for the entry `entry` of `file`: an error
    /// naming both when it cannot be read, or with `--lenient` a warning and no texture (the
    /// material keeps its constant colour).
    fn texture(
        &mut self,
        file: &Path,
        entry: &str,
        dir: &Path,
        name: &Option<PathBuf>,
    ) -> Result<Option<u32>, SceneError> {
        let Some(name) = name else {
            return Ok(None);
        };
        let path = dir.join(name);
        match self.builder.image(&path) {
            Ok(image) => Ok(Some(self.builder.texture(&path, &image, Rgb::WHITE))),
            Err(message) if self.builder.lenient() => {
                self.builder.warn(Warning::entry(
                    file,
                    entry,
                    format!("{message}; using the material's constant colour"),
                ));
                Ok(None)
            }
            Err(message) => Err(SceneError::Invalid {
                file: file.to_path_buf(),
                entry: entry.to_string(),
                message,
            }),
        }
    }

    /// The roughness textures of the material `index` from `table`, as [`MaterialTextures`]
    /// takes them: the u axis's (both axes' where the second is `None`), and the v axis's. An
    /// axis without an image of its own, beside one with, keeps its number as a one-texel
    /// texture.
    fn roughness_textures(
        &mut self,
        index: u32,
        entry: &str,
        t: &MaterialTable,
    ) -> Result<(Option<u32>, Option<u32>), SceneError> {
        let (path, dir) = (self.path.clone(), self.dir.clone());
        let image = |s: &mut Self, key: &str, name: &Option<PathBuf>| {
            s.texture(&path, &format!("{entry}.{key}"), &dir, name)
        };
        let both = image(self, "roughness_texture", &t.roughness_texture)?;
        let u = image(self, "uroughness_texture", &t.uroughness_texture)?.or(both);
        let v = image(self, "vroughness_texture", &t.vroughness_texture)?.or(both);
        Ok(match (u, v) {
            (u, v) if u == v => (u, None),
            (Some(u), None) => {
                let kind = &self.builder.material_at(index).kind;
                let params = kind.params();
                let v = ["vroughness", "conductor.vroughness"]
                    .iter()
                    .find_map(|n| params.number(n))
                    .unwrap_or(0.0);
                (Some(u), Some(self.builder.constant_texture(Rgb::splat(v))))
            }
            (u, v) => (u, v),
        })
    }

    fn direction(&self, entry: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
        let d = self.vec3(entry, v)?;
        if d.length_squared() == 0.0 {
            return Err(self.invalid(entry, "a direction cannot be zero"));
        }
        Ok(d.normalize())
    }

    fn camera(&self, i: usize, c: &CameraTable) -> Result<CameraDesc, SceneError> {
        let name = c.name.clone().unwrap_or_else(|| i.to_string());
        let entry = format!("camera[{i}] ({name})");
        let position = self.point(&format!("{entry}.position"), c.position)?;
        let look_at = self.point(&format!("{entry}.look_at"), c.look_at)?;
        let up = self.direction(&format!("{entry}.up"), c.up)?;
        if !(MIN_FOV..=MAX_FOV).contains(&c.fov) {
            return Err(self.invalid(
                format!("{entry}.fov"),
                format!("{} is not in [{MIN_FOV}, {MAX_FOV}] degrees", c.fov),
            ));
        }
        let forward = look_at - position;
        if forward.length_squared() == 0.0 {
            return Err(self.invalid(&entry, "position and look_at coincide"));
        }
        if forward.normalize().cross(up).length() < 1e-4 {
            return Err(self.invalid(&entry, "the camera looks along its up vector"));
        }
        Ok(CameraDesc {
            name,
            position,
            look_at,
            up,
            fov_deg: c.fov,
            fov_axis: FovAxis::Vertical,
            mirrored: false,
        })
    }

    /// Adds the mixes among `tables`, each after the materials it names (a mix may name a
    /// mix).
    fn mixes(&mut self, tables: &BTreeMap<String, MaterialTable>) -> Result<(), SceneError> {
        let mut pending: Vec<(&String, &MaterialTable)> = tables
            .iter()
            .filter(|(_, t)| t.kind.as_deref() == Some(MIX))
            .collect();
        while !pending.is_empty() {
            let ready = |t: &MaterialTable| {
                t.materials
                    .as_ref()
                    .is_none_or(|m| m.iter().all(|n| self.by_name.contains_key(n)))
            };
            // None ready: name the first one's missing material (unknown, or a cycle).
            let at = pending.iter().position(|(_, t)| ready(t)).unwrap_or(0);
            let (name, t) = pending.remove(at);
            let entry = format!("material.{name}");
            let names = t.materials.as_ref().ok_or_else(|| {
                self.invalid(&entry, "a mix needs materials = [\"first\", \"second\"]")
            })?;
            let materials = [
                self.material_index(&format!("{entry}.materials"), &names[0])?,
                self.material_index(&format!("{entry}.materials"), &names[1])?,
            ];
            let amount = t.amount.unwrap_or(0.5);
            if !(0.0..=1.0).contains(&amount) {
                return Err(self.invalid(
                    format!("{entry}.amount"),
                    format!("{amount} is not in [0, 1]"),
                ));
            }
            if let Some(key) = t.params.keys().next() {
                return Err(self.invalid(format!("{entry}.{key}"), "unknown key for a mix"));
            }
            let (path, dir) = (self.path.clone(), self.dir.clone());
            let amount_texture = self.texture(
                &path,
                &format!("{entry}.amount_texture"),
                &dir,
                &t.amount_texture,
            )?;
            let mix = Mix {
                materials,
                amount,
                amount_texture,
            };
            let index = self.builder.mix(name.clone(), mix);
            self.by_name.insert(name.clone(), index);
        }
        Ok(())
    }

    /// The parameters a table gives by its types' own names (`reflectance`, `roughness`, ...):
    /// numbers, booleans (as 0 or 1) and colour triples, each a parameter of `type_name`.
    fn type_params(
        &self,
        entry: &str,
        type_name: &str,
        t: &MaterialTable,
        params: &mut Params,
    ) -> Result<(), SceneError> {
        let specs = MaterialKind::param_specs(type_name)
            .map_err(|e| self.invalid(format!("{entry}.type"), e.to_string()))?;
        for (key, value) in &t.params {
            let here = format!("{entry}.{key}");
            let Some(spec) = specs.iter().find(|s| s.name == key) else {
                let known: Vec<&str> = specs.iter().map(|s| s.name).collect();
                return Err(self.invalid(
                    here,
                    format!("unknown key for type {type_name} (its parameters: {known:?})"),
                ));
            };
            let number = |x: f64| -> Result<f32, SceneError> {
                let x = x as f32;
                if x.is_finite() {
                    Ok(x)
                } else {
                    Err(self.invalid(&here, format!("{x} is not a finite number")))
                }
            };
            let value = match value {
                toml::Value::Float(x) => ParamValue::Number(number(*x)?),
                toml::Value::Integer(x) => ParamValue::Number(number(*x as f64)?),
                toml::Value::Boolean(b) => ParamValue::Number(if *b { 1.0 } else { 0.0 }),
                toml::Value::Array(a) if a.len() == 3 && spec.kind == ParamKind::Color => {
                    let mut c = [0.0f32; 3];
                    for (slot, v) in c.iter_mut().zip(a) {
                        *slot = match v {
                            toml::Value::Float(x) => number(*x)?,
                            toml::Value::Integer(x) => number(*x as f64)?,
                            _ => return Err(self.invalid(&here, "expected three numbers")),
                        };
                    }
                    ParamValue::Color(self.color(&here, c)?)
                }
                _ => {
                    let expected = match spec.kind {
                        ParamKind::Color => "a number or three numbers",
                        ParamKind::Number => "a number",
                    };
                    return Err(self.invalid(here, format!("expected {expected}")));
                }
            };
            params.set(key, value);
        }
        Ok(())
    }

    /// Adds a material through the builder, findable by its name.
    fn add_material(&mut self, origin: &Origin, material: MaterialDesc) -> Result<u32, SceneError> {
        let name = material.name.clone();
        let index = self.builder.material(origin, material)?;
        self.by_name.insert(name, index);
        Ok(index)
    }

    fn material_index(&self, entry: &str, name: &str) -> Result<u32, SceneError> {
        self.by_name.get(name).copied().ok_or_else(|| {
            let mut known: Vec<_> = self.by_name.keys().cloned().collect();
            known.sort();
            self.invalid(
                entry,
                format!("unknown material '{name}' (known: {known:?})"),
            )
        })
    }

    /// A material from a `[material.NAME]` table, on top of `base` (an MTL material of the
    /// same name) when there is one.
    fn material_from_table(
        &self,
        name: &str,
        t: &MaterialTable,
        base: Option<&Material>,
    ) -> Result<MaterialDesc, SceneError> {
        let entry = format!("material.{name}");
        // Over a base, what the base's type lacks is black (its exponent 1, its ior 1.5);
        // without one, each type's own defaults.
        let mut params = match base {
            Some(m) => {
                let mut p = Params::new()
                    .with_color("kd", Rgb::BLACK)
                    .with_color("ks", Rgb::BLACK)
                    .with_number("exponent", 1.0)
                    .with_number("ior", 1.5);
                p.overlay(&m.kind.params());
                p
            }
            None => Params::new(),
        };
        if let Some(v) = t.kd {
            params = params.with_color("kd", self.albedo(&format!("{entry}.kd"), v)?);
        }
        if let Some(v) = t.ks {
            params = params.with_color("ks", self.albedo(&format!("{entry}.ks"), v)?);
        }
        if let Some(x) = t.exponent {
            params =
                params.with_number("exponent", self.positive(&format!("{entry}.exponent"), x)?);
        }
        if let Some(x) = t.ior {
            params = params.with_number("ior", self.positive(&format!("{entry}.ior"), x)?);
        }
        match t.eta {
            Some(NumberOrColor::Number(x)) => {
                params = params.with_number("eta", self.positive(&format!("{entry}.eta"), x)?);
            }
            Some(NumberOrColor::Color(v)) => {
                params = params.with_color("eta", self.color(&format!("{entry}.eta"), v)?);
            }
            None => {}
        }
        for (key, value) in [("k", t.k), ("reflectance", t.reflectance)] {
            if let Some(v) = value {
                params = params.with_color(key, self.color(&format!("{entry}.{key}"), v)?);
            }
        }
        for (key, value) in [
            ("roughness", t.roughness),
            ("uroughness", t.uroughness),
            ("vroughness", t.vroughness),
        ] {
            if let Some(x) = value {
                params = params.with_number(key, self.non_negative(&format!("{entry}.{key}"), x)?);
            }
        }
        if let Some(remap) = t.remaproughness {
            params = params.with_number("remaproughness", if remap { 1.0 } else { 0.0 });
        }
        let emission = match t.emission {
            Some(v) => self.color(&format!("{entry}.emission"), v)?,
            None => base.map_or(Rgb::BLACK, |m| m.emission),
        };
        let type_name = match (&t.kind, base) {
            (Some(k), _) => k.as_str(),
            (None, Some(m)) => m.kind.type_name(),
            (None, None) => "lambert",
        };
        let Some(&type_name) = MaterialKind::TYPE_NAMES.iter().find(|&&t| t == type_name) else {
            let e = BsdfError::UnknownType {
                name: type_name.to_string(),
            };
            return Err(self.invalid(format!("{entry}.type"), e.to_string()));
        };
        if t.materials.is_some() || t.amount.is_some() || t.amount_texture.is_some() {
            return Err(self.invalid(
                &entry,
                "'materials', 'amount' and 'amount_texture' belong to type = \"mix\"",
            ));
        }
        self.type_params(&entry, type_name, t, &mut params)?;
        Ok(MaterialDesc {
            emission,
            two_sided: t.two_sided.or(base.map(|m| m.two_sided)).unwrap_or(false),
            ..MaterialDesc::new(name, type_name, params)
        })
    }

    /// Adds a mesh read by [`read_mesh`] to the scene.
    fn mesh(&mut self, i: usize, mesh: &MeshTable, read: ReadMesh) -> Result<(), SceneError> {
        let entry = format!("mesh[{i}]");
        let ReadMesh {
            path: obj_path,
            bytes,
            obj,
        } = read;
        self.builder.input(&obj_path, &bytes);
        drop(bytes);
        for mtl in &obj.mtl_files {
            self.builder.input(&mtl.path, &mtl.bytes);
            for w in unknown_mtl_statements(&mtl.path, &String::from_utf8_lossy(&mtl.bytes)) {
                self.builder.warn(w);
            }
        }
        if mesh.material.is_none() {
            let scene_materials: Vec<String> = self.by_name.keys().cloned().collect();
            for w in wavefront::unknown_usemtl(&obj_path, &obj, &scene_materials) {
                self.builder.warn(w);
            }
        }
        // Texture files are named relative to the MTL file that names them.
        let mtl_file = obj
            .mtl_files
            .first()
            .map_or_else(|| obj_path.clone(), |mtl| mtl.path.clone());
        let mut indices = Vec::with_capacity(obj.materials.len());
        for m in &obj.materials {
            indices.push(self.mtl_material(&obj_path, &mtl_file, m)?);
        }
        let first_vertex = self.geometry.positions.len();
        let first_triangle = self.geometry.triangles.len();
        self.mesh_models(&entry, &obj_path, mesh, &obj.models, &indices)?;
        self.check_extent(&entry, &obj_path, first_vertex)?;
        if let Some(a) = self.alpha(&format!("{entry}.alpha"), &mesh.alpha)? {
            let triangles = first_triangle..self.geometry.triangles.len();
            alpha::cut_out(&mut self.geometry, &self.shading, triangles, &a);
        }
        Ok(())
    }

    /// A mesh's alpha: a finite constant, or an image relative to the scene file (with
    /// `--lenient`, an image that cannot be read leaves the mesh opaque with a warning).
    fn alpha(&mut self, entry: &str, a: &Option<AlphaEntry>) -> Result<Option<Alpha>, SceneError> {
        match a {
            None => Ok(None),
            Some(AlphaEntry::Constant(a)) if a.is_finite() => Ok(Some(Alpha::Constant(*a))),
            Some(AlphaEntry::Constant(a)) => {
                Err(self.invalid(entry, format!("{a} is not a finite number")))
            }
            Some(AlphaEntry::Image(name)) => match alpha::read_image(&self.dir.join(name)) {
                Ok((image, bytes)) => {
                    self.builder.input(&self.dir.join(name), &bytes);
                    Ok(Some(Alpha::Texture(std::sync::Arc::new(image))))
                }
                Err(message) if self.builder.lenient() => {
                    let w = Warning::entry(&self.path, entry, format!("{message}; left opaque"));
                    self.builder.warn(w);
                    Ok(None)
                }
                Err(message) => Err(self.invalid(entry, message)),
            },
        }
    }

    /// Vertices (after the transform) must lie where f32 positions stay precise enough.
    fn check_extent(&self, entry: &str, obj_path: &Path, first: usize) -> Result<(), SceneError> {
        let positions = &self.geometry.positions[first..];
        match positions
            .iter()
            .position(|p| !p.is_finite() || p.abs().max_element() > MAX_COORDINATE)
        {
            Some(k) => Err(SceneError::Invalid {
                file: obj_path.to_path_buf(),
                entry: format!("{entry}, vertex {}", k + 1),
                message: format!(
                    "{} (after the transform) lies beyond +-{MAX_COORDINATE:e}, where f32 positions lose their precision",
                    positions[k]
                ),
            }),
            None => Ok(()),
        }
    }

    fn mesh_models(
        &mut self,
        entry: &str,
        obj_path: &Path,
        mesh: &MeshTable,
        models: &[tobj::Model],
        mtl_indices: &[u32],
    ) -> Result<(), SceneError> {
        let transform = match &mesh.transform {
            Some(t) => {
                let scale = self.positive(&format!("{entry}.transform.scale"), t.scale)?;
                let r = self.vec3(&format!("{entry}.transform.rotate_deg"), t.rotate_deg)?;
                let translate = self.vec3(&format!("{entry}.transform.translate"), t.translate)?;
                Some((rotation_deg(r) * scale, translate))
            }
            None => None,
        };
        let override_material = mesh
            .material
            .as_ref()
            .map(|name| self.material_index(&format!("{entry}.material"), name))
            .transpose()?;
        let mut default_material = None;
        for model in models {
            let m = &model.mesh;
            let base = self.geometry.positions.len() as u32;
            let (normal_base, uv_base) = self.model_shading(
                obj_path,
                model,
                mesh.shading_normals,
                transform.map(|(linear, _)| linear),
            )?;
            self.geometry.positions.reserve(m.positions.len() / 3);
            self.geometry.triangles.reserve(m.indices.len() / 3);
            self.triangle_materials.reserve(m.indices.len() / 3);
            for (k, p) in m.positions.chunks_exact(3).enumerate() {
                let mut v = Vec3::new(p[0], p[1], p[2]);
                if !v.is_finite() {
                    return Err(SceneError::Invalid {
                        file: obj_path.to_path_buf(),
                        entry: format!("object '{}', vertex {k}", model.name),
                        message: format!("{v} is not finite"),
                    });
                }
                if let Some((linear, translate)) = transform {
                    v = linear * v + translate;
                }
                self.geometry.positions.push(v);
            }
            let material = match (override_material, m.material_id) {
                (Some(o), _) => o,
                (None, Some(id)) if id < mtl_indices.len() => mtl_indices[id],
                _ => match default_material {
                    Some(d) => d,
                    None => {
                        self.builder.warn(Warning::file(
                            obj_path,
                            format!(
                                "object '{}' has no material; using grey lambert (kd 0.8)",
                                model.name
                            ),
                        ));
                        let d = self.default_material()?;
                        default_material = Some(d);
                        d
                    }
                },
            };
            for (k, tri) in m.indices.chunks_exact(3).enumerate() {
                let t = [base + tri[0], base + tri[1], base + tri[2]];
                let [a, b, c] = t.map(|i| self.geometry.positions[i as usize]);
                if (b - a).cross(c - a).length_squared() <= 0.0 {
                    self.dropped_triangles += 1;
                    continue;
                }
                let triangle = self.geometry.triangles.len();
                if let Some(nb) = normal_base {
                    let n = &m.normal_indices[3 * k..3 * k + 3];
                    let list = &mut self.shading.triangle_normals;
                    list.resize(triangle, MeshShading::NONE);
                    list.push([nb + n[0], nb + n[1], nb + n[2]]);
                }
                if let Some(ub) = uv_base {
                    let n = &m.texcoord_indices[3 * k..3 * k + 3];
                    let list = &mut self.shading.triangle_uvs;
                    list.resize(triangle, MeshShading::NONE);
                    list.push([ub + n[0], ub + n[1], ub + n[2]]);
                }
                self.geometry.triangles.push(t);
                self.triangle_materials.push(material);
            }
        }
        Ok(())
    }

    /// Appends a model's normals (when `use_normals`, turned by `linear`) and uvs to the
    /// scene's shading data; returns where each list starts, `None` for data the model lacks.
    fn model_shading(
        &mut self,
        obj_path: &Path,
        model: &tobj::Model,
        use_normals: bool,
        linear: Option<Mat3>,
    ) -> Result<(Option<u32>, Option<u32>), SceneError> {
        let m = &model.mesh;
        let invalid = |what: &str, k: usize, v: &[f32]| SceneError::Invalid {
            file: obj_path.to_path_buf(),
            entry: format!("object '{}', {what} {k}", model.name),
            message: format!("{v:?} is not finite"),
        };
        let has_normals = self.shading_normals
            && use_normals
            && !m.normals.is_empty()
            && m.normal_indices.len() == m.indices.len();
        let normal_base = if has_normals {
            let base = self.shading.normals.len() as u32;
            for (k, n) in m.normals.chunks_exact(3).enumerate() {
                let v = Vec3::new(n[0], n[1], n[2]);
                if !v.is_finite() {
                    return Err(invalid("normal", k, n));
                }
                // Rotation and uniform scale: normals turn with the linear part.
                let v = linear.map_or(v, |l| l * v);
                self.shading.normals.push(v.normalize_or_zero());
            }
            Some(base)
        } else {
            None
        };
        let has_uvs = !m.texcoords.is_empty() && m.texcoord_indices.len() == m.indices.len();
        let uv_base = if has_uvs {
            let base = self.shading.uvs.len() as u32;
            for (k, t) in m.texcoords.chunks_exact(2).enumerate() {
                let v = Vec2::new(t[0], t[1]);
                if !v.is_finite() {
                    return Err(invalid("texture coordinate", k, t));
                }
                self.shading.uvs.push(v);
            }
            Some(base)
        } else {
            None
        };
        Ok((normal_base, uv_base))
    }

    fn default_material(&mut self) -> Result<u32, SceneError> {
        const NAME: &str = "(default grey)";
        match self.by_name.get(NAME) {
            Some(&i) => Ok(i),
            None => {
                let origin = Origin {
                    file: self.path.clone(),
                    line: None,
                    entry: NAME.into(),
                };
                let params = Params::new().with_color("kd", Rgb::splat(0.8));
                self.add_material(&origin, MaterialDesc::new(NAME, "lambert", params))
            }
        }
    }

    /// The material for an MTL entry: a scene-file table of the same name wins (it was added
    /// first); otherwise DESIGN.md's MTL mapping.
    fn mtl_material(
        &mut self,
        obj_path: &Path,
        mtl_file: &Path,
        m: &tobj::Material,
    ) -> Result<u32, SceneError> {
        if let Some(&i) = self.by_name.get(&m.name) {
            return Ok(i);
        }
        let entry = format!("material '{}' of {}", m.name, obj_path.display());
        let color = |v: Option<[f32; 3]>| v.map_or(Rgb::BLACK, Rgb::from_array);
        let kd = color(m.diffuse);
        let ks = color(m.specular);
        let emission = color(m.emissive);
        for (what, c) in [("Kd", kd), ("Ks", ks), ("Ke", emission)] {
            if !c.is_finite() || c.min_component() < 0.0 {
                return Err(self.invalid(
                    format!("{entry}: {what}"),
                    format!("{:?} is not a non-negative finite colour", c.to_array()),
                ));
            }
        }
        let illum = m.illumination_model.unwrap_or(0);
        let dissolve = m.dissolve.unwrap_or(1.0);
        let (type_name, params) = if matches!(illum, 4 | 6 | 7) || dissolve < 1.0 {
            let ior = m.optical_density.filter(|n| *n > 0.0).unwrap_or(1.5);
            ("glass", Params::new().with_number("ior", ior))
        } else if matches!(illum, 3 | 5) {
            let ks = if m.specular.is_some() { ks } else { Rgb::WHITE };
            ("mirror", Params::new().with_color("ks", ks))
        } else if ks.max_component() > 0.0 {
            let exponent = m.shininess.filter(|n| *n >= 0.0).unwrap_or(1.0);
            let p = Params::new()
                .with_color("kd", kd)
                .with_color("ks", ks)
                .with_number("exponent", exponent);
            ("phong", p)
        } else {
            ("lambert", Params::new().with_color("kd", kd))
        };
        let origin = Origin {
            file: self.path.clone(),
            line: None,
            entry,
        };
        let material = MaterialDesc {
            emission,
            ..MaterialDesc::new(m.name.clone(), type_name, params)
        };
        let index = self.add_material(&origin, material)?;
        let mtl_dir = mtl_file.parent().unwrap_or(Path::new("")).to_path_buf();
        let map = |t: &Option<String>| t.as_ref().map(|s| PathBuf::from(texture_file_name(s)));
        let kd = self.texture(
            mtl_file,
            &format!("material '{}': map_Kd", m.name),
            &mtl_dir,
            &map(&m.diffuse_texture),
        )?;
        let ks = self.texture(
            mtl_file,
            &format!("material '{}': map_Ks", m.name),
            &mtl_dir,
            &map(&m.specular_texture),
        )?;
        self.builder.set_textures(
            index,
            MaterialTextures {
                kd,
                ks,
                roughness: None,
                vroughness: None,
            },
        );
        Ok(index)
    }

    fn light(&self, i: usize, l: &LightTable) -> Result<Light, SceneError> {
        let entry = format!("light[{i}]");
        let need = |v: Option<[f32; 3]>, key: &str| {
            v.ok_or_else(|| self.invalid(&entry, format!("a {} light needs `{key}`", l.kind)))
        };
        if l.kind != "spot" {
            let spot_only = [
                ("look_at", l.look_at.is_some()),
                ("cone_angle", l.cone_angle.is_some()),
                ("cone_delta", l.cone_delta.is_some()),
            ];
            if let Some((key, _)) = spot_only.iter().find(|(_, given)| *given) {
                return Err(self.invalid(
                    format!("{entry}.{key}"),
                    format!("only spot lights take `{key}`, not a {} light", l.kind),
                ));
            }
        }
        match l.kind.as_str() {
            "point" => Ok(Light::Point {
                position: self.point(&format!("{entry}.position"), need(l.position, "position")?)?,
                intensity: self.color(&format!("{entry}.intensity"), need(l.intensity, "intensity")?)?,
            }),
            "directional" => Ok(Light::Directional {
                direction: self.direction(&format!("{entry}.direction"), need(l.direction, "direction")?)?,
                irradiance: self.color(&format!("{entry}.irradiance"), need(l.irradiance, "irradiance")?)?,
                scene: SceneBounds::new(Vec3::ZERO, Vec3::ONE),
            }),
            "spot" => self.spot(&entry, l),
            other => Err(self.invalid(
                format!("{entry}.type"),
                format!("unknown light type '{other}' (point, spot, directional; area lights are emissive materials)"),
            )),
        }
    }
}

impl Loader {
    /// A spot light: its axis by `direction` or by `look_at`, its cone in degrees (pbrt-v4's
    /// defaults: 30 and 5).
    fn spot(&self, entry: &str, l: &LightTable) -> Result<Light, SceneError> {
        let need = |v: Option<[f32; 3]>, key: &str| {
            v.ok_or_else(|| self.invalid(entry, format!("a spot light needs `{key}`")))
        };
        let position = self.point(&format!("{entry}.position"), need(l.position, "position")?)?;
        let axis = match (l.direction, l.look_at) {
            (Some(d), None) => self.direction(&format!("{entry}.direction"), d)?,
            (None, Some(target)) => {
                let key = format!("{entry}.look_at");
                let axis = self.point(&key, target)? - position;
                if axis.length_squared() == 0.0 {
                    return Err(self.invalid(key, "the spot light looks at its own position"));
                }
                axis
            }
            _ => {
                return Err(
                    self.invalid(entry, "a spot light needs one of `direction` and `look_at`")
                )
            }
        };
        let cone = SpotCone::new(
            axis,
            l.cone_angle.unwrap_or(30.0),
            l.cone_delta.unwrap_or(5.0),
        )
        .map_err(|e| {
            let key = match e {
                SpotError::ConeDelta { .. } => "cone_delta",
                SpotError::ConeAngle(_) => "cone_angle",
                SpotError::Axis(_) => "direction",
            };
            self.invalid(format!("{entry}.{key}"), e.to_string())
        })?;
        Ok(Light::Spot {
            position,
            intensity: self.color(
                &format!("{entry}.intensity"),
                need(l.intensity, "intensity")?,
            )?,
            cone,
        })
    }
}

/// Rotation by Euler angles in degrees: about x, then y, then z.
fn rotation_deg(r: Vec3) -> Mat3 {
    Mat3::from_rotation_z(r.z.to_radians())
        * Mat3::from_rotation_y(r.y.to_radians())
        * Mat3::from_rotation_x(r.x.to_radians())
}

/// The file of an MTL `map_*` statement: its last word, after any options (`-s 1 1 1 ...`).
fn texture_file_name(statement: &str) -> &str {
    statement.split_whitespace().last().unwrap_or(statement)
}

/// MTL statements vmerge understands; anything else is reported once per file.
const KNOWN_MTL: &[&str] = &[
    "newmtl", "Kd", "Ks", "Ke", "Ns", "Ni", "d", "illum", "map_Kd", "map_Ks",
];

fn unknown_mtl_statements(path: &Path, text: &str) -> Vec<Warning> {
    let mut warnings = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for line in text.lines() {
        let line = line.trim();
        let Some(word) = line.split_whitespace().next() else {
            continue;
        };
        if word.starts_with('#') || KNOWN_MTL.contains(&word) {
            continue;
        }
        if seen.insert(word.to_string()) {
            warnings.push(Warning::file(
                path,
                format!("skipping unsupported MTL statement '{word}'"),
            ));
        }
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    /// More meshes than one parallel batch holds, mesh k a triangle at x = k.
    const MESHES: usize = 11;

    fn write_scene(dir: &Path, broken: &[(usize, &str)]) -> PathBuf {
        let mut toml = String::from(
            "[[camera]]\nname = \"c\"\nposition = [0.0, 0.0, 5.0]\nlook_at = [0.0, 0.0, 0.0]\nup = [0.0, 1.0, 0.0]\nfov = 40.0\n",
        );
        for k in 0..MESHES {
            let name = format!("m{k}.obj");
            let text = match broken.iter().find(|(i, _)| *i == k) {
                Some((_, text)) => text.to_string(),
                None => format!("v {k} 0 0\nv {k} 1 0\nv {k} 0 1\nf 1 2 3\n"),
            };
            if !text.is_empty() {
                std::fs::write(dir.join(&name), text).unwrap();
            }
            toml += &format!("[[mesh]]\nfile = \"{name}\"\n");
        }
        let path = dir.join("scene.toml");
        std::fs::write(&path, toml).unwrap();
        path
    }

    fn options() -> LoadOptions {
        LoadOptions {
            accel: AccelKind::default_kind(),
            lenient: false,
            shading_normals: true,
        }
    }

    #[test]
    fn meshes_read_in_parallel_join_in_file_order() {
        let dir = tempfile::tempdir().unwrap();
        let parts = load_parts(&write_scene(dir.path(), &[]), &options()).unwrap();
        let xs: Vec<f32> = parts
            .geometry
            .triangles
            .iter()
            .map(|t| parts.geometry.positions[t[0] as usize].x)
            .collect();
        assert_eq!(xs, (0..MESHES).map(|k| k as f32).collect::<Vec<_>>());
    }

    #[test]
    fn the_first_broken_mesh_in_file_order_is_named() {
        let dir = tempfile::tempdir().unwrap();
        // mesh[3]'s file is missing (an empty text writes no file), mesh[8]'s face is short.
        let scene = write_scene(dir.path(), &[(3, ""), (8, "v 0 0 0\nf 1 1\n")]);
        let message = load_parts(&scene, &options()).err().unwrap().to_string();
        assert!(message.contains("mesh[3]"), "{message}");
        let scene = write_scene(dir.path(), &[(3, "v 0 0 0\nf 1 1\n"), (8, "")]);
        let message = load_parts(&scene, &options()).err().unwrap().to_string();
        assert!(
            message.contains("m3.obj") && message.contains("line 2"),
            "{message}"
        );
    }
}
