//! The one builder both scene formats hand their content to: the TOML/OBJ loader and the pbrt
//! importer read their files and describe materials, textures, geometry, lights and cameras;
//! the builder owns what must not depend on the format: the energy rule for materials, the
//! decoded images (each file once), the scene hash, the list of input files and the warnings.
//!
//! # The energy rule
//!
//! Phong conserves energy only for kd + ks <= 1 per channel (000 eq. 3.1), the other BSDFs
//! for reflectances <= 1 (`MaterialKind::energy_excess`). A material that reaches the builder
//! with more, whatever file it came from, is refused with an error naming the file and the
//! entry, or, when the load is lenient, scaled down per channel to kd + ks = 1 (a single
//! reflectance clamped to 1) with a warning. The same Phong therefore gives the same material and the same
//! warning from a TOML table, an MTL entry or a pbrt material:
//! - the numbers are the file's: a sum above 1 is a mistake in them (pbrt-v4 would clamp it
//!   silently and render something else than the file says), so a strict load names it;
//! - `--lenient` is already the one switch for "render what can be rendered, with warnings"
//!   (missing textures, meshes and skies in both formats), so it is the switch here too;
//! - scaling both lobes by one factor per channel keeps the ratio of kd to ks, the material's
//!   look, and the lobe's shape, where clamping each would not.
//!
//! The pbrt importer's own approximations (a coated or rough material onto Phong, in
//! `pbrt/material.rs`) conserve energy by construction for reflectances up to 1, so only
//! what a file states can trip the rule; none of the shipped or Bitterli scenes does.

use super::{
    CameraDesc, MaterialTextures, MeshShading, Mix, RenderDefaults, SceneError, SceneParts, Warning,
};
use crate::accel::Geometry;
use crate::bsdf::{EnergyFix, Material, MaterialKind, Params};
use crate::color::Rgb;
use crate::light::{EnvMapDesc, Light, SkyDesc};
use crate::options::OptionName;
use crate::texture::{self, Texture};
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where a material was declared: its file, the line where the format has lines (pbrt), and
/// the entry (`material.NAME`, `material 'NAME'`), for its errors and warnings.
#[derive(Clone, Debug)]
pub struct Origin {
    pub file: PathBuf,
    pub line: Option<u32>,
    pub entry: String,
}

impl Origin {
    fn error(&self, message: String) -> SceneError {
        match self.line {
            Some(line) => SceneError::At {
                file: self.file.clone(),
                line,
                message: format!("{}: {message}", self.entry),
            },
            None => SceneError::Invalid {
                file: self.file.clone(),
                entry: self.entry.clone(),
                message,
            },
        }
    }

    fn warning(&self, message: String) -> Warning {
        Warning {
            file: Some(self.file.clone()),
            line: self.line,
            entry: Some(self.entry.clone()),
            message,
        }
    }
}

/// A material as a front-end describes it: a BSDF by type name with its parameters (those
/// absent take the type's defaults), and its emission.
pub struct MaterialDesc {
    pub name: String,
    pub type_name: &'static str,
    pub params: Params,
    pub emission: Rgb,
    /// Emission on both sides.
    pub two_sided: bool,
}

impl MaterialDesc {
    /// A material that does not emit.
    pub fn new(name: impl Into<String>, type_name: &'static str, params: Params) -> Self {
        MaterialDesc {
            name: name.into(),
            type_name,
            params,
            emission: Rgb::BLACK,
            two_sided: false,
        }
    }
}

/// What a front-end built besides the materials and textures, for [`Builder::finish`].
pub struct Contents {
    pub geometry: Geometry,
    pub triangle_materials: Vec<u32>,
    pub sphere_materials: Vec<u32>,
    pub shading: MeshShading,
    pub lights: Vec<Light>,
    pub sky: Option<SkyDesc>,
    pub env_map: Option<EnvMapDesc>,
    pub cameras: Vec<CameraDesc>,
    pub defaults: RenderDefaults,
    pub dropped_triangles: usize,
}

pub struct Builder {
    /// The scene file the load started from.
    source: PathBuf,
    lenient: bool,
    hasher: Sha256,
    /// Every file read, for the check that an output overwrites none of them.
    inputs: Vec<PathBuf>,
    warnings: Vec<Warning>,
    materials: Vec<Material>,
    /// Parallel to `materials`.
    material_textures: Vec<MaterialTextures>,
    /// Parallel to `materials` once a mix is added.
    mixes: Vec<Option<Mix>>,
    /// Each image file decoded so far (the file's extension fixes its colour space, so one
    /// path is one decoding).
    images: HashMap<PathBuf, Arc<Texture>>,
    textures: Vec<Arc<Texture>>,
    /// Index in `textures` of each image times a factor.
    texture_index: HashMap<(PathBuf, [u32; 3]), u32>,
}

