//! pbrt-v4's materials mapped onto vmerge's four BSDFs (the table in docs/pbrt.md, "Materials"): the Material,
//! MakeNamedMaterial and NamedMaterial directives, the mapping of each material type, and its
//! arithmetic (Fresnel reflectance at normal incidence, roughness to a Phong exponent, the RGB
//! values of pbrt's named metal spectra). The mapping conserves energy for reflectances up to
//! 1 (a coated diffuse's kd = reflectance x (1 - F0) beside ks = F0); the builder's rule
//! handles what a file states beyond that.

use super::import::{Importer, Loc};
use super::parser::{Directive, ParamList, ParamType, Spectrum};
use super::textures::Tex;
use crate::bsdf::{EnergyFix, MaterialKind, Params};
use crate::color::Rgb;
use crate::files::snippet;
use crate::scene::builder::{round3, MaterialDesc, Origin};
use crate::scene::SceneError;

/// The largest Phong exponent a mapped material gets: past it, f32 cannot resolve the lobe
/// (its width, sqrt(2/n) rad, nears the spacing of cosines close to 1).
pub const MAX_EXPONENT: f32 = 10_000.0;

/// pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha` (used when `remaproughness`).
pub fn roughness_to_alpha(roughness: f32) -> f32 {
    roughness.max(0.0).sqrt()
}

/// The Phong exponent with the same lobe width as a microfacet distribution of roughness
/// `alpha`: n = 2 / alpha^2 - 2 (Walter et al. 2007, the Beckmann-Phong correspondence),
/// clamped to [1, MAX_EXPONENT].
pub fn phong_exponent(alpha: f32) -> f32 {
    if alpha <= 0.0 {
        return MAX_EXPONENT;
    }
    (2.0 / (alpha * alpha) - 2.0).clamp(1.0, MAX_EXPONENT)
}

/// Reflectance at normal incidence of a dielectric interface of relative index `eta`.
pub fn dielectric_f0(eta: f32) -> f32 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// Reflectance at normal incidence of a conductor, per channel:
/// ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2).
pub fn conductor_f0(eta: Rgb, k: Rgb) -> Rgb {
    let f = |n: f32, k: f32| ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
    Rgb::new(f(eta.r, k.r), f(eta.g, k.g), f(eta.b, k.b))
}

/// RGB values of pbrt's named metal spectra (`"metal-Au-eta"`, ...): the spectra averaged
/// over the sRGB primaries' bands, the values renderers that work in RGB use for them.
pub fn named_spectrum(name: &str) -> Option<Rgb> {
    Some(match name {
        "metal-Ag-eta" => Rgb::new(0.155_265, 0.116_723, 0.138_381),
        "metal-Ag-k" => Rgb::new(4.828_343, 3.122_246, 2.146_95),
        "metal-Al-eta" => Rgb::new(1.657_46, 0.880_369, 0.521_229),
        "metal-Al-k" => Rgb::new(9.223_869, 6.269_523, 4.837_001),
        "metal-Au-eta" => Rgb::new(0.143_119, 0.374_957, 1.442_479),
        "metal-Au-k" => Rgb::new(3.983_16, 2.385_721, 1.603_215),
        "metal-Cu-eta" => Rgb::new(0.200_438, 0.924_033, 1.102_212),
        "metal-Cu-k" => Rgb::new(3.912_949, 2.452_848, 2.142_188),
        "metal-CuZn-eta" => Rgb::new(0.444, 0.527, 1.094),
        "metal-CuZn-k" => Rgb::new(3.695, 2.765, 1.829),
        "glass-BK7" => Rgb::splat(1.5168),
        "glass-BAF10" => Rgb::splat(1.67),
        "glass-F11" => Rgb::splat(1.62),
        _ => return None,
    })
}

