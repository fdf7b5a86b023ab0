//! pbrt-v4's graphics state over the directive stream, and the result handed to the scene
//! builder: the importer's state and its walk over the files. What each directive does lives
//! with its concept: `state` (graphics state, transforms, objects, camera and settings),
//! `shapes`, `material`, `textures`, `lights`; `directives` lists them all.

use super::directives::{self, Place};
use super::lights::AreaLight;
use super::parser::{Directive, ParseError, Parser};
use super::shapes::{Laid, ShapeRecord};
use super::textures::{FloatTex, PendingTextures, Tex};
use crate::files::{self, snippet, FileError, Kind};
use crate::light::{Light, SkyDesc};
use crate::scene::builder::{Builder, Contents};
use crate::scene::{CameraDesc, FovAxis, RenderDefaults, SceneError, SceneParts, Warning};
use glam::{DMat4, Vec3};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};

/// A place in a scene file: index into `Importer::files`, and the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Loc {
    pub(super) file: usize,
    pub(super) line: u32,
}

/// The graphics state that AttributeBegin saves and AttributeEnd restores.
#[derive(Clone, Debug)]
pub(super) struct State {
    pub(super) ctm: DMat4,
    pub(super) reverse_orientation: bool,
    pub(super) material: Option<u32>,
    pub(super) area_light: Option<AreaLight>,
}

/// An open block, closed by its own End directive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Block {
    Attribute,
    Transform,
    Object,
}

impl Block {
    /// The directive that opens the block.
    pub(super) fn directive(self) -> &'static str {
        match self {
            Block::Attribute => "AttributeBegin",
            Block::Transform => "TransformBegin",
            Block::Object => "ObjectBegin",
        }
    }
}

/// The import in progress: the files, the graphics state and what the directives declared,
/// until [`Importer::finish`] hands it to the builder.
pub(super) struct Importer {
    pub(super) lenient: bool,
    /// Materials, images, the scene hash and the warnings.
    pub(super) builder: Builder,
    /// Every file read, for locations; the main file first.
    pub(super) files: Vec<PathBuf>,
    pub(super) canonical: Vec<PathBuf>,
    pub(super) include_stack: Vec<usize>,
    /// Relative paths resolve against the main file's folder, as in pbrt.
    pub(super) dir: PathBuf,

    pub(super) state: State,
    pub(super) stack: Vec<(Block, Loc, State)>,
    pub(super) world: bool,
    pub(super) motion_warned: bool,
    pub(super) ignore_transforms: bool,
    pub(super) named_coordinates: HashMap<String, DMat4>,
    pub(super) named_materials: HashMap<String, u32>,
    pub(super) textures: HashMap<String, Tex>,
    pub(super) float_textures: HashMap<String, FloatTex>,
    pub(super) objects: HashMap<String, Vec<ShapeRecord>>,
    pub(super) current_object: Option<(String, Vec<ShapeRecord>)>,
    pub(super) shapes: Vec<ShapeRecord>,
    /// Shapes left out (unsupported, no surface, missing file), and what they were.
    pub(super) skipped_shapes: Vec<(Loc, String)>,
    /// The materials of kind `interface`: their shapes are no surface.
    pub(super) interfaces: HashSet<u32>,
    /// Directives whose settings vmerge's own replace, each with where it came first.
    pub(super) ignored_directives: BTreeMap<String, Loc>,
    /// Each distinct warning once: where it came first, and how many times more.
    pub(super) warnings: Vec<(Loc, String, usize)>,
    pub(super) warning_index: HashMap<String, usize>,

    /// Per material of the builder: the images its parameters come from.
    pub(super) material_textures: Vec<Option<PendingTextures>>,
    pub(super) default_material: Option<u32>,
    pub(super) emissive: HashMap<(u32, [u32; 3], bool), u32>,
    pub(super) camera: Option<CameraDesc>,
    pub(super) resolution: Option<[u32; 2]>,
    pub(super) max_path_length: Option<u32>,
    pub(super) lights: Vec<Light>,
    pub(super) sky: Option<SkyDesc>,
    pub(super) env_image: Option<(PathBuf, f32, DMat4, Loc)>,
}