impl Builder {
    pub fn new(source: &Path, lenient: bool) -> Builder {
        Builder {
            source: source.to_path_buf(),
            lenient,
            hasher: Sha256::new(),
            inputs: Vec::new(),
            warnings: Vec::new(),
            materials: Vec::new(),
            material_textures: Vec::new(),
            mixes: Vec::new(),
            images: HashMap::new(),
            textures: Vec::new(),
            texture_index: HashMap::new(),
        }
    }

    pub fn lenient(&self) -> bool {
        self.lenient
    }

    /// Records a file read and adds its bytes to the scene hash. The hash covers every input
    /// in the order read, so the front-ends read in a fixed order.
    pub fn input(&mut self, path: &Path, bytes: &[u8]) {
        self.hasher.update(bytes);
        self.inputs.push(path.to_path_buf());
    }

    /// [`Builder::input`] for a file hashed on its own (meshes read in parallel): its digest
    /// goes into the scene hash.
    pub fn input_digest(&mut self, path: &Path, digest: &[u8]) {
        self.input(path, digest);
    }

    pub fn warn(&mut self, warning: Warning) {
        self.warnings.push(warning);
    }

    /// Decodes the images at `paths` that are not decoded yet (in parallel), hashing and
    /// recording each new file in the order given; per path, the image or why it cannot be
    /// read (a message naming the file).
    pub fn images(&mut self, paths: &[PathBuf]) -> Vec<Result<Arc<Texture>, String>> {
        let mut seen = std::collections::HashSet::new();
        let new: Vec<&PathBuf> = paths
            .iter()
            .filter(|p| !self.images.contains_key(*p) && seen.insert(*p))
            .collect();
        let decoded: Vec<Result<(Texture, Vec<u8>), String>> = new
            .par_iter()
            .map(|p| {
                let bytes = std::fs::read(p).map_err(|e| e.to_string())?;
                Ok((texture::read(p)?, bytes))
            })
            .collect();
        let mut failed = HashMap::new();
        for (path, result) in new.into_iter().zip(decoded) {
            match result {
                Ok((image, bytes)) => {
                    self.input(path, &bytes);
                    self.images.insert(path.clone(), Arc::new(image));
                }
                Err(e) => {
                    failed.insert(path, format!("cannot read image {}: {e}", path.display()));
                }
            }
        }
        paths
            .iter()
            .map(|p| match self.images.get(p) {
                Some(image) => Ok(Arc::clone(image)),
                None => Err(failed.get(p).cloned().unwrap_or_else(|| {
                    format!("cannot read image {}: it was not read", p.display())
                })),
            })
            .collect()
    }

    /// [`Builder::images`] for one image.
    pub fn image(&mut self, path: &Path) -> Result<Arc<Texture>, String> {
        let mut result = self.images(&[path.to_path_buf()]);
        result
            .pop()
            .unwrap_or_else(|| Err(path.display().to_string()))
    }

    /// The scene texture for the decoded image of `path` times `factor` (a scaled copy where
    /// that is not 1), one per image and factor.
    pub fn texture(&mut self, path: &Path, image: &Arc<Texture>, factor: Rgb) -> u32 {
        let key = (path.to_path_buf(), factor.to_array().map(f32::to_bits));
        if let Some(&i) = self.texture_index.get(&key) {
            return i;
        }
        let texture = if factor == Rgb::WHITE {
            Arc::clone(image)
        } else {
            let texels = image.texels.iter().map(|&t| t * factor).collect();
            Arc::new(Texture {
                texels,
                ..(**image).clone()
            })
        };
        self.textures.push(texture);
        let i = self.textures.len() as u32 - 1;
        self.texture_index.insert(key, i);
        i
    }

    /// A one-texel scene texture of `value`: one axis of a roughness pair whose other axis
    /// comes from an image.
    pub fn constant_texture(&mut self, value: Rgb) -> u32 {
        let key = (
            PathBuf::from(format!("(constant {:?})", value.to_array())),
            value.to_array().map(f32::to_bits),
        );
        if let Some(&i) = self.texture_index.get(&key) {
            return i;
        }
        let texture = Texture {
            width: 1,
            height: 1,
            texels: vec![value],
        };
        self.textures.push(Arc::new(texture));
        let i = self.textures.len() as u32 - 1;
        self.texture_index.insert(key, i);
        i
    }

    /// Builds a material (its parameters checked by the BSDF) under the energy rule (module
    /// doc); returns its index.
    pub fn material(&mut self, origin: &Origin, desc: MaterialDesc) -> Result<u32, SceneError> {
        let kind = MaterialKind::from_params(desc.type_name, &desc.params)
            .map_err(|e| origin.error(e.to_string()))?;
        let kind = self.conserve_energy(origin, kind)?;
        Ok(self.push_material(Material {
            name: desc.name,
            kind,
            emission: desc.emission,
            two_sided: desc.two_sided,
        }))
    }