impl Importer {
    pub(super) fn make_named_material(
        &mut self,
        loc: Loc,
        d: &Directive,
    ) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let mat_name = d.str_arg(0).to_string();
        let ty = d
            .params
            .string("type")
            .map_err(&pe)?
            .ok_or_else(|| {
                self.at(
                    loc,
                    format!(
                        "MakeNamedMaterial '{mat_name}' has no \"string type\"",
                        mat_name = snippet(&mat_name)
                    ),
                )
            })?
            .to_string();
        if self.named_materials.contains_key(&mat_name) {
            self.warn(
                loc,
                format!(
                    "MakeNamedMaterial: '{mat_name}' redefined",
                    mat_name = snippet(&mat_name)
                ),
            );
        }
        let index = self.material(loc, &ty, &mat_name, &d.params)?;
        self.named_materials.insert(mat_name, index);
        Ok(())
    }

    /// Material: an anonymous material, named after its type and place.
    pub(super) fn material_directive(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let ty = d.str_arg(0).to_string();
        let label = format!("{ty} ({}:{})", self.files[loc.file].display(), loc.line);
        let index = self.material(loc, &ty, &label, &d.params)?;
        self.state.material = Some(index);
        Ok(())
    }

    pub(super) fn named_material(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        match self.named_materials.get(d.str_arg(0)) {
            Some(&m) => {
                self.state.material = Some(m);
                Ok(())
            }
            None => Err(self.at(
                loc,
                format!(
                    "NamedMaterial: no material named '{}'",
                    snippet(d.str_arg(0))
                ),
            )),
        }
    }

    /// The microfacet alpha of a material's `roughness` (or the mean of `uroughness` and
    /// `vroughness`), remapped as pbrt does unless `remaproughness` is false.
    pub(super) fn alpha(&mut self, loc: Loc, params: &ParamList) -> Result<f32, SceneError> {
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
            roughness_to_alpha(roughness)
        } else {
            roughness
        })
    }

    /// Maps a pbrt material onto vmerge's BSDFs (docs/pbrt.md, "Materials"); one warning per
    /// material that is approximated.
    pub(super) fn material(
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
        let (bsdf, params) = match ty {
            "diffuse" => lambert(albedo(self, "reflectance", Rgb::splat(0.5))?),
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
                phong(reflectance * (1.0 - f0), Rgb::splat(f0), exponent)
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
                    mirror(f0)
                } else {
                    let exponent = phong_exponent(alpha);
                    notes.push(format!(
                        "rough conductor as Phong: ks = F0 = {:?}, exponent {exponent:.0} from alpha {alpha}",
                        round3(f0)
                    ));
                    phong(Rgb::BLACK, f0, exponent)
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
                                let msg = format!(
                                    "unknown named spectrum '{n}'; eta 1.5",
                                    n = snippet(&n)
                                );
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
                glass(eta)
            }
            "diffusetransmission" => {
                let reflectance = albedo(self, "reflectance", Rgb::splat(0.25))?;
                let scale = p.float("scale", 1.0).map_err(&pe)?;
                p.mark_used(&["transmittance"]);
                notes.push(
                    "diffusetransmission as lambert of its reflectance (no transmission)".into(),
                );
                factor = Rgb::splat(scale);
                lambert(reflectance * scale)
            }
            "interface" => return self.interface_material(loc, name),
            "coatedconductor" | "measured" | "mix" | "hair" | "subsurface" => {
                let kd = match p.params.iter().any(|q| q.name == "reflectance") {
                    true => albedo(self, "reflectance", Rgb::splat(0.5))?,
                    false => Rgb::splat(0.5),
                };
                p.mark_all_used();
                notes.push(format!(
                    "'{ty}' as lambert of kd {:?}",
                    round3(kd),
                    ty = snippet(ty)
                ));
                lambert(kd)
            }
            other => {
                return Err(self.at(
                    loc,
                    format!("unknown material type '{other}'", other = snippet(other)),
                ));
            }
        };
        for ignored in ["displacement", "normalmap"] {
            if p.params.iter().any(|q| q.name == ignored) {
                p.mark_used(&[ignored]);
                notes.push(format!("{ignored} ignored"));
            }
        }
        let params = clamp_reflectance(&mut notes, bsdf, params);
        if !notes.is_empty() {
            self.warn(
                loc,
                format!(
                    "material '{name}': {}",
                    notes.join("; "),
                    name = snippet(name)
                ),
            );
        }
        let origin = Origin {
            file: self.files[loc.file].clone(),
            line: Some(loc.line),
            entry: format!("material '{name}'", name = snippet(name)),
        };
        let material = MaterialDesc::new(name, bsdf, params);
        let index = self.builder.material(&origin, material)?;
        self.material_textures
            .push(texture.map(|(path, scale, loc)| (path, scale * factor, loc)));
        Ok(index)
    }

    /// A spectrum parameter given as a value, a float, or a constant texture; image textures
    /// are not followed here (a warning, and `fallback`).
    pub(super) fn constant_spectrum(
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
                        round3(fallback),
                        name = snippet(name)
                    ),
                );
                Ok(fallback)
            }
        }
    }

    pub(super) fn current_material(&mut self) -> Result<u32, SceneError> {
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
        let (bsdf, params) = lambert(Rgb::splat(0.5));
        let material = MaterialDesc::new("(default diffuse)", bsdf, params);
        let index = self.builder.material(&origin, material)?;
        self.material_textures.push(None);
        self.default_material = Some(index);
        Ok(index)
    }

    /// The material shapes get now: the current one, emissive when an area light is set.
    pub(super) fn shape_material(&mut self) -> Result<u32, SceneError> {
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
}

