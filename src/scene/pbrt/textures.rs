//! Textures: the Texture directive (image maps, constants, scales), spectrum and float
//! parameters that may name a texture, and the images read for the materials at the end.

use super::import::{Importer, Loc};
use super::material::named_spectrum;
use super::parser::{Directive, ParamList, Spectrum, TexOr};
use crate::accel::Alpha;
use crate::color::Rgb;
use crate::files::snippet;
use crate::options::OptionName;
use crate::scene::alpha;
use crate::scene::builder::Builder;
use crate::scene::{MaterialTextures, SceneError};
use crate::texture::Texture;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

/// A spectrum-valued texture, as far as vmerge follows it.
#[derive(Clone, Debug)]
pub(super) enum Tex {
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
pub(super) enum FloatTex {
    Constant(f32),
    /// An image map, or [`Tex::Missing`].
    Image(Tex),
}

/// An image a material parameter reads: the file, the factor on its texels, and the Texture
/// directive that named it.
pub(super) type ImageRef = (PathBuf, Rgb, Loc);

/// What a texture slot of a material holds until the images are read.
#[derive(Clone, Debug)]
pub(super) enum Slot {
    Image(ImageRef),
    /// One value everywhere: an axis of a roughness pair whose other axis is an image.
    Constant(f32),
}

/// The images a material's parameters read (module `scene`'s `MaterialTextures`, and a mix's
/// amount), decoded at the end of the import.
#[derive(Clone, Debug, Default)]
pub(super) struct PendingTextures {
    pub kd: Option<ImageRef>,
    pub ks: Option<ImageRef>,
    /// The roughness of both axes, or of the u axis where `vroughness` is given.
    pub roughness: Option<Slot>,
    pub vroughness: Option<Slot>,
    pub amount: Option<ImageRef>,
}

impl PendingTextures {
    fn images(&self) -> impl Iterator<Item = &ImageRef> {
        fn slot(s: &Option<Slot>) -> Option<&ImageRef> {
            match s {
                Some(Slot::Image(i)) => Some(i),
                _ => None,
            }
        }
        [
            self.kd.as_ref(),
            self.ks.as_ref(),
            slot(&self.roughness),
            slot(&self.vroughness),
            self.amount.as_ref(),
        ]
        .into_iter()
        .flatten()
    }

    /// Whether nothing is read from an image.
    pub fn is_empty(&self) -> bool {
        self.images().next().is_none()
    }