    /// Adds a mix of two materials already added (`amount` the probability of the second,
    /// clamped to [0, 1]); it is named and listed like any material, and hits resolve it.
    pub fn mix(&mut self, name: String, mix: Mix) -> u32 {
        let mut m = self.materials[mix.materials[0] as usize].clone();
        m.name = name;
        m.emission = Rgb::BLACK;
        let index = self.push_material(m);
        self.mixes.resize(self.materials.len(), None);
        self.mixes[index as usize] = Some(Mix {
            amount: mix.amount.clamp(0.0, 1.0),
            ..mix
        });
        index
    }

    /// Gives the mix `index` the texture whose mean channel is its amount per point.
    pub fn set_mix_texture(&mut self, index: u32, texture: u32) {
        if let Some(Some(mix)) = self.mixes.get_mut(index as usize) {
            mix.amount_texture = Some(texture);
        }
    }

    /// Adds a material that is a variant of one already checked (an emissive copy, on one side
    /// or on both; of a mix, the mix of its materials' variants, so the emission survives the
    /// choice).
    pub fn variant(&mut self, base: u32, name: String, emission: Rgb, two_sided: bool) -> u32 {
        if let Some(Some(mix)) = self.mixes.get(base as usize).copied() {
            let materials = mix.materials.map(|m| {
                self.variant(
                    m,
                    format!("{name} ({})", self.materials[m as usize].name),
                    emission,
                    two_sided,
                )
            });
            let index = self.mix(name, Mix { materials, ..mix });
            self.materials[index as usize].emission = emission;
            self.materials[index as usize].two_sided = two_sided;
            return index;
        }
        let mut m = self.materials[base as usize].clone();
        m.name = name;
        m.emission = emission;
        m.two_sided = two_sided;
        let textures = self.material_textures[base as usize];
        let index = self.push_material(m);
        self.material_textures[index as usize] = textures;
        index
    }

    fn push_material(&mut self, material: Material) -> u32 {
        self.materials.push(material);
        self.material_textures.push(MaterialTextures::default());
        if !self.mixes.is_empty() {
            self.mixes.push(None);
        }
        self.materials.len() as u32 - 1
    }

    pub fn set_textures(&mut self, material: u32, textures: MaterialTextures) {
        self.material_textures[material as usize] = textures;
    }

    pub fn material_at(&self, index: u32) -> &Material {
        &self.materials[index as usize]
    }

    /// The one energy rule (module doc).
    fn conserve_energy(
        &mut self,
        origin: &Origin,
        kind: MaterialKind,
    ) -> Result<MaterialKind, SceneError> {
        let Some(excess) = kind.energy_excess() else {
            return Ok(kind);
        };
        let (what, total) = (excess.what, round3(excess.total));
        if !self.lenient {
            return Err(origin.error(format!(
                "{what} = {total:?} exceeds 1 and would create energy (use {} to clamp)",
                OptionName("lenient")
            )));
        }
        let fix = match excess.fix {
            EnergyFix::Scaled => "scaled down",
            EnergyFix::Clamped => "clamped to 1",
        };
        self.warn(origin.warning(format!(
            "{what} = {total:?} exceeds 1; {fix} to conserve energy"
        )));
        Ok(excess.conserving)
    }

    /// Warns about dropped triangles and refuses a scene without geometry.
    pub fn check_geometry(
        &mut self,
        geometry: &Geometry,
        dropped: usize,
    ) -> Result<(), SceneError> {
        if dropped > 0 {
            let w = Warning::file(
                &self.source,
                format!("dropped {dropped} degenerate triangles"),
            );
            self.warn(w);
        }
        if geometry.triangles.is_empty() && geometry.spheres.is_empty() {
            return Err(SceneError::NoGeometry {
                file: self.source.clone(),
                dropped,
            });
        }
        Ok(())
    }

    pub fn finish(self, c: Contents) -> SceneParts {
        let source_hash = self
            .hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        SceneParts {
            source: self.source,
            source_hash,
            geometry: c.geometry,
            triangle_materials: c.triangle_materials,
            sphere_materials: c.sphere_materials,
            materials: self.materials,
            material_textures: self.material_textures,
            mixes: self.mixes,
            textures: self.textures,
            shading: c.shading,
            point_and_directional: c.lights,
            sky: c.sky,
            env_map: c.env_map,
            cameras: c.cameras,
            defaults: c.defaults,
            dropped_triangles: c.dropped_triangles,
            inputs: self.inputs,
            warnings: self.warnings,
        }
    }
}

/// A colour rounded to three decimals, for messages.
pub fn round3(c: Rgb) -> [f32; 3] {
    c.to_array().map(|x| (x * 1000.0).round() / 1000.0)
}
