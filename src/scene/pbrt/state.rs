//! The graphics state and transforms: blocks (attributes, transforms, objects and their
//! instances), the current transform, and the directives before WorldBegin (the camera, the
//! film, the integrator and the settings vmerge replaces with its own).

use super::import::{Block, Importer, Loc};
use super::parser::Directive;
use super::shapes::ShapeRecord;
use crate::files::snippet;
use crate::scene::{CameraDesc, FovAxis, SceneError};
use glam::{DMat4, DVec3};

impl Importer {
    pub(super) fn world_begin(&mut self, loc: Loc, _: &Directive) -> Result<(), SceneError> {
        if self.world {
            return Err(self.at(loc, "a second WorldBegin"));
        }
        self.world = true;
        self.state.ctm = DMat4::IDENTITY;
        self.named_coordinates
            .insert("world".into(), DMat4::IDENTITY);
        Ok(())
    }

    /// Directives with nothing to do: WorldEnd (the file's end closes the world),
    /// TransformTimes (no motion blur).
    pub(super) fn nothing(&mut self, _: Loc, _: &Directive) -> Result<(), SceneError> {
        Ok(())
    }

    /// AttributeBegin, TransformBegin.
    pub(super) fn begin_block(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let block = if d.name == "AttributeBegin" {
            Block::Attribute
        } else {
            Block::Transform
        };
        self.stack.push((block, loc, self.state.clone()));
        Ok(())
    }