    /// Each image times `factor` (the material's scale of its reflectances).
    pub fn scaled(mut self, factor: Rgb) -> Self {
        for image in [&mut self.kd, &mut self.ks].into_iter().flatten() {
            image.1 *= factor;
        }
        self
    }
}

impl Importer {
    pub(super) fn texture(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let (name, ty, class) = (d.str_arg(0), d.str_arg(1), d.str_arg(2));
        let spectrum = match ty {
            "spectrum" | "color" => true,
            "float" => false,
            other => {
                return Err(self.at(
                    loc,
                    format!(
                        "Texture '{name}': type '{other}' is neither spectrum nor float",
                        name = snippet(name),
                        other = snippet(other)
                    ),
                ))
            }
        };
        let p = &d.params;
        let tex = match class {
            "imagemap" => {
                let file = p.string("filename").map_err(&pe)?.ok_or_else(|| {
                    self.at(
                        loc,
                        format!(
                            "Texture '{name}': imagemap without a filename",
                            name = snippet(name)
                        ),
                    )
                })?;
                let scale = p.float("scale", 1.0).map_err(&pe)?;
                if p.bool("invert", false).map_err(&pe)? {
                    self.warn(
                        loc,
                        format!("Texture '{name}': invert ignored", name = snippet(name)),
                    );
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
                            path.display(), name = snippet(name)),
                    );
                    Tex::Missing
                } else {
                    return Err(self.at(
                        loc,
                        format!(
                            "Texture '{name}': {} is missing (use {} to render with the material's constant)",
                            path.display(),
                            OptionName("lenient"), name = snippet(name)),
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
            "scale" if !spectrum => {
                let base = self.float_texture(loc, p, "tex")?;
                let scale = self.texture_scale(loc, p, name)?;
                let scaled = match base {
                    None => FloatTex::Constant(scale),
                    Some(FloatTex::Constant(v)) => FloatTex::Constant(v * scale),
                    Some(FloatTex::Image(Tex::Image {
                        path,
                        scale: s,
                        loc,
                    })) => FloatTex::Image(Tex::Image {
                        path,
                        scale: s * scale,
                        loc,
                    }),
                    Some(missing @ FloatTex::Image(_)) => missing,
                };
                self.float_textures.insert(name.to_string(), scaled);
                return Ok(());
            }
            "scale" if spectrum => {
                let base = self.spectrum_texture(loc, p, "tex", Rgb::WHITE)?;
                let scale = self.texture_scale(loc, p, name)?;
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
                    format!(
                        "Texture '{name}': class '{other}' not supported; grey 0.5 used",
                        name = snippet(name),
                        other = snippet(other)
                    ),
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
                .insert(name.to_string(), FloatTex::Image(tex));
        }
        Ok(())
    }

    /// A scale texture's `scale`: a number (a texture is not followed: a warning, and 1).
    fn texture_scale(&mut self, loc: Loc, p: &ParamList, name: &str) -> Result<f32, SceneError> {
        Ok(match p.float_texture("scale").map_err(self.pe(loc.file))? {
            None => 1.0,
            Some((TexOr::Value(v), _)) => v,
            Some((TexOr::Texture(t), line)) => match self.float_textures.get(&t) {
                Some(FloatTex::Constant(v)) => *v,
                _ => {
                    self.warn(
                        Loc { line, ..loc },
                        format!(
                            "Texture '{name}': scale by texture '{t}' not supported; 1 used",
                            name = snippet(name),
                            t = snippet(&t)
                        ),
                    );
                    1.0
                }
            },
        })
    }

    /// An RGB value for a spectrum parameter, with a warning where it is approximated.
    pub(super) fn spectrum(
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

    pub(super) fn spectrum_value(
        &mut self,
        loc: Loc,
        name: &str,
        s: Spectrum,
    ) -> Result<Rgb, SceneError> {
        let rgb = match s {
            Spectrum::Rgb(v) => Rgb::from_array(v),
            Spectrum::Named(n) => match named_spectrum(&n) {
                Some(c) => c,
                None => {
                    self.warn(
                        loc,
                        format!(
                            "'{name}': unknown named spectrum '{n}'; grey 1 used",
                            name = snippet(name),
                            n = snippet(&n)
                        ),
                    );
                    Rgb::WHITE
                }
            },
            Spectrum::Blackbody(t) => {
                self.warn(
                    loc,
                    format!(
                        "'{name}': blackbody {t} K approximated as white",
                        name = snippet(name)
                    ),
                );
                Rgb::WHITE
            }
            Spectrum::Sampled(v) => {
                let values: Vec<f32> = v.chunks_exact(2).map(|p| p[1]).collect();
                let mean = values.iter().sum::<f32>() / values.len().max(1) as f32;
                self.warn(
                    loc,
                    format!(
                        "'{name}': sampled spectrum approximated by its mean {mean}",
                        name = snippet(name)
                    ),
                );
                Rgb::splat(mean)
            }
        };
        if !rgb.is_finite() || rgb.min_component() < 0.0 {
            return Err(self.at(
                loc,
                format!(
                    "'{name}' {:?} is negative",
                    rgb.to_array(),
                    name = snippet(name)
                ),
            ));
        }
        Ok(rgb)
    }

    /// A spectrum parameter that may name a texture.
    pub(super) fn spectrum_texture(
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
                    format!(
                        "'{name}': no spectrum texture named '{t}'",
                        name = snippet(name),
                        t = snippet(&t)
                    ),
                )),
            },
        }
    }

    /// A float parameter that may name a texture: its value, or the image texture it names.
    pub(super) fn float_texture(
        &mut self,
        loc: Loc,
        params: &ParamList,
        name: &str,
    ) -> Result<Option<FloatTex>, SceneError> {
        match params.float_texture(name).map_err(self.pe(loc.file))? {
            None => Ok(None),
            Some((TexOr::Value(v), _)) => Ok(Some(FloatTex::Constant(v))),
            Some((TexOr::Texture(t), line)) => match self.float_textures.get(&t) {
                Some(tex) => Ok(Some(tex.clone())),
                None => Err(self.at(
                    Loc { line, ..loc },
                    format!(
                        "'{name}': no float texture named '{t}'",
                        name = snippet(name),
                        t = snippet(&t)
                    ),
                )),
            },
        }
    }

