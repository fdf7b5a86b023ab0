//! pbrt-v4's graphics state over the directive stream, and the result as [`SceneParts`]: shapes
//! flattened into one triangle list (instances expanded), materials mapped onto vmerge's BSDFs
//! (`material.rs`), area lights as emissive variants of their shapes' materials.

use super::material::{self, conductor_f0, dielectric_f0, named_spectrum, phong_exponent};
use super::parser::{Directive, ParamList, ParamType, ParseError, Parser, Spectrum, TexOr};
use super::ply::{self, PlyMesh};
use crate::accel::{Geometry, Sphere};
use crate::bsdf::{EnergyFix, Material, MaterialKind};
use crate::color::Rgb;
use crate::files::{self, FileError, Kind};
use crate::light::{EnvMapDesc, Light, SceneBounds, SkyDesc};
use crate::options::OptionName;
use crate::scene::builder::{round3, Builder, Contents, Origin};
use crate::scene::{
    CameraDesc, FovAxis, MaterialTextures, MeshShading, RenderDefaults, SceneError, SceneParts,
    Warning, MAX_COORDINATE,
};
use crate::texture;
use glam::{DMat3, DMat4, DVec3, Mat3, Vec2, Vec3};
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A place in a scene file: index into `Importer::files`, and the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Loc {
    file: usize,
    line: u32,
}

/// A spectrum-valued texture, as far as vmerge follows it.
#[derive(Clone, Debug)]
enum Tex {
    Constant(Rgb),
    /// An image file that exists, times `scale`, and its Texture directive.
    Image {
        path: PathBuf,
        scale: Rgb,
        loc: Loc,
    },
    /// An image file that is missing (with `--lenient`): the material's constant stands in.
    Missing,
}

#[derive(Clone, Debug)]
enum FloatTex {
    Constant(f32),
    Image,
}

/// A mesh in object space, shared between the instances that use it.
#[derive(Debug)]
enum MeshSource {
    Inline(Arc<PlyMesh>),
    Ply(PathBuf),
}

#[derive(Clone, Debug)]
enum ShapeKind {
    Mesh(Arc<MeshSource>),
    Sphere { radius: f64 },
}

/// A shape with the graphics state it was declared in.
#[derive(Clone, Debug)]
struct ShapeRecord {
    kind: ShapeKind,
    ctm: DMat4,
    reverse_orientation: bool,
    material: u32,
    loc: Loc,
}

#[derive(Clone, Debug)]
struct AreaLight {
    radiance: Rgb,
    loc: Loc,
}

#[derive(Clone, Debug)]
struct State {
    ctm: DMat4,
    reverse_orientation: bool,
    material: Option<u32>,
    area_light: Option<AreaLight>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Block {
    Attribute,
    Transform,
    Object,
}

pub struct Importer {
    lenient: bool,
    /// Materials, images, the scene hash and the warnings.
    builder: Builder,
    /// Every file read, for locations; the main file first.
    files: Vec<PathBuf>,
    canonical: Vec<PathBuf>,
    include_stack: Vec<usize>,
    /// Relative paths resolve against the main file's folder, as in pbrt.
    dir: PathBuf,

    state: State,
    stack: Vec<(Block, Loc, State)>,
    world: bool,
    motion_warned: bool,
    ignore_transforms: bool,
    named_coordinates: HashMap<String, DMat4>,
    named_materials: HashMap<String, u32>,
    textures: HashMap<String, Tex>,
    float_textures: HashMap<String, FloatTex>,
    objects: HashMap<String, Vec<ShapeRecord>>,
    current_object: Option<(String, Vec<ShapeRecord>)>,
    shapes: Vec<ShapeRecord>,
    ignored_directives: BTreeSet<String>,

