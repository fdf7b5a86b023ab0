//! pbrt-v4's materials mapped onto vmerge's BSDFs (the table in docs/pbrt.md, "Materials"): the
//! Material, MakeNamedMaterial and NamedMaterial directives, the mapping of each material type,
//! and the RGB values of pbrt's named metal spectra. Conductors, dielectrics and thin dielectrics are vmerge's own types of the same
//! names; `diffusetransmission`, `coateddiffuse`, `coatedconductor` and `mix` map to their own
//! models. Reflectances are clamped to [0, 1] as pbrt-v4 clamps them; the builder's rule
//! handles what a file states beyond that.

use super::import::{Importer, Loc};
use super::parser::{Directive, ParamList, ParamType, Spectrum, Values};
use super::textures::{FloatTex, ImageRef, PendingTextures, Slot, Tex};
use crate::bsdf::{EnergyFix, MaterialKind, ParamValue, Params};
use crate::color::Rgb;
use crate::files::snippet;
use crate::scene::builder::{round3, MaterialDesc, Origin};
use crate::scene::Mix;
use crate::scene::SceneError;

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

    /// A microfacet material's `roughness`, `uroughness`, `vroughness` and `remaproughness`
    /// as the parameters of vmerge's microfacet types (which read them the same way), the
    /// images among them into `pending`.
    fn roughness_params(
        &mut self,
        loc: Loc,
        p: &ParamList,
        pending: &mut PendingTextures,
    ) -> Result<Params, SceneError> {
        let (u, v) = self.roughnesses(loc, p, "", Some(pending))?;
        let remap = p.bool("remaproughness", true).map_err(self.pe(loc.file))?;
        Ok(Params::new()
            .with_number("uroughness", u)
            .with_number("vroughness", v)
            .with_number("remaproughness", if remap { 1.0 } else { 0.0 }))
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
        let mut pending = PendingTextures::default();
        // A spectrum parameter's constant, its image (if any) into `slot`.
        let spectrum = |im: &mut Importer,
                        param: &str,
                        default: Rgb,
                        slot: &mut Option<ImageRef>|
         -> Result<Rgb, SceneError> {
            Ok(match im.spectrum_texture(loc, p, param, default)? {
                Tex::Constant(c) => c,
                Tex::Image { path, scale, loc } => {
                    *slot = Some((path, scale, loc));
                    default
                }
                Tex::Missing => default,
            })
        };
        let albedo = |im: &mut Importer,
                      pending: &mut PendingTextures,
                      param: &str,
                      default: Rgb|
         -> Result<Rgb, SceneError> {
            spectrum(im, param, default, &mut pending.kd)
        };
        // What the mapping multiplies the reflectance by, applied to a texture's texels too.
        let mut factor = Rgb::WHITE;
        let (bsdf, params) = match ty {
            "diffuse" => lambert(albedo(self, &mut pending, "reflectance", Rgb::splat(0.5))?),
            "coateddiffuse" => {
                let reflectance = albedo(self, &mut pending, "reflectance", Rgb::splat(0.5))?;
                let mut params = self.coating(loc, p, "")?;
                params.set("eta", ParamValue::Number(self.eta_param(loc, p, "eta")?));
                (
                    "coateddiffuse",
                    params.with_color("reflectance", unit(reflectance)),
                )
            }
            "coatedconductor" => {
                let given = |n: &str| p.params.iter().any(|q| q.name == n);
                if given("reflectance") && (given("conductor.eta") || given("conductor.k")) {
                    return Err(self.at(
                        loc,
                        "coatedconductor: \"reflectance\" and \"conductor.eta\"/\"conductor.k\" exclude each other".to_string(),
                    ));
                }
                let mut params = self.coating(loc, p, "interface.")?;
                params.set(
                    "interface.eta",
                    ParamValue::Number(self.eta_param(loc, p, "interface.eta")?),
                );
                let (u, v) = self.roughnesses(loc, p, "conductor.", Some(&mut pending))?;
                params = params
                    .with_number("conductor.uroughness", u)
                    .with_number("conductor.vroughness", v);
                if given("reflectance") {
                    let r = albedo(self, &mut pending, "reflectance", Rgb::splat(0.5))?;
                    params = params.with_color("reflectance", unit(r));
                } else {
                    let cu = |n| named_spectrum(n).unwrap_or(Rgb::WHITE);
                    let eta =
                        self.constant_spectrum(loc, p, "conductor.eta", cu("metal-Cu-eta"))?;
                    let k = self.constant_spectrum(loc, p, "conductor.k", cu("metal-Cu-k"))?;
                    params = params
                        .with_color("conductor.eta", eta)
                        .with_color("conductor.k", k);
                }
                ("coatedconductor", params)
            }
            "conductor" => {
                let params = self.roughness_params(loc, p, &mut pending)?;
                let params = if p.params.iter().any(|q| q.name == "reflectance") {
                    let r = self.constant_spectrum(loc, p, "reflectance", Rgb::WHITE)?;
                    params.with_color("reflectance", r)
                } else {
                    let cu = |n| named_spectrum(n).unwrap_or(Rgb::WHITE);
                    let eta = self.constant_spectrum(loc, p, "eta", cu("metal-Cu-eta"))?;
                    let k = self.constant_spectrum(loc, p, "k", cu("metal-Cu-k"))?;
                    params.with_color("eta", eta).with_color("k", k)
                };
                ("conductor", params)
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
                if ty == "thindielectric" {
                    ("thindielectric", Params::new().with_number("eta", eta))
                } else {
                    let params = self.roughness_params(loc, p, &mut pending)?;
                    // A roughness texture makes it rough at least somewhere.
                    let rough = !pending.is_empty()
                        || MaterialKind::from_params("dielectric", &params)
                            .is_ok_and(|kind| !kind.is_delta());
                    if rough {
                        ("dielectric", params.with_number("eta", eta))
                    } else {
                        // The smooth interface is glass itself.
                        glass(eta)
                    }
                }
            }
            "diffusetransmission" => {
                let reflectance = albedo(self, &mut pending, "reflectance", Rgb::splat(0.25))?;
                let transmittance =
                    spectrum(self, "transmittance", Rgb::splat(0.25), &mut pending.ks)?;
                // pbrt-v4 scales both and clamps each to [0, 1].
                let scale = p.float("scale", 1.0).map_err(&pe)?;
                factor = Rgb::splat(scale);
                diffuse_transmission(unit(reflectance * scale), unit(transmittance * scale))
            }
            "interface" => return self.interface_material(loc, name),
            "mix" => return self.mix(loc, name, p),
            "measured" | "hair" | "subsurface" => {
                let kd = match p.params.iter().any(|q| q.name == "reflectance") {
                    true => albedo(self, &mut pending, "reflectance", Rgb::splat(0.5))?,
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
            .push((!pending.is_empty()).then(|| pending.scaled(factor)));
        Ok(index)
    }

    /// A roughness pair as pbrt-v4 reads it under `prefix`: `uroughness` and `vroughness`,
    /// each defaulting to `roughness`, then 0. With `pending`, an axis may come from an image
    /// (its number is then 0, the image goes into `pending`); without, an image is not followed
    /// (a warning, and 0).
    fn roughnesses(
        &mut self,
        loc: Loc,
        p: &ParamList,
        prefix: &str,
        pending: Option<&mut PendingTextures>,
    ) -> Result<(f32, f32), SceneError> {
        let get = |im: &mut Importer, n: &str| im.float_texture(loc, p, &format!("{prefix}{n}"));
        let common = get(self, "roughness")?;
        let u = get(self, "uroughness")?.or_else(|| common.clone());
        let v = get(self, "vroughness")?.or(common);
        let textured = pending.is_some();
        let axis = |im: &mut Importer, t: Option<FloatTex>| -> Result<_, SceneError> {
            let r = match t {
                None => return Ok((0.0, None)),
                Some(FloatTex::Constant(r) | FloatTex::Image(Tex::Constant(Rgb { r, .. }))) => r,
                Some(FloatTex::Image(Tex::Image { path, scale, loc })) if textured => {
                    return Ok((0.0, Some((path, scale, loc))))
                }
                // Warned of at the Texture directive.
                Some(FloatTex::Image(Tex::Missing)) => 0.0,
                Some(FloatTex::Image(Tex::Image { .. })) => {
                    im.warn(
                        loc,
                        format!("'{prefix}roughness' from an image texture not supported; 0 used"),
                    );
                    0.0
                }
            };
            if !(r >= 0.0 && r.is_finite()) {
                return Err(im.at(loc, format!("{prefix}roughness {r} is negative")));
            }
            Ok((r, None))
        };
        let (u, u_image) = axis(self, u)?;
        let (v, v_image) = axis(self, v)?;
        if let Some(pending) = pending {
            let same = |a: &ImageRef, b: &ImageRef| a.0 == b.0 && a.1 == b.1;
            (pending.roughness, pending.vroughness) = match (u_image, v_image) {
                (None, None) => (None, None),
                (Some(a), Some(b)) if same(&a, &b) => (Some(Slot::Image(a)), None),
                (Some(a), Some(b)) => (Some(Slot::Image(a)), Some(Slot::Image(b))),
                (Some(a), None) => (Some(Slot::Image(a)), Some(Slot::Constant(v))),
                (None, Some(b)) => (None, Some(Slot::Image(b))),
            };
        }
        Ok((u, v))
    }

    /// The parameters of a layered material's coating (its interface's roughness under
    /// `prefix`, the slab and pbrt's walk), for the coated types.
    fn coating(&mut self, loc: Loc, p: &ParamList, prefix: &str) -> Result<Params, SceneError> {
        let pe = self.pe(loc.file);
        let (u, v) = self.roughnesses(loc, p, prefix, None)?;
        let thickness = self.float_param(loc, p, "thickness", 0.01)?.unwrap_or(0.01);
        if !(thickness >= 0.0 && thickness.is_finite()) {
            return Err(self.at(loc, format!("thickness {thickness} is negative")));
        }
        let medium = self.constant_spectrum(loc, p, "albedo", Rgb::BLACK)?;
        let max_depth = p.int("maxdepth", 10).map_err(&pe)?;
        // The model is deterministic (bsdf/layer.rs): pbrt's samples per evaluation and the
        // phase function's asymmetry (the medium's scattering is taken as forward) do not
        // enter it.
        p.mark_used(&["nsamples", "g"]);
        let remap = p.bool("remaproughness", true).map_err(&pe)?;
        Ok(Params::new()
            .with_number(&format!("{prefix}uroughness"), u)
            .with_number(&format!("{prefix}vroughness"), v)
            .with_number("remaproughness", if remap { 1.0 } else { 0.0 })
            .with_number("thickness", thickness)
            .with_color("albedo", unit(medium))
            .with_number("maxdepth", max_depth.clamp(0, 1 << 20) as f32))
    }

    /// An interface's index: a float, or a spectrum (named glasses by their mean); 1.5 when
    /// absent, and pbrt's 0 taken as 1.
    fn eta_param(&mut self, loc: Loc, p: &ParamList, name: &str) -> Result<f32, SceneError> {
        let eta = match p.params.iter().find(|q| q.name == name).map(|q| q.ty) {
            None => 1.5,
            Some(ParamType::Float) => self.float_param(loc, p, name, 1.5)?.unwrap_or(1.5),
            Some(_) => self
                .constant_spectrum(loc, p, name, Rgb::splat(1.5))?
                .average(),
        };
        if eta.is_nan() || eta < 0.0 {
            return Err(self.at(loc, format!("{name} {eta} is negative")));
        }
        Ok(if eta == 0.0 { 1.0 } else { eta })
    }

    /// pbrt-v4's MixMaterial: two named materials and the probability `amount` of the second
    /// (module `scene::mix`).
    fn mix(&mut self, loc: Loc, name: &str, p: &ParamList) -> Result<u32, SceneError> {
        let names = match p.params.iter().find(|q| q.name == "materials") {
            Some(q) => match &q.values {
                Values::Strs(v) if q.ty == ParamType::Str && v.len() == 2 => v.clone(),
                _ => {
                    return Err(self.at(
                        Loc {
                            line: q.line,
                            ..loc
                        },
                        "mix: \"string materials\" must name two materials".to_string(),
                    ))
                }
            },
            None => {
                return Err(self.at(loc, "mix without \"string materials\"".to_string()));
            }
        };
        p.mark_used(&["materials"]);
        let mut materials = [0u32; 2];
        for (slot, m) in materials.iter_mut().zip(&names) {
            *slot = *self
                .named_materials
                .get(m)
                .ok_or_else(|| self.at(loc, format!("mix: no material named '{}'", snippet(m))))?;
        }
        let mut pending = PendingTextures::default();
        let amount = match self.float_texture(loc, p, "amount")? {
            None => 0.5,
            Some(FloatTex::Constant(a) | FloatTex::Image(Tex::Constant(Rgb { r: a, .. }))) => a,
            Some(FloatTex::Image(Tex::Image { path, scale, loc })) => {
                pending.amount = Some((path, scale, loc));
                0.5
            }
            // Warned of at the Texture directive.
            Some(FloatTex::Image(Tex::Missing)) => 0.5,
        };
        if !(0.0..=1.0).contains(&amount) {
            return Err(self.at(loc, format!("mix: amount {amount} is not in [0, 1]")));
        }
        let mix = Mix {
            materials,
            amount,
            amount_texture: None,
        };
        let index = self.builder.mix(name.to_string(), mix);
        self.material_textures
            .push((!pending.is_empty()).then_some(pending));
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
        let key = (
            base,
            light.radiance.to_array().map(f32::to_bits),
            light.two_sided,
        );
        if let Some(&m) = self.emissive.get(&key) {
            return Ok(m);
        }
        let name = format!(
            "{} + AreaLightSource ({}:{})",
            self.builder.material_at(base).name,
            self.files[light.loc.file].display(),
            light.loc.line
        );
        let index = self
            .builder
            .variant(base, name, light.radiance, light.two_sided);
        // A mix's variant comes after variants of its materials (which keep their constants).
        self.material_textures.resize(index as usize, None);
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

/// Each channel clamped to [0, 1], as pbrt-v4 clamps reflectances.
fn unit(c: Rgb) -> Rgb {
    Rgb::new(
        c.r.clamp(0.0, 1.0),
        c.g.clamp(0.0, 1.0),
        c.b.clamp(0.0, 1.0),
    )
}

fn diffuse_transmission(r: Rgb, t: Rgb) -> (&'static str, Params) {
    let params = Params::new()
        .with_color("reflectance", r)
        .with_color("transmittance", t);
    ("diffusetransmission", params)
}

fn glass(ior: f32) -> (&'static str, Params) {
    ("glass", Params::new().with_number("ior", ior))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_metals() {
        // Silver reflects over 90 % at normal incidence.
        let ag = crate::bsdf::fresnel::complex(
            1.0,
            named_spectrum("metal-Ag-eta").unwrap(),
            named_spectrum("metal-Ag-k").unwrap(),
        );
        assert!(
            ag.min_component() > 0.9 && ag.max_component() < 1.0,
            "{ag:?}"
        );
    }
}