    /// A float parameter that may name a texture, where only constants are followed.
    pub(super) fn float_param(
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
                Some(FloatTex::Image(_)) => {
                    self.warn(
                        Loc { line, ..loc },
                        format!(
                            "'{name}': float image texture '{t}' not supported; {default} used",
                            name = snippet(name),
                            t = snippet(&t)
                        ),
                    );
                    Ok(Some(default))
                }
                None => Err(self.at(
                    Loc { line, ..loc },
                    format!(
                        "'{name}': no float texture named '{t}'",
                        name = snippet(name),
                        t = snippet(&t)
                    ),
                )),
            },
        }
    }

    /// A shape's `alpha`: a constant below 1 or a float texture (pbrt-v4 ignores constants of
    /// 1 and more); `None` for an opaque shape.
    pub(super) fn shape_alpha(
        &mut self,
        loc: Loc,
        params: &ParamList,
    ) -> Result<Option<FloatTex>, SceneError> {
        match params.float_texture("alpha").map_err(self.pe(loc.file))? {
            None => Ok(None),
            Some((TexOr::Value(a), line)) if !a.is_finite() => Err(self.at(
                Loc { line, ..loc },
                format!("Shape: alpha {a} is not a finite number"),
            )),
            Some((TexOr::Value(a), _)) => Ok((a < 1.0).then_some(FloatTex::Constant(a))),
            Some((TexOr::Texture(t), line)) => match self.float_textures.get(&t) {
                Some(tex) => Ok(Some(tex.clone())),
                None => Err(self.at(
                    Loc { line, ..loc },
                    format!(
                        "Shape: alpha: no float texture named '{t}'",
                        t = snippet(&t)
                    ),
                )),
            },
        }
    }

    /// The alpha of a shape as the ray queries take it, its images decoded once each into
    /// `images` (scaled by the texture's `scale`); `None` where it is opaque or its image is
    /// missing (already warned of).
    pub(super) fn cutout_alpha(
        &mut self,
        tex: &FloatTex,
        images: &mut HashMap<(PathBuf, u32), Arc<Texture>>,
    ) -> Result<Option<Alpha>, SceneError> {
        let (path, scale, loc) = match tex {
            FloatTex::Constant(a) => return Ok(Some(Alpha::Constant(*a))),
            FloatTex::Image(Tex::Image { path, scale, loc }) => (path, scale.r, *loc),
            FloatTex::Image(_) => return Ok(None),
        };
        let key = (path.clone(), scale.to_bits());
        if let Some(image) = images.get(&key) {
            return Ok(Some(Alpha::Texture(Arc::clone(image))));
        }
        let (mut image, bytes) = alpha::read_image(path).map_err(|e| self.at(loc, e))?;
        self.builder.input(path, &bytes);
        for t in &mut image.texels {
            *t *= scale;
        }
        let image = Arc::new(image);
        images.insert(key, Arc::clone(&image));
        Ok(Some(Alpha::Texture(image)))
    }

    /// Decodes the materials' images (in parallel, each file once) and gives each material its
    /// textures: each image times its factor (a scaled copy where that is not 1).
    pub(super) fn load_textures(&mut self) -> Result<(), SceneError> {
        let pending = std::mem::take(&mut self.material_textures);
        let all = || pending.iter().flatten().flat_map(PendingTextures::images);
        let mut paths: Vec<PathBuf> = all().map(|(p, _, _)| p.clone()).collect();
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
                    let loc = all()
                        .find(|(p, _, _)| p == path)
                        .map_or(Loc { file: 0, line: 1 }, |&(_, _, loc)| loc);
                    if !self.lenient {
                        return Err(self.at(loc, message));
                    }
                    self.warn(loc, format!("{message}; its materials use their constant"));
                }
            }
        }
        for (material, entry) in pending.iter().enumerate() {
            let Some(entry) = entry else {
                continue;
            };
            let builder = &mut self.builder;
            let kd = scene_texture(builder, &images, entry.kd.as_ref());
            let ks = scene_texture(builder, &images, entry.ks.as_ref());
            let amount = scene_texture(builder, &images, entry.amount.as_ref());
            let roughness = slot_texture(builder, &images, entry.roughness.as_ref());
            let vroughness = slot_texture(builder, &images, entry.vroughness.as_ref());
            if let Some(amount) = amount {
                builder.set_mix_texture(material as u32, amount);
            }
            // Where one axis's image is missing, both axes keep their constants.
            let both = |r: Option<u32>, other: Option<u32>, other_slot: &Option<Slot>| {
                r.filter(|_| other.is_some() || other_slot.is_none())
            };
            builder.set_textures(
                material as u32,
                MaterialTextures {
                    kd,
                    ks,
                    roughness: both(roughness, vroughness, &entry.vroughness),
                    vroughness: both(vroughness, roughness, &entry.roughness),
                },
            );
        }
        Ok(())
    }
}

/// The scene texture of a material's image; `None` where none is given or the image is missing.
fn scene_texture(
    builder: &mut Builder,
    images: &HashMap<PathBuf, Arc<Texture>>,
    image: Option<&ImageRef>,
) -> Option<u32> {
    let (path, factor, _) = image?;
    Some(builder.texture(path, images.get(path)?, *factor))
}

fn slot_texture(
    builder: &mut Builder,
    images: &HashMap<PathBuf, Arc<Texture>>,
    slot: Option<&Slot>,
) -> Option<u32> {
    match slot? {
        Slot::Image(image) => scene_texture(builder, images, Some(image)),
        Slot::Constant(v) => Some(builder.constant_texture(Rgb::splat(*v))),
    }
}