    /// AttributeEnd, TransformEnd: the state (or only the transform) as it was at the begin.
    pub(super) fn end_block(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let name = d.name.as_str();
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
                return Err(self.at(
                    loc,
                    format!(
                        "{name} closes the {} of {}:{}",
                        open.directive(),
                        self.files[open_loc.file].display(),
                        open_loc.line
                    ),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn identity(&mut self, _: Loc, _: &Directive) -> Result<(), SceneError> {
        self.set_ctm(DMat4::IDENTITY);
        Ok(())
    }

    pub(super) fn translate(&mut self, _: Loc, d: &Directive) -> Result<(), SceneError> {
        let v = d.num_args();
        self.concat(DMat4::from_translation(DVec3::new(v[0], v[1], v[2])));
        Ok(())
    }

    pub(super) fn scale(&mut self, _: Loc, d: &Directive) -> Result<(), SceneError> {
        let v = d.num_args();
        self.concat(DMat4::from_scale(DVec3::new(v[0], v[1], v[2])));
        Ok(())
    }

    pub(super) fn rotate(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let v = d.num_args();
        let axis = DVec3::new(v[1], v[2], v[3]);
        if axis.length_squared() == 0.0 {
            return Err(self.at(loc, "Rotate about a zero axis"));
        }
        self.concat(DMat4::from_axis_angle(axis.normalize(), v[0].to_radians()));
        Ok(())
    }

    pub(super) fn look_at(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let v = d.num_args();
        let m = look_at(
            DVec3::new(v[0], v[1], v[2]),
            DVec3::new(v[3], v[4], v[5]),
            DVec3::new(v[6], v[7], v[8]),
        )
        .ok_or_else(|| self.at(loc, "LookAt: the eye, target and up are degenerate"))?;
        self.concat(m);
        Ok(())
    }

    /// Transform (replaces the current transform), ConcatTransform (multiplies it).
    pub(super) fn transform(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let name = d.name.as_str();
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
        Ok(())
    }

    pub(super) fn coordinate_system(&mut self, _: Loc, d: &Directive) -> Result<(), SceneError> {
        self.named_coordinates
            .insert(d.str_arg(0).to_string(), self.state.ctm);
        Ok(())
    }

    pub(super) fn coord_sys_transform(
        &mut self,
        loc: Loc,
        d: &Directive,
    ) -> Result<(), SceneError> {
        match self.named_coordinates.get(d.str_arg(0)) {
            Some(&m) => self.state.ctm = m,
            None => {
                let msg = format!(
                    "CoordSysTransform: no coordinate system '{}'",
                    snippet(d.str_arg(0))
                );
                self.warn(loc, msg);
            }
        }
        Ok(())
    }

    pub(super) fn active_transform(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        if !self.motion_warned {
            self.motion_warned = true;
            self.warn(
                loc,
                "ActiveTransform: no motion blur; only the start transform is used",
            );
        }
        self.ignore_transforms = d.str_arg(0) == "EndTime";
        Ok(())
    }

    pub(super) fn reverse_orientation(&mut self, _: Loc, _: &Directive) -> Result<(), SceneError> {
        self.state.reverse_orientation = !self.state.reverse_orientation;
        Ok(())
    }

    pub(super) fn object_begin(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        if self.current_object.is_some() {
            return Err(self.at(loc, "ObjectBegin inside another object"));
        }
        self.stack.push((Block::Object, loc, self.state.clone()));
        self.current_object = Some((d.str_arg(0).to_string(), Vec::new()));
        Ok(())
    }

    pub(super) fn object_end(&mut self, loc: Loc, _: &Directive) -> Result<(), SceneError> {
        match self.stack.pop() {
            Some((Block::Object, _, saved)) => {
                self.state = saved;
                if let Some((name, shapes)) = self.current_object.take() {
                    self.objects.insert(name, shapes);
                }
                Ok(())
            }
            _ => Err(self.at(loc, "unbalanced ObjectEnd: no object is open")),
        }
    }

    /// The object's shapes, flattened into the scene under the current transform.
    pub(super) fn object_instance(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        if self.current_object.is_some() {
            return Err(self.at(loc, "ObjectInstance inside an object definition"));
        }
        let Some(shapes) = self.objects.get(d.str_arg(0)) else {
            return Err(self.at(
                loc,
                format!(
                    "ObjectInstance: no object named '{}'",
                    snippet(d.str_arg(0))
                ),
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
        Ok(())
    }

    pub(super) fn film(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        let x = d.params.int("xresolution", 1280).map_err(&pe)?;
        let y = d.params.int("yresolution", 720).map_err(&pe)?;
        if !(1..=65536).contains(&x) || !(1..=65536).contains(&y) {
            return Err(self.at(loc, format!("Film: resolution {x}x{y} is not positive")));
        }
        self.resolution = Some([x as u32, y as u32]);
        d.params.string("filename").map_err(&pe)?;
        Ok(())
    }

    pub(super) fn integrator(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let depth = d.params.int("maxdepth", 5).map_err(self.pe(loc.file))?;
        if depth < 0 {
            return Err(self.at(loc, format!("Integrator: maxdepth {depth} is negative")));
        }
        // pbrt counts bounces; vmerge counts a path's segments, one more.
        self.max_path_length = Some(depth as u32 + 1);
        d.params.mark_all_used();
        self.ignored_directives
            .entry("Integrator (but maxdepth)".into())
            .or_insert(loc);
        Ok(())
    }

    /// Directives whose settings vmerge's own replace: listed in one warning at the end.
    pub(super) fn ignored(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        d.params.mark_all_used();
        self.ignored_directives.entry(d.name.clone()).or_insert(loc);
        Ok(())
    }

    /// Directives vmerge does not render: participating media (MakeNamedMedium,
    /// MediumInterface) and default parameters (Attribute). One warning per kind, at the
    /// first line, counted.
    pub(super) fn unsupported(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        d.params.mark_all_used();
        let message = match d.name.as_str() {
            "Attribute" => "Attribute: default parameters are not supported; ignored".to_string(),
            name => format!(
                "{name}: participating media are not supported; ignored (light travels as in a vacuum)"
            ),
        };
        self.warn(loc, message);
        Ok(())
    }

    pub(super) fn set_ctm(&mut self, m: DMat4) {
        if !self.ignore_transforms {
            self.state.ctm = m;
        }
    }

    pub(super) fn concat(&mut self, m: DMat4) {
        if !self.ignore_transforms {
            self.state.ctm *= m;
        }
    }

    pub(super) fn camera(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
        let pe = self.pe(loc.file);
        if d.str_arg(0) != "perspective" {
            return Err(self.at(
                loc,
                format!(
                    "Camera '{}' is not supported (perspective only)",
                    snippet(d.str_arg(0))
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