/// Imports the pbrt-v4 scene at `path` and the files it includes; with `lenient`, missing
/// files and over-energetic materials are warned about instead of refused.
pub fn import(path: &Path, lenient: bool) -> Result<SceneParts, SceneError> {
    let mut im = Importer {
        lenient,
        builder: Builder::new(path, lenient),
        files: Vec::new(),
        canonical: Vec::new(),
        include_stack: Vec::new(),
        dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
        state: State {
            ctm: DMat4::IDENTITY,
            reverse_orientation: false,
            material: None,
            area_light: None,
        },
        stack: Vec::new(),
        world: false,
        motion_warned: false,
        ignore_transforms: false,
        named_coordinates: HashMap::new(),
        named_materials: HashMap::new(),
        textures: HashMap::new(),
        float_textures: HashMap::new(),
        objects: HashMap::new(),
        current_object: None,
        shapes: Vec::new(),
        skipped_shapes: Vec::new(),
        interfaces: HashSet::new(),
        ignored_directives: BTreeMap::new(),
        warnings: Vec::new(),
        warning_index: HashMap::new(),
        material_textures: Vec::new(),
        default_material: None,
        emissive: HashMap::new(),
        camera: None,
        resolution: None,
        max_path_length: None,
        lights: Vec::new(),
        sky: None,
        env_image: None,
    };
    im.run_file(path, None)?;
    if let Some(&(block, loc, _)) = im.stack.last() {
        return Err(im.at(loc, format!("{} is never closed", block.directive())));
    }
    if !im.world {
        return Err(im.at(
            Loc { file: 0, line: 1 },
            "the file has no WorldBegin".to_string(),
        ));
    }
    // One line for them all, at the first of them.
    if let Some(&first) = im
        .ignored_directives
        .values()
        .min_by_key(|l| (l.file, l.line))
    {
        let names: Vec<_> = im.ignored_directives.keys().cloned().collect();
        let w = Warning::at(
            &im.files[first.file],
            first.line,
            format!(
                "ignored (vmerge's own settings apply): {}",
                names.join(", ")
            ),
        );
        im.builder.warn(w);
    }
    im.finish()
}

impl Importer {
    pub(super) fn at(&self, loc: Loc, message: impl Into<String>) -> SceneError {
        SceneError::At {
            file: self.files[loc.file].clone(),
            line: loc.line,
            message: message.into(),
        }
    }

    /// Warns at `loc`; a message repeated elsewhere is counted, not repeated (a scene with
    /// thousands of curves gets one line, "N more like this").
    pub(super) fn warn(&mut self, loc: Loc, message: impl Into<String>) {
        let message = message.into();
        match self.warning_index.get(&message) {
            Some(&i) => self.warnings[i].2 += 1,
            None => {
                self.warning_index
                    .insert(message.clone(), self.warnings.len());
                self.warnings.push((loc, message, 0));
            }
        }
    }

    /// Hands the warnings, counted, to the builder.
    fn flush_warnings(&mut self) {
        for (loc, message, more) in std::mem::take(&mut self.warnings) {
            let message = match more {
                0 => message,
                n => format!("{message} ({n} more like this)"),
            };
            let w = Warning::at(&self.files[loc.file], loc.line, message);
            self.builder.warn(w);
        }
        self.warning_index.clear();
    }

    /// Turns a parameter error into a scene error in `file`.
    pub(super) fn pe(&self, file: usize) -> impl Fn(ParseError) -> SceneError {
        let path = self.files[file].clone();
        move |e| SceneError::At {
            file: path.clone(),
            line: e.line,
            message: e.message,
        }
    }

    pub(super) fn resolve(&self, name: &str) -> PathBuf {
        let p = Path::new(name);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }

    pub(super) fn run_file(&mut self, path: &Path, from: Option<Loc>) -> Result<(), SceneError> {
        let read_error = |e: FileError| match from {
            Some(loc) => self.at(loc, format!("cannot read included file {e}")),
            None => SceneError::File(e),
        };
        let text = files::read_text(path, Kind::Pbrt).map_err(read_error)?;
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        if let (Some(loc), Some(k)) = (
            from,
            self.include_stack
                .iter()
                .position(|&i| self.canonical[i] == canonical),
        ) {
            let mut chain: Vec<String> = self.include_stack[k..]
                .iter()
                .map(|&i| self.files[i].display().to_string())
                .collect();
            chain.push(path.display().to_string());
            return Err(self.at(loc, format!("Include loop: {}", chain.join(" -> "))));
        }
        self.builder.input(path, text.as_bytes());
        let file = self.files.len();
        self.files.push(path.to_path_buf());
        self.canonical.push(canonical);
        self.include_stack.push(file);
        let mut parser = Parser::new(&text);
        loop {
            let directive = parser.next_directive().map_err(self.pe(file))?;
            let Some(d) = directive else { break };
            self.directive(file, d)?;
        }
        self.include_stack.pop();
        Ok(())
    }

    pub(super) fn directive(&mut self, file: usize, d: Directive) -> Result<(), SceneError> {
        let loc = Loc { file, line: d.line };
        let name = d.name.as_str();
        match directives::find(name) {
            None => self.warn(
                loc,
                format!("unknown directive '{name}' skipped", name = snippet(name)),
            ),
            Some(spec) => {
                if spec.place == Place::World && !self.world {
                    return Err(self.at(loc, format!("{name} before WorldBegin")));
                }
                if spec.place == Place::Options && self.world {
                    return Err(self.at(loc, format!("{name} after WorldBegin")));
                }
                (spec.run)(self, loc, &d)?;
            }
        }
        let unused: Vec<_> = d
            .params
            .unused()
            .map(|p| {
                (
                    p.line,
                    format!(
                        "{name}: parameter \"{} {}\" ignored",
                        p.ty.name(),
                        snippet(&p.name),
                        name = snippet(name)
                    ),
                )
            })
            .collect();
        for (line, msg) in unused {
            self.warn(Loc { file, line }, msg);
        }
        Ok(())
    }

    /// Include, Import: the file runs in the current graphics state.
    pub(super) fn include(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let path = self.resolve(d.str_arg(0));
        self.run_file(&path, Some(loc))
    }

    /// The shapes laid out, the images read, and everything handed to the builder.
    pub(super) fn finish(mut self) -> Result<SceneParts, SceneError> {
        let Laid {
            geometry,
            triangle_materials,
            sphere_materials,
            shading,
            dropped,
        } = self.lay_out_shapes()?;
        if geometry.triangles.is_empty() && geometry.spheres.is_empty() {
            if let Some((loc, what)) = self.skipped_shapes.first() {
                let more = match self.skipped_shapes.len() - 1 {
                    0 => String::new(),
                    n => format!(" ({n} more shapes skipped)"),
                };
                return Err(self.at(
                    *loc,
                    format!("the scene has no geometry left: {what}; skipped{more}"),
                ));
            }
        }
        self.builder.check_geometry(&geometry, dropped)?;
        self.load_textures()?;
        let env_map = self.env_map()?;
        let camera = self.camera.clone().unwrap_or_else(|| CameraDesc {
            name: "camera".into(),
            position: Vec3::ZERO,
            look_at: Vec3::Z,
            up: Vec3::Y,
            fov_deg: 90.0,
            fov_axis: FovAxis::Shorter,
            mirrored: true,
        });
        self.flush_warnings();
        let defaults = RenderDefaults {
            resolution: self.resolution.unwrap_or([1280, 720]),
            max_path_length: self.max_path_length.unwrap_or(6),
            radius: None,
        };
        Ok(self.builder.finish(Contents {
            geometry,
            triangle_materials,
            sphere_materials,
            shading,
            lights: self.lights,
            sky: self.sky,
            env_map,
            cameras: vec![camera],
            defaults,
            dropped_triangles: dropped,
        }))
    }
}