    /// Per material of the builder: the image its reflectance comes from, the factor on its
    /// texels, and the Texture directive.
    material_textures: Vec<Option<(PathBuf, Rgb, Loc)>>,
    default_material: Option<u32>,
    emissive: HashMap<(u32, [u32; 3]), u32>,
    camera: Option<CameraDesc>,
    resolution: Option<[u32; 2]>,
    max_path_length: Option<u32>,
    lights: Vec<Light>,
    sky: Option<SkyDesc>,
    env_image: Option<(PathBuf, f32, DMat4, Loc)>,
}

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
        ignored_directives: BTreeSet::new(),
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
        let name = match block {
            Block::Attribute => "AttributeBegin",
            Block::Transform => "TransformBegin",
            Block::Object => "ObjectBegin",
        };
        return Err(im.at(loc, format!("{name} is never closed")));
    }
    if !im.world {
        return Err(im.at(
            Loc { file: 0, line: 1 },
            "the file has no WorldBegin".to_string(),
        ));
    }
    if !im.ignored_directives.is_empty() {
        let names: Vec<_> = im.ignored_directives.iter().cloned().collect();
        let w = Warning::file(
            &im.files[0],
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
    fn at(&self, loc: Loc, message: impl Into<String>) -> SceneError {
        SceneError::At {
            file: self.files[loc.file].clone(),
            line: loc.line,
            message: message.into(),
        }
    }

    fn warn(&mut self, loc: Loc, message: impl Into<String>) {
        let w = Warning::at(&self.files[loc.file], loc.line, message);
        self.builder.warn(w);
    }

    /// Turns a parameter error into a scene error in `file`.
    fn pe(&self, file: usize) -> impl Fn(ParseError) -> SceneError {
        let path = self.files[file].clone();
        move |e| SceneError::At {
            file: path.clone(),
            line: e.line,
            message: e.message,
        }
    }

    fn resolve(&self, name: &str) -> PathBuf {
        let p = Path::new(name);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }

    fn run_file(&mut self, path: &Path, from: Option<Loc>) -> Result<(), SceneError> {
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

    fn directive(&mut self, file: usize, d: Directive) -> Result<(), SceneError> {
        let loc = Loc { file, line: d.line };
        let pe = self.pe(file);
        let name = d.name.as_str();
        let needs_world = matches!(
            name,
            "Shape"
                | "Material"
                | "MakeNamedMaterial"
                | "NamedMaterial"
                | "Texture"
                | "LightSource"
                | "AreaLightSource"
                | "AttributeBegin"
                | "AttributeEnd"
                | "ObjectBegin"
                | "ObjectEnd"
                | "ObjectInstance"
                | "ReverseOrientation"
        );
        if needs_world && !self.world {
            return Err(self.at(loc, format!("{name} before WorldBegin")));
        }
        let before_world = matches!(
            name,
            "Camera" | "Film" | "Sampler" | "PixelFilter" | "Integrator" | "Accelerator"
        );
        if before_world && self.world {
            return Err(self.at(loc, format!("{name} after WorldBegin")));
        }
        match name {
            "WorldBegin" => {
                if self.world {
                    return Err(self.at(loc, "a second WorldBegin"));
                }
                self.world = true;
                self.state.ctm = DMat4::IDENTITY;
                self.named_coordinates
                    .insert("world".into(), DMat4::IDENTITY);
            }
            "WorldEnd" => {}
            "AttributeBegin" | "TransformBegin" => {
                let block = if name == "AttributeBegin" {
                    Block::Attribute
                } else {
                    Block::Transform
                };
                self.stack.push((block, loc, self.state.clone()));
            }
            "AttributeEnd" | "TransformEnd" => {
                let block = if name == "AttributeEnd" {
                    Block::Attribute
                } else {
                    Block::Transform
                };
                match self.stack.pop() {
                    None => return Err(self.at(loc, format!("unbalanced {name}: nothing is open"))),
                    Some((open, _, saved)) if open == block => {
                        if block == Block::Attribute {
                            self.state = saved;
                        } else {
                            self.state.ctm = saved.ctm;
                        }
                    }
                    Some((open, open_loc, _)) => {
                        let what = match open {
                            Block::Attribute => "AttributeBegin",
                            Block::Transform => "TransformBegin",
                            Block::Object => "ObjectBegin",
                        };
                        return Err(self.at(
                            loc,
                            format!(
                                "{name} closes the {what} of {}:{}",
                                self.files[open_loc.file].display(),
                                open_loc.line
                            ),
                        ));
                    }
                }
            }
            "Identity" => self.set_ctm(DMat4::IDENTITY),
            "Translate" => {
                let v = d.num_args();
                self.concat(DMat4::from_translation(DVec3::new(v[0], v[1], v[2])));
            }
            "Scale" => {
                let v = d.num_args();
                self.concat(DMat4::from_scale(DVec3::new(v[0], v[1], v[2])));
            }
            "Rotate" => {
                let v = d.num_args();
                let axis = DVec3::new(v[1], v[2], v[3]);
                if axis.length_squared() == 0.0 {
                    return Err(self.at(loc, "Rotate about a zero axis"));
                }
                self.concat(DMat4::from_axis_angle(axis.normalize(), v[0].to_radians()));
            }
            "LookAt" => {
                let v = d.num_args();
                let m = look_at(
                    DVec3::new(v[0], v[1], v[2]),
                    DVec3::new(v[3], v[4], v[5]),
                    DVec3::new(v[6], v[7], v[8]),
                )
                .ok_or_else(|| self.at(loc, "LookAt: the eye, target and up are degenerate"))?;
                self.concat(m);
            }
            "Transform" | "ConcatTransform" => {
                let v = d.num_args();
                let mut a = [0.0; 16];
                a.copy_from_slice(&v);
                // pbrt lists the matrix column by column (the translation last).
                let m = DMat4::from_cols_array(&a);
                if m.determinant() == 0.0 {
                    return Err(self.at(loc, format!("{name}: the matrix is singular")));
                }
                if name == "Transform" {
                    self.set_ctm(m);
                } else {
                    self.concat(m);
                }
            }
            "CoordinateSystem" => {
                self.named_coordinates
                    .insert(d.str_arg(0).to_string(), self.state.ctm);
            }
            "CoordSysTransform" => match self.named_coordinates.get(d.str_arg(0)) {
                Some(&m) => self.state.ctm = m,
                None => {
                    let msg = format!("CoordSysTransform: no coordinate system '{}'", d.str_arg(0));
                    self.warn(loc, msg);
                }
            },
            "ActiveTransform" => {
                if !self.motion_warned {
                    self.motion_warned = true;
                    self.warn(
                        loc,
                        "ActiveTransform: no motion blur; only the start transform is used",
                    );
                }
                self.ignore_transforms = d.str_arg(0) == "EndTime";
            }
            "TransformTimes" => {}
            "ReverseOrientation" => {
                self.state.reverse_orientation = !self.state.reverse_orientation
            }
            "Camera" => self.camera(loc, &d)?,
            "Film" => {
                let x = d.params.int("xresolution", 1280).map_err(&pe)?;
                let y = d.params.int("yresolution", 720).map_err(&pe)?;
                if !(1..=65536).contains(&x) || !(1..=65536).contains(&y) {
                    return Err(self.at(loc, format!("Film: resolution {x}x{y} is not positive")));
                }
                self.resolution = Some([x as u32, y as u32]);
                d.params.string("filename").map_err(&pe)?;
            }
            "Integrator" => {
                let depth = d.params.int("maxdepth", 5).map_err(&pe)?;
                if depth < 0 {
                    return Err(self.at(loc, format!("Integrator: maxdepth {depth} is negative")));
                }
                // pbrt counts bounces; vmerge counts a path's segments, one more.
                self.max_path_length = Some(depth as u32 + 1);
                d.params.mark_all_used();
                self.ignored_directives
                    .insert("Integrator (but maxdepth)".into());
            }
            "Sampler" | "PixelFilter" | "Accelerator" | "ColorSpace" | "Option"
            | "MakeNamedMedium" | "MediumInterface" | "Attribute" => {
                d.params.mark_all_used();
                self.ignored_directives.insert(name.to_string());
            }
            "Include" | "Import" => {
                let path = self.resolve(d.str_arg(0));
                self.run_file(&path, Some(loc))?;
            }
            "MakeNamedMaterial" => {
                let mat_name = d.str_arg(0).to_string();
                let ty = d
                    .params
                    .string("type")
                    .map_err(&pe)?
                    .ok_or_else(|| {
                        self.at(
                            loc,
                            format!("MakeNamedMaterial '{mat_name}' has no \"string type\""),
                        )
                    })?
                    .to_string();
                if self.named_materials.contains_key(&mat_name) {
                    self.warn(loc, format!("MakeNamedMaterial: '{mat_name}' redefined"));
                }
                let index = self.material(loc, &ty, &mat_name, &d.params)?;
                self.named_materials.insert(mat_name, index);
            }
            "Material" => {
                let ty = d.str_arg(0).to_string();
                let label = format!("{ty} ({}:{})", self.files[file].display(), d.line);
                let index = self.material(loc, &ty, &label, &d.params)?;
                self.state.material = Some(index);
            }
            "NamedMaterial" => match self.named_materials.get(d.str_arg(0)) {
                Some(&m) => self.state.material = Some(m),
                None => {
                    return Err(self.at(
                        loc,
                        format!("NamedMaterial: no material named '{}'", d.str_arg(0)),
                    ))
                }
            },
            "Texture" => self.texture(loc, &d)?,
            "AreaLightSource" => {
                if d.str_arg(0) != "diffuse" {
                    return Err(self.at(
                        loc,
                        format!("AreaLightSource '{}' is unknown (diffuse)", d.str_arg(0)),
                    ));
                }
                let l = self.spectrum(loc, &d.params, "L", Rgb::WHITE)?;
                let scale = d.params.float("scale", 1.0).map_err(&pe)?;
                if d.params.bool("twosided", false).map_err(&pe)? {
                    self.warn(
                        loc,
                        "AreaLightSource: twosided is not supported; emits on the front side only",
                    );
                }
                if d.params.string("filename").map_err(&pe)?.is_some() {
                    self.warn(
                        loc,
                        "AreaLightSource: image emission is not supported; uses L",
                    );
                }
                self.state.area_light = Some(AreaLight {
                    radiance: l * scale,
                    loc,
                });
            }
            "LightSource" => self.light_source(loc, &d)?,
            "Shape" => self.shape(loc, &d)?,
            "ObjectBegin" => {
                if self.current_object.is_some() {
                    return Err(self.at(loc, "ObjectBegin inside another object"));
                }
                self.stack.push((Block::Object, loc, self.state.clone()));
                self.current_object = Some((d.str_arg(0).to_string(), Vec::new()));
            }
            "ObjectEnd" => match self.stack.pop() {
                Some((Block::Object, _, saved)) => {
                    self.state = saved;
                    if let Some((name, shapes)) = self.current_object.take() {
                        self.objects.insert(name, shapes);
                    }
                }
                _ => return Err(self.at(loc, "unbalanced ObjectEnd: no object is open")),
            },
            "ObjectInstance" => {
                if self.current_object.is_some() {
                    return Err(self.at(loc, "ObjectInstance inside an object definition"));
                }
                let Some(shapes) = self.objects.get(d.str_arg(0)) else {
                    return Err(self.at(
                        loc,
                        format!("ObjectInstance: no object named '{}'", d.str_arg(0)),
                    ));
                };
                let ctm = self.state.ctm;
                let instanced: Vec<_> = shapes
                    .iter()
                    .map(|s| ShapeRecord {
                        ctm: ctm * s.ctm,
                        ..s.clone()
                    })
                    .collect();
                self.shapes.extend(instanced);
            }
            _ => {
                self.warn(loc, format!("unknown directive '{name}' skipped"));
            }
        }
        let unused: Vec<_> = d
            .params
            .unused()
            .map(|p| {
                (
                    p.line,
                    format!("{name}: parameter \"{} {}\" ignored", p.ty.name(), p.name),
                )
            })
            .collect();
        for (line, msg) in unused {
            self.warn(Loc { file, line }, msg);
        }
        Ok(())
    }

    fn set_ctm(&mut self, m: DMat4) {
        if !self.ignore_transforms {
            self.state.ctm = m;
        }
    }

    fn concat(&mut self, m: DMat4) {
        if !self.ignore_transforms {
            self.state.ctm *= m;
        }
    }

    fn camera(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        if d.str_arg(0) != "perspective" {
            return Err(self.at(
                loc,
                format!(
                    "Camera '{}' is not supported (perspective only)",
                    d.str_arg(0)
                ),
            ));
        }
        let fov = d.params.float("fov", 90.0).map_err(&pe)?;
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.at(loc, format!("Camera: fov {fov} is not in (0, 180) degrees")));
        }
        if d.params.float("lensradius", 0.0).map_err(&pe)? > 0.0 {
            self.warn(
                loc,
                "Camera: lensradius ignored (a pinhole camera, no depth of field)",
            );
        }
        d.params.float("focaldistance", 1e6).map_err(&pe)?;
        let world_from_camera = self.state.ctm.inverse();
        if !world_from_camera.is_finite() {
            return Err(self.at(loc, "Camera: the camera transform is singular"));
        }
        self.named_coordinates
            .insert("camera".into(), world_from_camera);
        let position = world_from_camera.transform_point3(DVec3::ZERO);
        let forward = world_from_camera.transform_vector3(DVec3::Z).normalize();
        let up = world_from_camera.transform_vector3(DVec3::Y).normalize();
        let right = world_from_camera.transform_vector3(DVec3::X);
        // vmerge's camera puts forward x up on the image's right; pbrt puts camera-space +x
        // there, which is the opposite side unless the transform swaps handedness.
        let mirrored = forward.cross(up).dot(right) < 0.0;
        self.camera = Some(CameraDesc {
            name: "camera".into(),
            position: position.as_vec3(),
            look_at: (position + forward).as_vec3(),
            up: up.as_vec3(),
            fov_deg: fov,
            fov_axis: FovAxis::Shorter,
            mirrored,
        });
        Ok(())
    }

    /// An RGB value for a spectrum parameter, with a warning where it is approximated.
    fn spectrum(
        &mut self,
        loc: Loc,
        params: &ParamList,
        name: &str,
        default: Rgb,
    ) -> Result<Rgb, SceneError> {
        let Some((s, line)) = params.spectrum(name).map_err(self.pe(loc.file))? else {
            return Ok(default);
        };
        self.spectrum_value(Loc { line, ..loc }, name, s)
    }

    fn spectrum_value(&mut self, loc: Loc, name: &str, s: Spectrum) -> Result<Rgb, SceneError> {
        let rgb = match s {
            Spectrum::Rgb(v) => Rgb::from_array(v),
            Spectrum::Named(n) => match named_spectrum(&n) {
                Some(c) => c,
                None => {
                    self.warn(
                        loc,
                        format!("'{name}': unknown named spectrum '{n}'; grey 1 used"),
                    );
                    Rgb::WHITE
                }
            },
            Spectrum::Blackbody(t) => {
                self.warn(
                    loc,
                    format!("'{name}': blackbody {t} K approximated as white"),
                );
                Rgb::WHITE
            }
            Spectrum::Sampled(v) => {
                let values: Vec<f32> = v.chunks_exact(2).map(|p| p[1]).collect();
                let mean = values.iter().sum::<f32>() / values.len().max(1) as f32;
                self.warn(
                    loc,
                    format!("'{name}': sampled spectrum approximated by its mean {mean}"),
                );
                Rgb::splat(mean)
            }
        };
        if !rgb.is_finite() || rgb.min_component() < 0.0 {
            return Err(self.at(loc, format!("'{name}' {:?} is negative", rgb.to_array())));
        }
        Ok(rgb)
    }

    fn texture(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let (name, ty, class) = (d.str_arg(0), d.str_arg(1), d.str_arg(2));
        let spectrum = match ty {
            "spectrum" | "color" => true,
            "float" => false,
            other => {
                return Err(self.at(
                    loc,
                    format!("Texture '{name}': type '{other}' is neither spectrum nor float"),
                ))
            }
        };
        let p = &d.params;
        let tex = match class {
            "imagemap" => {
                let file = p.string("filename").map_err(&pe)?.ok_or_else(|| {
                    self.at(
                        loc,
                        format!("Texture '{name}': imagemap without a filename"),
                    )
                })?;
                let scale = p.float("scale", 1.0).map_err(&pe)?;
                if p.bool("invert", false).map_err(&pe)? {
                    self.warn(loc, format!("Texture '{name}': invert ignored"));
                }
                p.mark_used(&["filter", "wrap", "encoding", "maxanisotropy"]);
                let path = self.resolve(file);
                if path.exists() {
                    Tex::Image {
                        path,
                        scale: Rgb::splat(scale),
                        loc,
                    }
                } else if self.lenient {
                    self.warn(
                        loc,
                        format!(
                            "Texture '{name}': {} is missing; its materials use their constant instead",
                            path.display()
                        ),
                    );
                    Tex::Missing
                } else {
                    return Err(self.at(
                        loc,
                        format!(
                            "Texture '{name}': {} is missing (use {} to render with the material's constant)",
                            path.display(),
                            OptionName("lenient")
                        ),
                    ));
                }
            }
            "constant" if spectrum => Tex::Constant(self.spectrum(loc, p, "value", Rgb::WHITE)?),
            "constant" => {
                let v = p.float("value", 1.0).map_err(&pe)?;
                self.float_textures
                    .insert(name.to_string(), FloatTex::Constant(v));
                return Ok(());
            }
            "scale" if spectrum => {
                let base = self.spectrum_texture(loc, p, "tex", Rgb::WHITE)?;
                let scale = match p.float_texture("scale").map_err(&pe)? {
                    None => 1.0,
                    Some((TexOr::Value(v), _)) => v,
                    Some((TexOr::Texture(t), line)) => {
                        self.warn(
                            Loc { line, ..loc },
                            format!(
                                "Texture '{name}': scale by texture '{t}' not supported; 1 used"
                            ),
                        );
                        1.0
                    }
                };
                match base {
                    Tex::Constant(c) => Tex::Constant(c * scale),
                    Tex::Image {
                        path,
                        scale: s,
                        loc,
                    } => Tex::Image {
                        path,
                        scale: s * scale,
                        loc,
                    },
                    Tex::Missing => Tex::Missing,
                }
            }
            other => {
                self.warn(
                    loc,
                    format!("Texture '{name}': class '{other}' not supported; grey 0.5 used"),
                );
                p.mark_all_used();
                if spectrum {
                    Tex::Constant(Rgb::splat(0.5))
                } else {
                    self.float_textures
                        .insert(name.to_string(), FloatTex::Constant(0.5));
                    return Ok(());
                }
            }
        };
        if spectrum {
            self.textures.insert(name.to_string(), tex);
        } else {
            self.float_textures
                .insert(name.to_string(), FloatTex::Image);
        }
        Ok(())
    }

    /// A spectrum parameter that may name a texture.
    fn spectrum_texture(
        &mut self,
        loc: Loc,
        params: &ParamList,
        name: &str,
        default: Rgb,
    ) -> Result<Tex, SceneError> {
        match params.spectrum_texture(name).map_err(self.pe(loc.file))? {
            None => Ok(Tex::Constant(default)),
            Some((TexOr::Value(s), line)) => Ok(Tex::Constant(self.spectrum_value(
                Loc { line, ..loc },
                name,
                s,
            )?)),
            Some((TexOr::Texture(t), line)) => match self.textures.get(&t) {
                Some(tex) => Ok(tex.clone()),
                None => Err(self.at(
                    Loc { line, ..loc },
                    format!("'{name}': no spectrum texture named '{t}'"),
                )),
            },
        }
    }

    /// A float parameter that may name a texture (only constants are followed).
    fn float_param(
        &mut self,
        loc: Loc,
        params: &ParamList,
        name: &str,
        default: f32,
    ) -> Result<Option<f32>, SceneError> {
        match params.float_texture(name).map_err(self.pe(loc.file))? {
            None => Ok(None),
            Some((TexOr::Value(v), _)) => Ok(Some(v)),
            Some((TexOr::Texture(t), line)) => match self.float_textures.get(&t) {
                Some(FloatTex::Constant(v)) => Ok(Some(*v)),
                Some(FloatTex::Image) => {
                    self.warn(
                        Loc { line, ..loc },
                        format!(
                            "'{name}': float image texture '{t}' not supported; {default} used"
                        ),
                    );
                    Ok(Some(default))
                }
                None => Err(self.at(
                    Loc { line, ..loc },
                    format!("'{name}': no float texture named '{t}'"),
                )),
            },
        }
    }

    /// The microfacet alpha of a material's `roughness` (or the mean of `uroughness` and
    /// `vroughness`), remapped as pbrt does unless `remaproughness` is false.
    fn alpha(&mut self, loc: Loc, params: &ParamList) -> Result<f32, SceneError> {
        let r = self.float_param(loc, params, "roughness", 0.0)?;
        let u = self.float_param(loc, params, "uroughness", 0.0)?;
        let v = self.float_param(loc, params, "vroughness", 0.0)?;
        let roughness = match (u, v) {
            (None, None) => r.unwrap_or(0.0),
            (u, v) => {
                let (u, v) = (u.or(r).unwrap_or(0.0), v.or(r).unwrap_or(0.0));
                if (u - v).abs() > 1e-6 {
                    self.warn(loc, format!("anisotropic roughness ({u}, {v}) averaged"));
                }
                0.5 * (u + v)
            }
        };
        if !(roughness >= 0.0 && roughness.is_finite()) {
            return Err(self.at(loc, format!("roughness {roughness} is negative")));
        }
        let remap = params
            .bool("remaproughness", true)
            .map_err(self.pe(loc.file))?;
        Ok(if remap {
            material::roughness_to_alpha(roughness)
        } else {
            roughness
        })
    }

    /// Maps a pbrt material onto vmerge's BSDFs (README, "pbrt-v4 scenes"); one warning per
    /// material that is approximated.
    fn material(
        &mut self,
        loc: Loc,
        ty: &str,
        name: &str,
        p: &ParamList,
    ) -> Result<u32, SceneError> {
        let pe = self.pe(loc.file);
        let mut notes: Vec<String> = Vec::new();
        let mut texture = None;
        let mut albedo =
            |im: &mut Importer, param: &str, default: Rgb| -> Result<Rgb, SceneError> {
                Ok(match im.spectrum_texture(loc, p, param, default)? {
                    Tex::Constant(c) => c,
                    Tex::Image { path, scale, loc } => {
                        texture = Some((path, scale, loc));
                        default
                    }
                    Tex::Missing => default,
                })
            };
        // What the mapping multiplies the reflectance by, applied to a texture's texels too.
        let mut factor = Rgb::WHITE;
        let kind = match ty {
            "diffuse" => MaterialKind::Lambert {
                kd: albedo(self, "reflectance", Rgb::splat(0.5))?,
            },
            "coateddiffuse" => {
                let reflectance = albedo(self, "reflectance", Rgb::splat(0.5))?;
                let eta = self.float_param(loc, p, "eta", 1.5)?.unwrap_or(1.5);
                let alpha = self.alpha(loc, p)?;
                let f0 = dielectric_f0(eta);
                // The coating's layer parameters have no counterpart in Phong.
                p.mark_used(&["thickness", "g", "maxdepth", "nsamples", "albedo"]);
                let exponent = phong_exponent(alpha);
                notes.push(format!(
                    "coateddiffuse as Phong: kd = reflectance x (1 - F0), ks = F0 = {f0:.3}, exponent {exponent:.0} from alpha {alpha}"
                ));
                factor = Rgb::splat(1.0 - f0);
                MaterialKind::Phong {
                    kd: reflectance * (1.0 - f0),
                    ks: Rgb::splat(f0),
                    exponent,
                }
            }
            "conductor" => {
                let alpha = self.alpha(loc, p)?;
                let f0 = if p.params.iter().any(|q| q.name == "reflectance") {
                    self.constant_spectrum(loc, p, "reflectance", Rgb::WHITE)?
                } else {
                    let cu = |n| named_spectrum(n).unwrap_or(Rgb::WHITE);
                    let eta = self.constant_spectrum(loc, p, "eta", cu("metal-Cu-eta"))?;
                    let k = self.constant_spectrum(loc, p, "k", cu("metal-Cu-k"))?;
                    conductor_f0(eta, k)
                };
                if alpha == 0.0 {
                    MaterialKind::Mirror { ks: f0 }
                } else {
                    let exponent = phong_exponent(alpha);
                    notes.push(format!(
                        "rough conductor as Phong: ks = F0 = {:?}, exponent {exponent:.0} from alpha {alpha}",
                        round3(f0)
                    ));
                    MaterialKind::Phong {
                        kd: Rgb::BLACK,
                        ks: f0,
                        exponent,
                    }
                }
            }
            "dielectric" | "thindielectric" => {
                let eta_type = p.params.iter().find(|q| q.name == "eta").map(|q| q.ty);
                let spectral = matches!(
                    eta_type,
                    Some(ParamType::Rgb | ParamType::Spectrum | ParamType::Blackbody)
                );
                let eta = if !spectral {
                    self.float_param(loc, p, "eta", 1.5)?.unwrap_or(1.5)
                } else {
                    match p.spectrum("eta").map_err(&pe)? {
                        Some((Spectrum::Named(n), line)) => match named_spectrum(&n) {
                            Some(c) => c.average(),
                            None => {
                                let msg = format!("unknown named spectrum '{n}'; eta 1.5");
                                self.warn(Loc { line, ..loc }, msg);
                                1.5
                            }
                        },
                        Some((s, line)) => self
                            .spectrum_value(Loc { line, ..loc }, "eta", s)?
                            .average(),
                        None => 1.5,
                    }
                };
                if eta.is_nan() || eta <= 0.0 {
                    return Err(self.at(loc, format!("dielectric eta {eta} is not positive")));
                }
                if self.alpha(loc, p)? > 0.0 {
                    notes.push("rough dielectric as smooth glass".into());
                }
                if ty == "thindielectric" {
                    notes.push("thindielectric as glass".into());
                }
                MaterialKind::Glass { ior: eta }
            }
            "diffusetransmission" => {
                let reflectance = albedo(self, "reflectance", Rgb::splat(0.25))?;
                let scale = p.float("scale", 1.0).map_err(&pe)?;
                p.mark_used(&["transmittance"]);
                notes.push(
                    "diffusetransmission as lambert of its reflectance (no transmission)".into(),
                );
                factor = Rgb::splat(scale);
                MaterialKind::Lambert {
                    kd: reflectance * scale,
                }
            }
            "coatedconductor" | "measured" | "mix" | "hair" | "subsurface" | "interface" => {
                let kd = match p.params.iter().any(|q| q.name == "reflectance") {
                    true => albedo(self, "reflectance", Rgb::splat(0.5))?,
                    false => Rgb::splat(0.5),
                };
                p.mark_all_used();
                notes.push(format!("'{ty}' as lambert of kd {:?}", round3(kd)));
                MaterialKind::Lambert { kd }
            }
            other => {
                return Err(self.at(loc, format!("unknown material type '{other}'")));
            }
        };
        for ignored in ["displacement", "normalmap"] {
            if p.params.iter().any(|q| q.name == ignored) {
                p.mark_used(&[ignored]);
                notes.push(format!("{ignored} ignored"));
            }
        }
        let kind = clamp_reflectance(&mut notes, kind);
        if !notes.is_empty() {
            self.warn(loc, format!("material '{name}': {}", notes.join("; ")));
        }
        let origin = Origin {
            file: self.files[loc.file].clone(),
            line: Some(loc.line),
            entry: format!("material '{name}'"),
        };
        let material = Material {
            name: name.to_string(),
            kind,
            emission: Rgb::BLACK,
        };
        let index = self.builder.material(&origin, material)?;
        self.material_textures
            .push(texture.map(|(path, scale, loc)| (path, scale * factor, loc)));
        Ok(index)
    }

    /// A spectrum parameter given as a value, a float, or a constant texture; image textures
    /// are not followed here (a warning, and `fallback`).
    fn constant_spectrum(
        &mut self,
        loc: Loc,
        p: &ParamList,
        name: &str,
        fallback: Rgb,
    ) -> Result<Rgb, SceneError> {
        if let Some(q) = p.params.iter().find(|q| q.name == name) {
            if q.ty == ParamType::Float {
                let v = p.float(name, 1.0).map_err(self.pe(loc.file))?;
                return Ok(Rgb::splat(v));
            }
        }
        match self.spectrum_texture(loc, p, name, fallback)? {
            Tex::Constant(c) => Ok(c),
            _ => {
                self.warn(
                    loc,
                    format!(
                        "'{name}' from an image texture not supported; {:?} used",
                        round3(fallback)
                    ),
                );
                Ok(fallback)
            }
        }
    }

    fn current_material(&mut self) -> Result<u32, SceneError> {
        if let Some(m) = self.state.material {
            return Ok(m);
        }
        if let Some(m) = self.default_material {
            return Ok(m);
        }
        // pbrt's default material.
        let origin = Origin {
            file: self.files[0].clone(),
            line: None,
            entry: "(default diffuse)".into(),
        };
        let material = Material {
            name: "(default diffuse)".into(),
            kind: MaterialKind::Lambert {
                kd: Rgb::splat(0.5),
            },
            emission: Rgb::BLACK,
        };
        let index = self.builder.material(&origin, material)?;
        self.material_textures.push(None);
        self.default_material = Some(index);
        Ok(index)
    }

    /// The material shapes get now: the current one, emissive when an area light is set.
    fn shape_material(&mut self) -> Result<u32, SceneError> {
        let base = self.current_material()?;
        let Some(light) = self.state.area_light.clone() else {
            return Ok(base);
        };
        if light.radiance.is_black() {
            return Ok(base);
        }
        let key = (base, light.radiance.to_array().map(f32::to_bits));
        if let Some(&m) = self.emissive.get(&key) {
            return Ok(m);
        }
        let name = format!(
            "{} + AreaLightSource ({}:{})",
            self.builder.material_at(base).name,
            self.files[light.loc.file].display(),
            light.loc.line
        );
        let index = self.builder.variant(base, name, light.radiance);
        self.material_textures
            .push(self.material_textures[base as usize].clone());
        self.emissive.insert(key, index);
        Ok(index)
    }

    fn light_source(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let p = &d.params;
        let scale = p.float("scale", 1.0).map_err(&pe)?;
        for ignored in ["power", "illuminance"] {
            if p.float(ignored, -1.0).map_err(&pe)? > 0.0 {
                self.warn(
                    loc,
                    format!("LightSource: '{ignored}' not supported; scale used"),
                );
            }
        }
        let ctm = self.state.ctm;
        match d.str_arg(0) {
            "point" => {
                let intensity = self.spectrum(loc, p, "I", Rgb::WHITE)? * scale;
                let from = DVec3::from_array(p.vec3("from", [0.0; 3]).map_err(&pe)?);
                self.lights.push(Light::Point {
                    position: ctm.transform_point3(from).as_vec3(),
                    intensity,
                });
            }
            "distant" => {
                let irradiance = self.spectrum(loc, p, "L", Rgb::WHITE)? * scale;
                let from = DVec3::from_array(p.vec3("from", [0.0; 3]).map_err(&pe)?);
                let to = DVec3::from_array(p.vec3("to", [0.0, 0.0, 1.0]).map_err(&pe)?);
                let dir = ctm.transform_vector3(to - from);
                if dir.length_squared() == 0.0 {
                    return Err(self.at(loc, "LightSource distant: from and to coincide"));
                }
                self.lights.push(Light::Directional {
                    direction: dir.normalize().as_vec3(),
                    irradiance,
                    scene: SceneBounds::new(Vec3::ZERO, Vec3::ONE),
                });
            }
            "infinite" => {
                if self.sky.is_some() || self.env_image.is_some() {
                    self.warn(loc, "a second infinite light ignored");
                    p.mark_all_used();
                    return Ok(());
                }
                let file = p.string("filename").map_err(&pe)?.map(str::to_string);
                let l = self.spectrum(loc, p, "L", Rgb::WHITE)? * scale;
                match file {
                    Some(file) => {
                        let path = self.resolve(&file);
                        if path.exists() {
                            self.env_image = Some((path, scale, ctm, loc));
                        } else if self.lenient {
                            self.warn(
                                loc,
                                format!(
                                    "LightSource infinite: {} is missing; a constant sky of radiance {scale} instead",
                                    path.display()
                                ),
                            );
                            self.sky = Some(constant_sky(Rgb::splat(scale)));
                        } else {
                            return Err(self.at(
                                loc,
                                format!(
                                    "LightSource infinite: {} is missing (use {} for a constant sky)",
                                    path.display(),
                                    OptionName("lenient")
                                ),
                            ));
                        }
                    }
                    None => self.sky = Some(constant_sky(l)),
                }
            }
            other @ ("spot" | "goniometric" | "projection") => {
                self.warn(loc, format!("LightSource '{other}' not supported; skipped"));
                p.mark_all_used();
            }
            other => {
                return Err(self.at(loc, format!("LightSource '{other}' is unknown")));
            }
        }
        Ok(())
    }

    fn shape(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let p = &d.params;
        let kind = match d.str_arg(0) {
            "trianglemesh" => {
                let mesh = inline_mesh(p, false).map_err(&pe)?;
                ShapeKind::Mesh(Arc::new(MeshSource::Inline(Arc::new(mesh))))
            }
            "bilinearmesh" => {
                let mesh = inline_mesh(p, true).map_err(&pe)?;
                ShapeKind::Mesh(Arc::new(MeshSource::Inline(Arc::new(mesh))))
            }
            "plymesh" => {
                let file = p
                    .string("filename")
                    .map_err(&pe)?
                    .ok_or_else(|| self.at(loc, "Shape plymesh without a filename"))?;
                let path = self.resolve(file);
                ShapeKind::Mesh(Arc::new(MeshSource::Ply(path)))
            }
            "sphere" => {
                let radius = p.float("radius", 1.0).map_err(&pe)?;
                if radius.is_nan() || radius <= 0.0 {
                    return Err(self.at(
                        loc,
                        format!("Shape sphere: radius {radius} is not positive"),
                    ));
                }
                let zmin = p.float("zmin", -radius).map_err(&pe)?;
                let zmax = p.float("zmax", radius).map_err(&pe)?;
                let phimax = p.float("phimax", 360.0).map_err(&pe)?;
                if zmin > -radius || zmax < radius || phimax < 360.0 {
                    self.warn(loc, "Shape sphere: partial spheres rendered whole");
                }
                ShapeKind::Sphere {
                    radius: radius as f64,
                }
            }
            other @ ("disk" | "cylinder" | "loopsubdiv" | "curve" | "bilinearpatch") => {
                self.warn(loc, format!("Shape '{other}' not supported; skipped"));
                p.mark_all_used();
                return Ok(());
            }
            other => return Err(self.at(loc, format!("unknown shape '{other}'"))),
        };
        if p.params.iter().any(|q| q.name == "alpha") {
            p.mark_used(&["alpha"]);
            self.warn(loc, "Shape: alpha (cut-outs) ignored");
        }
        let material = self.shape_material()?;
        let record = ShapeRecord {
            kind,
            ctm: self.state.ctm,
            reverse_orientation: self.state.reverse_orientation,
            material,
            loc,
        };
        match &mut self.current_object {
            Some((_, shapes)) => shapes.push(record),
            None => self.shapes.push(record),
        }
        Ok(())
    }

    /// Reads the PLY files (in parallel, each once), then lays all shapes out in order.
    fn finish(mut self) -> Result<SceneParts, SceneError> {
        let mut first_use: HashMap<PathBuf, Loc> = HashMap::new();
        for s in &self.shapes {
            if let ShapeKind::Mesh(m) = &s.kind {
                if let MeshSource::Ply(path) = &**m {
                    first_use.entry(path.clone()).or_insert(s.loc);
                }
            }
        }
        let mut paths: Vec<_> = first_use.keys().cloned().collect();
        paths.sort();
        let loaded: Vec<_> = paths
            .par_iter()
            .map(|path| {
                if !path.exists() {
                    return Err(None::<FileError>);
                }
                let bytes = files::read(path, Kind::Ply).map_err(Some)?;
                Ok((Sha256::digest(&bytes), ply::parse(&bytes)))
            })
            .collect();
        let mut meshes: HashMap<PathBuf, Arc<PlyMesh>> = HashMap::new();
        for (path, result) in paths.iter().zip(loaded) {
            let loc = first_use[path];
            match result {
                Ok((hash, Ok(mesh))) => {
                    self.builder.input_digest(path, &hash);
                    meshes.insert(path.clone(), Arc::new(mesh));
                }
                Ok((_, Err(message))) => {
                    return Err(self.at(loc, format!("Shape plymesh {}: {message}", path.display())))
                }
                Err(None) if self.lenient => {
                    self.warn(
                        loc,
                        format!("Shape plymesh: {} is missing; skipped", path.display()),
                    );
                }
                Err(None) => {
                    return Err(self.at(
                        loc,
                        format!(
                            "Shape plymesh: cannot read {}: it is missing (use {} to skip it)",
                            path.display(),
                            OptionName("lenient")
                        ),
                    ))
                }
                Err(Some(e)) => return Err(self.at(loc, format!("Shape plymesh: {e}"))),
            }
        }
        let mut geometry = Geometry::default();
        let mut triangle_materials = Vec::new();
        let mut sphere_materials = Vec::new();
        let mut shading = MeshShading::default();
        let mut dropped = 0usize;
        let shapes = std::mem::take(&mut self.shapes);
        for s in &shapes {
            match &s.kind {
                ShapeKind::Sphere { radius } => {
                    let center = s.ctm.transform_point3(DVec3::ZERO);
                    let m = DMat3::from_mat4(s.ctm);
                    let scales = [m.x_axis.length(), m.y_axis.length(), m.z_axis.length()];
                    let mean = (scales[0] + scales[1] + scales[2]) / 3.0;
                    if scales.iter().any(|&x| (x - mean).abs() > 1e-4 * mean) {
                        self.warn(
                            s.loc,
                            "Shape sphere: non-uniform scale; the mean scale used",
                        );
                    }
                    if s.reverse_orientation && self.builder.material_at(s.material).is_emissive() {
                        self.warn(
                            s.loc,
                            "Shape sphere: ReverseOrientation ignored; emits outwards",
                        );
                    }
                    let (center, radius) = (center.as_vec3(), (radius * mean) as f32);
                    let reach = center.abs().max_element() + radius;
                    if !reach.is_finite() || reach > MAX_COORDINATE {
                        return Err(self.at(
                            s.loc,
                            format!("Shape sphere: centre {center}, radius {radius} reaches beyond +-{MAX_COORDINATE:e}"),
                        ));
                    }
                    geometry.spheres.push(Sphere { center, radius });
                    sphere_materials.push(s.material);
                }
                ShapeKind::Mesh(source) => {
                    let mesh = match &**source {
                        MeshSource::Inline(m) => Arc::clone(m),
                        MeshSource::Ply(path) => match meshes.get(path) {
                            Some(m) => Arc::clone(m),
                            None => continue,
                        },
                    };
                    let first = geometry.positions.len();
                    dropped += place_mesh(
                        &mesh,
                        s,
                        &mut geometry,
                        &mut triangle_materials,
                        &mut shading,
                    );
                    if let Some(p) = geometry.positions[first..]
                        .iter()
                        .find(|p| !p.is_finite() || p.abs().max_element() > MAX_COORDINATE)
                    {
                        return Err(self.at(
                            s.loc,
                            format!("Shape: vertex {p} (after the transform) lies beyond +-{MAX_COORDINATE:e}, where f32 positions lose their precision"),
                        ));
                    }
                }
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

    /// Decodes the materials' images (in parallel, each file once) and gives each material its
    /// texture: the image times the material's factor (a scaled copy where that is not 1).
    fn load_textures(&mut self) -> Result<(), SceneError> {
        let mut paths: Vec<PathBuf> = self
            .material_textures
            .iter()
            .flatten()
            .map(|(p, _, _)| p.clone())
            .collect();
        paths.sort();
        paths.dedup();
        let decoded = self.builder.images(&paths);
        let mut images = HashMap::new();
        for (path, result) in paths.iter().zip(decoded) {
            match result {
                Ok(image) => {
                    images.insert(path.clone(), image);
                }
                Err(message) => {
                    let loc = self
                        .material_textures
                        .iter()
                        .flatten()
                        .find(|(p, _, _)| p == path)
                        .map_or(Loc { file: 0, line: 1 }, |&(_, _, loc)| loc);
                    if !self.lenient {
                        return Err(self.at(loc, message));
                    }
                    self.warn(loc, format!("{message}; its materials use their constant"));
                }
            }
        }
        let pending = std::mem::take(&mut self.material_textures);
        for (material, entry) in pending.iter().enumerate() {
            let Some((path, factor, _)) = entry else {
                continue;
            };
            let Some(image) = images.get(path) else {
                continue;
            };
            let kd = self.builder.texture(path, image, *factor);
            self.builder.set_textures(
                material as u32,
                MaterialTextures {
                    kd: Some(kd),
                    ks: None,
                },
            );
        }
        Ok(())
    }

    /// The infinite light's image: pbrt-v4's equal-area octahedral square, resampled to the
    /// equirectangular image vmerge's environment light takes, in world space.
    fn env_map(&mut self) -> Result<Option<EnvMapDesc>, SceneError> {
        let Some((path, scale, ctm, loc)) = self.env_image.take() else {
            return Ok(None);
        };
        let read = std::fs::read(&path)
            .map_err(|e| e.to_string())
            .and_then(|bytes| Ok((texture::read(&path)?, bytes)));
        let (image, bytes) = match read {
            Ok(x) => x,
            Err(message) => {
                let message = format!(
                    "LightSource infinite: cannot read {}: {message}",
                    path.display()
                );
                if !self.lenient {
                    return Err(self.at(loc, message));
                }
                self.warn(
                    loc,
                    format!("{message}; a constant sky of radiance {scale} instead"),
                );
                self.sky = Some(constant_sky(Rgb::splat(scale)));
                return Ok(None);
            }
        };
        if image.width != image.height {
            return Err(self.at(
                loc,
                format!(
                    "LightSource infinite: {} is {}x{}, not square (pbrt-v4's environment images are equal-area octahedral squares)",
                    path.display(),
                    image.width,
                    image.height
                ),
            ));
        }
        self.builder.input(&path, &bytes);
        let light_from_world = DMat3::from_mat4(ctm).inverse();
        let resampled = super::envmap::equirect_from_octahedral(&image, light_from_world);
        Ok(Some(EnvMapDesc {
            image: Arc::new(resampled),
            scale,
            rotation: Mat3::IDENTITY,
        }))
    }
}

/// Reflectances above 1 would create energy; pbrt-v4 clamps them to [0, 1] too. (Phong's
/// kd + ks is the builder's rule.)
fn clamp_reflectance(notes: &mut Vec<String>, kind: MaterialKind) -> MaterialKind {
    match kind.energy_excess() {
        Some(excess) if excess.fix == EnergyFix::Clamped => {
            notes.push(format!(
                "reflectance {:?} clamped to 1",
                round3(excess.total)
            ));
            excess.conserving
        }
        _ => kind,
    }
}

fn constant_sky(l: Rgb) -> SkyDesc {
    SkyDesc {
        horizon: l,
        zenith: l,
        up: Vec3::Y,
    }
}

/// pbrt's LookAt: the camera-from-world matrix, `None` when degenerate.
fn look_at(eye: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - eye).try_normalize()?;
    let right = up.try_normalize()?.cross(dir).try_normalize()?;
    let new_up = dir.cross(right);
    let world_from_camera = DMat4::from_cols(
        right.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        eye.extend(1.0),
    );
    Some(world_from_camera.inverse())
}

/// A `trianglemesh` (or, with `bilinear`, a `bilinearmesh` split into two triangles per
/// patch) from its parameters, checked.
fn inline_mesh(p: &ParamList, bilinear: bool) -> Result<PlyMesh, ParseError> {
    let what = if bilinear {
        "bilinearmesh"
    } else {
        "trianglemesh"
    };
    let fail = |line: u32, message: String| ParseError { line, message };
    let (positions, p_line) = p
        .nums("P", &[ParamType::Point3])?
        .ok_or_else(|| fail(0, format!("{what} without \"point3 P\"")))?;
    let n = positions.len() / 3;
    let per_face = if bilinear { 4 } else { 3 };
    let indices: Vec<u32> = match p.nums("indices", &[ParamType::Integer])? {
        Some((v, line)) => {
            if v.len() % per_face != 0 {
                return Err(fail(
                    line,
                    format!(
                        "{what}: {} indices are not a multiple of {per_face}",
                        v.len()
                    ),
                ));
            }
            let mut out = Vec::with_capacity(v.len());
            for &i in v {
                if i < 0.0 || i >= n as f64 {
                    return Err(fail(
                        line,
                        format!("{what}: index {i} out of range (there are {n} vertices)"),
                    ));
                }
                out.push(i as u32);
            }
            out
        }
        None if n == per_face => (0..per_face as u32).collect(),
        None => {
            return Err(fail(
                p_line,
                format!("{what} with {n} vertices needs \"integer indices\""),
            ))
        }
    };
    let normals = match p.nums("N", &[ParamType::Normal])? {
        Some((v, line)) if v.len() != positions.len() => {
            return Err(fail(
                line,
                format!("{what}: {} normals for {n} vertices", v.len() / 3),
            ))
        }
        Some((v, _)) => v
            .chunks_exact(3)
            .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
            .collect(),
        None => Vec::new(),
    };
    let uvs = match p.nums("uv", &[ParamType::Point2])? {
        Some((v, line)) if v.len() / 2 != n => {
            return Err(fail(
                line,
                format!("{what}: {} uvs for {n} vertices", v.len() / 2),
            ))
        }
        Some((v, _)) => v
            .chunks_exact(2)
            .map(|c| [c[0] as f32, c[1] as f32])
            .collect(),
        None => Vec::new(),
    };
    // Per-face indices only matter to pbrt's ptex lookups.
    p.mark_used(&["faceIndices"]);
    let triangles = if bilinear {
        indices
            .chunks_exact(4)
            .flat_map(|q| [[q[0], q[1], q[3]], [q[0], q[3], q[2]]])
            .collect()
    } else {
        indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect()
    };
    Ok(PlyMesh {
        positions: positions
            .chunks_exact(3)
            .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
            .collect(),
        normals,
        uvs,
        triangles,
    })
}

/// Appends a mesh in world space; returns the number of degenerate triangles dropped. Each
/// triangle is wound so that vmerge's normal (counter-clockwise side) is the side pbrt treats
/// as the front: its geometric normal, flipped by ReverseOrientation or a transform that swaps
/// handedness, or turned to the shading normals where the mesh has them.
fn place_mesh(
    mesh: &PlyMesh,
    s: &ShapeRecord,
    geometry: &mut Geometry,
    triangle_materials: &mut Vec<u32>,
    shading: &mut MeshShading,
) -> usize {
    let base = geometry.positions.len() as u32;
    let identity = s.ctm == DMat4::IDENTITY;
    geometry.positions.extend(mesh.positions.iter().map(|&p| {
        let v = Vec3::from_array(p);
        if identity {
            v
        } else {
            s.ctm.transform_point3(v.as_dvec3()).as_vec3()
        }
    }));
    let normal_matrix = DMat3::from_mat4(s.ctm).inverse().transpose();
    let normal_base = shading.normals.len() as u32;
    shading.normals.extend(mesh.normals.iter().map(|&n| {
        let v = Vec3::from_array(n);
        if identity {
            v
        } else {
            (normal_matrix * v.as_dvec3()).normalize_or_zero().as_vec3()
        }
    }));
    let uv_base = shading.uvs.len() as u32;
    shading
        .uvs
        .extend(mesh.uvs.iter().map(|&uv| Vec2::from_array(uv)));
    let flip = s.reverse_orientation ^ (DMat3::from_mat4(s.ctm).determinant() < 0.0);
    let mut dropped = 0;
    for &[a, b, c] in &mesh.triangles {
        let [pa, pb, pc] = [a, b, c].map(|i| geometry.positions[(base + i) as usize]);
        let ng = (pb - pa).cross(pc - pa);
        if ng.length_squared() <= 0.0 {
            dropped += 1;
            continue;
        }
        let front = if mesh.normals.is_empty() {
            if flip {
                -ng
            } else {
                ng
            }
        } else {
            [a, b, c]
                .map(|i| shading.normals[(normal_base + i) as usize])
                .into_iter()
                .sum::<Vec3>()
        };
        let t = if front.dot(ng) < 0.0 {
            [a, c, b]
        } else {
            [a, b, c]
        };
        geometry.triangles.push(t.map(|i| base + i));
        triangle_materials.push(s.material);
        shading.triangle_normals.push(if mesh.normals.is_empty() {
            MeshShading::NONE
        } else {
            t.map(|i| normal_base + i)
        });
        shading.triangle_uvs.push(if mesh.uvs.is_empty() {
            MeshShading::NONE
        } else {
            t.map(|i| uv_base + i)
        });
    }
    dropped
}

#[cfg(test)]
mod tests {
    use super::super::ply::tests::binary_ply;
    use super::*;

    /// Writes `files` (name, contents) to a fresh folder and imports the first.
    fn import_files(
        files: &[(&str, &[u8])],
    ) -> (tempfile::TempDir, Result<SceneParts, SceneError>) {
        let dir = tempfile::tempdir().unwrap();
        for (name, contents) in files {
            std::fs::write(dir.path().join(name), contents).unwrap();
        }
        let result = import(&dir.path().join(files[0].0), false);
        (dir, result)
    }

    fn parts(src: &str) -> SceneParts {
        let (_dir, result) = import_files(&[("scene.pbrt", src.as_bytes())]);
        result.unwrap_or_else(|e| panic!("{e}"))
    }

    fn error(files: &[(&str, &[u8])]) -> String {
        let (_dir, result) = import_files(files);
        match result {
            Err(e) => e.to_string(),
            Ok(_) => panic!("imported without an error"),
        }
    }

    const QUAD: &str =
        "\"point3 P\" [ -1 0 -1  1 0 -1  1 0 1  -1 0 1 ] \"integer indices\" [ 0 1 2 0 2 3 ]";

    #[test]
    fn nested_transforms_and_attributes() {
        let src =
            "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\nWorldBegin\n\
                   AttributeBegin\n  Translate 1 0 0\n  AttributeBegin\n    Scale 2 2 2\n\
                   Shape \"sphere\" \"float radius\" 0.5\n  AttributeEnd\n  Shape \"sphere\"\n\
                   TransformBegin\n Translate 0 3 0\n CoordinateSystem \"up\"\n TransformEnd\n\
                   AttributeEnd\nShape \"sphere\" \"float radius\" 0.25\n\
                   AttributeBegin\n CoordSysTransform \"up\"\n Rotate 90 0 0 1\n Translate 1 0 0\n\
                   Shape \"sphere\"\nAttributeEnd\n";
        let im = parts(src);
        let s = &im.geometry.spheres;
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
        assert!(close(s[0].center, Vec3::new(1.0, 0.0, 0.0)) && s[0].radius == 1.0);
        assert!(close(s[1].center, Vec3::new(1.0, 0.0, 0.0)) && s[1].radius == 1.0);
        assert!(close(s[2].center, Vec3::ZERO) && s[2].radius == 0.25);
        // The named system (translated by (1, 3, 0)), then rotated: local +x is world +y.
        assert!(
            close(s[3].center, Vec3::new(1.0, 4.0, 0.0)),
            "{:?}",
            s[3].center
        );
        let cam = &im.cameras[0];
        assert!(close(cam.position, Vec3::new(0.0, 0.0, 5.0)));
        assert!(close(cam.look_at - cam.position, Vec3::new(0.0, 0.0, -1.0)));
        // A plain LookAt is right-handed in pbrt's left-handed camera space: mirrored.
        assert!(cam.mirrored);
        assert_eq!(cam.fov_deg, 30.0);
        let unbalanced = "WorldBegin\nAttributeBegin\nTransformEnd\n";
        let (_d, e) = import_files(&[("scene.pbrt", unbalanced.as_bytes())]);
        let e = e.err().unwrap().to_string();
        assert!(
            e.contains("scene.pbrt:3: TransformEnd closes the AttributeBegin of"),
            "{e}"
        );
        assert!(e.ends_with("scene.pbrt:2"), "{e}");
    }

    #[test]
    fn named_materials_map_onto_the_four_bsdfs() {
        let src = "WorldBegin\n\
            MakeNamedMaterial \"white\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.8 0.8 0.8]\n\
            MakeNamedMaterial \"plastic\" \"string type\" \"coateddiffuse\" \"float roughness\" 0.01\n\
              \"rgb reflectance\" [1 0.5 0.25]\n\
            MakeNamedMaterial \"silver\" \"string type\" \"conductor\" \"float roughness\" 0\n\
              \"spectrum eta\" \"metal-Ag-eta\" \"spectrum k\" \"metal-Ag-k\"\n\
            MakeNamedMaterial \"brushed\" \"string type\" \"conductor\" \"float roughness\" 0.1\n\
              \"bool remaproughness\" false \"rgb eta\" [1.5 1.5 1.5] \"rgb k\" [0 0 0]\n\
            MakeNamedMaterial \"glass\" \"string type\" \"dielectric\" \"float eta\" 1.33\n\
            MakeNamedMaterial \"leaf\" \"string type\" \"diffusetransmission\" \"rgb reflectance\" [0.5 0.5 0.5] \"float scale\" 0.5\n";
        let mut src = src.to_string();
        for name in ["white", "plastic", "silver", "brushed", "glass", "leaf"] {
            src.push_str(&format!(
                "NamedMaterial \"{name}\"\nShape \"trianglemesh\" {QUAD}\n"
            ));
        }
        let im = parts(&src);
        let kinds: Vec<_> = im.materials.iter().map(|m| m.kind.clone()).collect();
        assert_eq!(
            kinds[0],
            MaterialKind::Lambert {
                kd: Rgb::splat(0.8)
            }
        );
        let MaterialKind::Phong { kd, ks, exponent } = kinds[1] else {
            panic!("{:?}", kinds[1])
        };
        // remaproughness: alpha = sqrt(0.01) = 0.1, so n = 2 / 0.01 - 2.
        assert!((exponent - 198.0).abs() < 1e-2, "{exponent}");
        assert!(
            (ks.r - 0.04).abs() < 1e-6 && (kd.r - 0.96).abs() < 1e-6 && (kd.b - 0.24).abs() < 1e-6
        );
        let MaterialKind::Mirror { ks } = kinds[2] else {
            panic!("{:?}", kinds[2])
        };
        assert!(ks.min_component() > 0.9);
        let MaterialKind::Phong { kd, ks, exponent } = kinds[3] else {
            panic!("{:?}", kinds[3])
        };
        assert_eq!(kd, Rgb::BLACK);
        assert!((ks.g - 0.04).abs() < 1e-6 && (exponent - 198.0).abs() < 1e-2);
        assert_eq!(kinds[4], MaterialKind::Glass { ior: 1.33 });
        assert_eq!(
            kinds[5],
            MaterialKind::Lambert {
                kd: Rgb::splat(0.25)
            }
        );
        // Each quad has its material; approximations warned once each, with the line.
        let tm = &im.triangle_materials;
        assert_eq!(tm.len(), 12);
        assert_eq!(
            tm.chunks(2).map(|c| c[0]).collect::<Vec<_>>(),
            vec![0, 1, 2, 3, 4, 5]
        );
        let warned: Vec<_> = im
            .warnings
            .iter()
            .map(Warning::to_string)
            .filter(|w| w.contains("material '"))
            .collect();
        assert_eq!(warned.len(), 3, "{warned:?}");
        assert!(
            warned[0].contains("scene.pbrt:3: material 'plastic'"),
            "{warned:?}"
        );
        // An undefined name is an error at its line.
        let e = error(&[("scene.pbrt", b"WorldBegin\n\nNamedMaterial \"nope\"\n")]);
        assert!(
            e.contains("scene.pbrt:3: NamedMaterial: no material named 'nope'"),
            "{e}"
        );
    }

    #[test]
    fn area_light_on_a_trianglemesh_faces_its_normals() {
        // Counter-clockwise seen from above, but the normals point down: the light faces down.
        let src = format!(
            "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2 4 6] \"float scale\" 0.5\n\
             Shape \"trianglemesh\" {QUAD}\n  \"normal N\" [0 -1 0 0 -1 0 0 -1 0 0 -1 0]\nAttributeEnd\n\
             Shape \"trianglemesh\" {QUAD}\n"
        );
        let im = parts(&src);
        let p = &im;
        let emissive: Vec<_> = p
            .triangle_materials
            .iter()
            .map(|&m| p.materials[m as usize].emission)
            .collect();
        assert_eq!(emissive[..2], [Rgb::new(1.0, 2.0, 3.0); 2]);
        assert_eq!(emissive[2..], [Rgb::BLACK; 2]);
        let normal = |t: usize| {
            let [a, b, c] = p.geometry.triangles[t].map(|i| p.geometry.positions[i as usize]);
            (b - a).cross(c - a).normalize()
        };
        assert!(normal(0).y < -0.99 && normal(1).y < -0.99);
        // Without normals the winding decides, and ReverseOrientation flips it.
        assert!(normal(2).y < -0.99, "P's order is clockwise seen from +y");
        let flipped = parts(&format!(
            "WorldBegin\nReverseOrientation\nShape \"trianglemesh\" {QUAD}\n"
        ));
        let g = &flipped.geometry;
        let [a, b, c] = g.triangles[0].map(|i| g.positions[i as usize]);
        assert!((b - a).cross(c - a).y > 0.0);
    }

    #[test]
    fn binary_ply_with_normals_and_uvs() {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let n = [[0.0, 0.0, -1.0]; 4];
        let uv = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let ply = binary_ply(&p, &n, &uv, &[&[0, 1, 2, 3]]);
        let src =
            "WorldBegin\nTranslate 0 0 2\nShape \"plymesh\" \"string filename\" \"mesh.ply\"\n";
        let (_dir, result) = import_files(&[("scene.pbrt", src.as_bytes()), ("mesh.ply", &ply)]);
        let im = result.unwrap_or_else(|e| panic!("{e}"));
        let g = &im.geometry;
        assert_eq!(g.positions.len(), 4);
        assert_eq!(g.positions[2], Vec3::new(1.0, 1.0, 2.0));
        // The quad is split in two, both turned to face the normals (-z), which with the uvs
        // become the triangles' shading data.
        assert_eq!(g.triangles.len(), 2);
        let sh = &im.shading;
        assert_eq!((sh.normals.len(), sh.uvs.len()), (4, 4));
        assert_eq!(sh.normals[0], Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(sh.triangle_normals, g.triangles);
        assert_eq!(sh.triangle_uvs, g.triangles);
        for t in &g.triangles {
            let [a, b, c] = t.map(|i| g.positions[i as usize]);
            assert!((b - a).cross(c - a).z < 0.0);
        }
        // A face index out of range, and a file cut short, name the Shape's line and the file.
        let bad = binary_ply(&p, &n, &uv, &[&[0, 1, 7]]);
        let e = error(&[("scene.pbrt", src.as_bytes()), ("mesh.ply", &bad)]);
        assert!(
            e.contains("scene.pbrt:3: Shape plymesh")
                && e.contains("mesh.ply: face 0 refers to vertex 7"),
            "{e}"
        );
        let e = error(&[
            ("scene.pbrt", src.as_bytes()),
            ("mesh.ply", &ply[..ply.len() - 2]),
        ]);
        assert!(
            e.contains("scene.pbrt:3:") && e.contains("ends after 0 of 1 faces"),
            "{e}"
        );
    }

    #[test]
    fn image_textures_carry_the_mappings_factor() {
        let image = texture::Texture::new(2, 1, vec![Rgb::splat(0.5), Rgb::WHITE]).unwrap();
        let pfm = texture::write_pfm(&image);
        let src = format!(
            "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"t.pfm\"\n\
             Texture \"half\" \"spectrum\" \"scale\" \"texture tex\" \"t\" \"float scale\" 0.5\n\
             Material \"diffuse\" \"texture reflectance\" \"t\"\nShape \"trianglemesh\" {QUAD}\n\
             Material \"coateddiffuse\" \"texture reflectance\" \"half\"\nShape \"trianglemesh\" {QUAD}\n"
        );
        let (_dir, result) = import_files(&[("scene.pbrt", src.as_bytes()), ("t.pfm", &pfm)]);
        let p = result.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(p.textures.len(), 2);
        let kd = |m: usize| p.material_textures[m].kd.unwrap() as usize;
        assert_eq!(p.textures[kd(0)].texels, image.texels);
        // The scale texture's 0.5, times coateddiffuse's 1 - F0 = 0.96.
        let t = &p.textures[kd(1)].texels;
        assert!(
            (t[1].r - 0.48).abs() < 1e-6 && (t[0].g - 0.24).abs() < 1e-6,
            "{t:?}"
        );
    }

    #[test]
    fn include_and_include_loops() {
        let main = "WorldBegin\nMakeNamedMaterial \"m\" \"string type\" \"diffuse\"\nInclude \"part.pbrt\"\nShape \"sphere\"\n";
        let part = "NamedMaterial \"m\"\nTranslate 0 1 0\nShape \"sphere\"\n";
        let (_dir, result) = import_files(&[
            ("scene.pbrt", main.as_bytes()),
            ("part.pbrt", part.as_bytes()),
        ]);
        let im = result.unwrap_or_else(|e| panic!("{e}"));
        // The included file shares the graphics state: its transform and material carry on.
        let s = &im.geometry.spheres;
        assert_eq!(s.len(), 2);
        assert_eq!((s[0].center.y, s[1].center.y), (1.0, 1.0));
        assert_eq!(im.sphere_materials, vec![0, 0]);
        let e = error(&[
            ("scene.pbrt", b"WorldBegin\nInclude \"a.pbrt\"\n"),
            ("a.pbrt", b"\nInclude \"scene.pbrt\"\n"),
        ]);
        assert!(
            e.contains("a.pbrt:2: Include loop:") && e.contains("scene.pbrt -> "),
            "{e}"
        );
        // Errors inside an included file name that file.
        let e = error(&[
            ("scene.pbrt", b"WorldBegin\nInclude \"a.pbrt\"\n"),
            ("a.pbrt", b"Shape \"sphere\"\n  \"float radius\" [ 1 2 ]\n"),
        ]);
        assert!(
            e.contains("a.pbrt:2: parameter 'float radius' takes one value, got 2"),
            "{e}"
        );
    }

    #[test]
    fn object_instances_are_flattened() {
        let src = format!(
            "WorldBegin\nObjectBegin \"q\"\nTranslate 0 1 0\nShape \"trianglemesh\" {QUAD}\nObjectEnd\n\
             ObjectInstance \"q\"\nTranslate 10 0 0\nObjectInstance \"q\"\n"
        );
        let im = parts(&src);
        let g = &im.geometry;
        assert_eq!(g.triangles.len(), 4);
        assert_eq!(g.positions[0], Vec3::new(-1.0, 1.0, -1.0));
        assert_eq!(g.positions[4], Vec3::new(9.0, 1.0, -1.0));
    }
}