/// Reflectances above 1 would create energy; pbrt-v4 clamps them to [0, 1] too. (Phong's
/// kd + ks is the builder's rule.)
fn clamp_reflectance(notes: &mut Vec<String>, bsdf: &'static str, params: Params) -> Params {
    let Ok(kind) = MaterialKind::from_params(bsdf, &params) else {
        // The builder names what is wrong with the parameters.
        return params;
    };
    match kind.energy_excess() {
        Some(excess) if excess.fix == EnergyFix::Clamped => {
            notes.push(format!(
                "reflectance {:?} clamped to 1",
                round3(excess.total)
            ));
            excess.conserving.params()
        }
        _ => params,
    }
}

/// The mapping's results: vmerge's BSDFs by type name and parameters, for the builder.
fn lambert(kd: Rgb) -> (&'static str, Params) {
    ("lambert", Params::new().with_color("kd", kd))
}

fn phong(kd: Rgb, ks: Rgb, exponent: f32) -> (&'static str, Params) {
    let params = Params::new()
        .with_color("kd", kd)
        .with_color("ks", ks)
        .with_number("exponent", exponent);
    ("phong", params)
}

fn mirror(ks: Rgb) -> (&'static str, Params) {
    ("mirror", Params::new().with_color("ks", ks))
}

fn glass(ior: f32) -> (&'static str, Params) {
    ("glass", Params::new().with_number("ior", ior))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_and_exponents() {
        assert!((dielectric_f0(1.5) - 0.04).abs() < 1e-6);
        // A conductor with k = 0 is a dielectric.
        let f = conductor_f0(Rgb::splat(1.5), Rgb::BLACK);
        assert!((f.r - 0.04).abs() < 1e-6);
        // Silver reflects over 90 % at normal incidence.
        let ag = conductor_f0(
            named_spectrum("metal-Ag-eta").unwrap(),
            named_spectrum("metal-Ag-k").unwrap(),
        );
        assert!(
            ag.min_component() > 0.9 && ag.max_component() < 1.0,
            "{ag:?}"
        );
        assert!((phong_exponent(0.1) - 198.0).abs() < 1e-3);
        assert_eq!(phong_exponent(0.0), MAX_EXPONENT);
        assert_eq!(phong_exponent(0.001), MAX_EXPONENT);
        assert_eq!(phong_exponent(2.0), 1.0);
        assert_eq!(roughness_to_alpha(0.25), 0.5);
    }
}
