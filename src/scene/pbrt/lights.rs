//! Lights: area lights (emissive variants of their shapes' materials, one- or two-sided),
//! point, spot and distant lights, and the infinite light as a constant sky or an environment
//! image.

use super::import::{Importer, Loc};
use super::parser::Directive;
use crate::color::Rgb;
use crate::files::snippet;
use crate::light::{EnvMapDesc, Light, SceneBounds, SkyDesc, SpotCone};
use crate::options::OptionName;
use crate::scene::SceneError;
use crate::texture;
use glam::{DMat3, DVec3, Mat3, Vec3};
use std::sync::Arc;

/// The area light in the graphics state.
#[derive(Clone, Debug)]
pub(super) struct AreaLight {
    pub(super) radiance: Rgb,
    pub(super) two_sided: bool,
    pub(super) loc: Loc,
}

impl Importer {
    /// AreaLightSource: shapes after it (in its block) emit.
    pub(super) fn area_light_source(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        if d.str_arg(0) != "diffuse" {
            return Err(self.at(
                loc,
                format!(
                    "AreaLightSource '{}' is unknown (diffuse)",
                    snippet(d.str_arg(0))
                ),
            ));
        }
        let l = self.spectrum(loc, &d.params, "L", Rgb::WHITE)?;
        let scale = d.params.float("scale", 1.0).map_err(&pe)?;
        let two_sided = d.params.bool("twosided", false).map_err(&pe)?;
        if d.params.string("filename").map_err(&pe)?.is_some() {
            self.warn(
                loc,
                "AreaLightSource: image emission is not supported; uses L",
            );
        }
        self.state.area_light = Some(AreaLight {
            radiance: l * scale,
            two_sided,
            loc,
        });
        Ok(())
    }

    pub(super) fn light_source(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let p = &d.params;
        let scale = p.float("scale", 1.0).map_err(&pe)?;
        // pbrt-v4 scales point and spot lights to emit `power` (with the spectrum's
        // luminance as the unit, which the RGB reduction already is).
        let power = p.float("power", -1.0).map_err(&pe)?;
        let with_power = matches!(d.str_arg(0), "point" | "spot");
        if power > 0.0 && !with_power {
            self.warn(loc, "LightSource: 'power' not supported; scale used");
        }
        if p.float("illuminance", -1.0).map_err(&pe)? > 0.0 {
            self.warn(loc, "LightSource: 'illuminance' not supported; scale used");
        }
        let ctm = self.state.ctm;
        match d.str_arg(0) {
            "point" => {
                let mut intensity = self.spectrum(loc, p, "I", Rgb::WHITE)? * scale;
                if power > 0.0 {
                    intensity *= power / (4.0 * std::f32::consts::PI);
                }
                let from = DVec3::from_array(p.vec3("from", [0.0; 3]).map_err(&pe)?);
                self.lights.push(Light::Point {
                    position: ctm.transform_point3(from).as_vec3(),
                    intensity,
                });
            }
            "spot" => {
                let mut intensity = self.spectrum(loc, p, "I", Rgb::WHITE)? * scale;
                let from = DVec3::from_array(p.vec3("from", [0.0; 3]).map_err(&pe)?);
                let to = DVec3::from_array(p.vec3("to", [0.0, 0.0, 1.0]).map_err(&pe)?);
                let cone_angle = p.float("coneangle", 30.0).map_err(&pe)?;
                let cone_delta = p.float("conedeltaangle", 5.0).map_err(&pe)?;
                let axis = ctm
                    .transform_vector3(to - from)
                    .normalize_or_zero()
                    .as_vec3();
                let cone = SpotCone::new(axis, cone_angle, cone_delta).map_err(|e| {
                    let what = if axis == Vec3::ZERO {
                        "from and to coincide".to_string()
                    } else {
                        e.to_string()
                    };
                    self.at(loc, format!("LightSource spot: {what}"))
                })?;
                if power > 0.0 {
                    intensity *= power / cone.solid_angle();
                }
                self.lights.push(Light::Spot {
                    position: ctm.transform_point3(from).as_vec3(),
                    intensity,
                    cone,
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
            other @ ("goniometric" | "projection") => {
                self.warn(
                    loc,
                    format!(
                        "LightSource '{other}' not supported; skipped",
                        other = snippet(other)
                    ),
                );
                p.mark_all_used();
            }
            other => {
                return Err(self.at(
                    loc,
                    format!("LightSource '{other}' is unknown", other = snippet(other)),
                ));
            }
        }
        Ok(())
    }

    /// The infinite light's image: pbrt-v4's equal-area octahedral square, resampled to the
    /// equirectangular image vmerge's environment light takes, in world space.
    pub(super) fn env_map(&mut self) -> Result<Option<EnvMapDesc>, SceneError> {
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

fn constant_sky(l: Rgb) -> SkyDesc {
    SkyDesc {
        horizon: l,
        zenith: l,
        up: Vec3::Y,
    }
}
