//! Shapes: triangle and bilinear meshes, PLY files, spheres, and disks and cylinders (as
//! meshes, `quadrics`), recorded with their graphics state and laid out in world space at the
//! end (instances expanded). Shapes of an `interface` material are no surface and dropped.

use super::import::{Importer, Loc};
use super::parser::{Directive, ParamList, ParamType, ParseError};
use super::ply::{self, PlyMesh};
use super::quadrics;
use super::textures::FloatTex;
use crate::accel::{Geometry, Sphere};
use crate::bsdf::Params;
use crate::color::Rgb;
use crate::files::{self, snippet, FileError, Kind};
use crate::options::OptionName;
use crate::scene::builder::{MaterialDesc, Origin};
use crate::scene::{alpha, MeshShading, SceneError, MAX_COORDINATE};
use glam::{DMat3, DMat4, DVec3, Vec2, Vec3};
use rayon::prelude::*;
use sha2::{Digest, Sha256};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

/// A mesh in object space, shared between the instances that use it.
#[derive(Debug)]
pub(super) enum MeshSource {
    Inline(Arc<PlyMesh>),
    Ply(PathBuf),
}

#[derive(Clone, Debug)]
pub(super) enum ShapeKind {
    Mesh(Arc<MeshSource>),
    Sphere {
        radius: f64,
    },
    /// A disk or cylinder: its front is pbrt's quadric normal, which flips under
    /// ReverseOrientation and under a transform that swaps handedness.
    Quadric(Arc<PlyMesh>),
}

/// A shape with the graphics state it was declared in.
#[derive(Clone, Debug)]
pub(super) struct ShapeRecord {
    pub(super) kind: ShapeKind,
    pub(super) ctm: DMat4,
    pub(super) reverse_orientation: bool,
    pub(super) material: u32,
    pub(super) loc: Loc,
    /// Its alpha cut-out, if any.
    pub(super) alpha: Option<FloatTex>,
}

/// The shapes in world space.
pub(super) struct Laid {
    pub(super) geometry: Geometry,
    pub(super) triangle_materials: Vec<u32>,
    pub(super) sphere_materials: Vec<u32>,
    pub(super) shading: MeshShading,
    /// Degenerate triangles dropped.
    pub(super) dropped: usize,
}

impl Importer {
    pub(super) fn shape(&mut self, loc: Loc, d: &Directive) -> Result<(), SceneError> {
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
            "disk" => {
                let radius = p.float("radius", 1.0).map_err(&pe)?;
                let inner = p.float("innerradius", 0.0).map_err(&pe)?;
                let height = p.float("height", 0.0).map_err(&pe)?;
                let phimax = self.phimax(loc, "disk", p)?;
                if !(radius > 0.0 && radius.is_finite()) {
                    return Err(
                        self.at(loc, format!("Shape disk: radius {radius} is not positive"))
                    );
                }
                if !(0.0..radius).contains(&inner) {
                    return Err(self.at(
                        loc,
                        format!("Shape disk: innerradius {inner} is not in [0, radius {radius})"),
                    ));
                }
                let mesh = quadrics::disk(radius.into(), inner.into(), height.into(), phimax);
                ShapeKind::Quadric(Arc::new(mesh))
            }
            "cylinder" => {
                let radius = p.float("radius", 1.0).map_err(&pe)?;
                let z0 = p.float("zmin", -1.0).map_err(&pe)?;
                let z1 = p.float("zmax", 1.0).map_err(&pe)?;
                let phimax = self.phimax(loc, "cylinder", p)?;
                if !(radius > 0.0 && radius.is_finite()) {
                    return Err(self.at(
                        loc,
                        format!("Shape cylinder: radius {radius} is not positive"),
                    ));
                }
                if z0.is_nan() || z1.is_nan() || z0 == z1 {
                    return Err(self.at(
                        loc,
                        format!("Shape cylinder: zmin {z0} and zmax {z1} leave no height"),
                    ));
                }
                // pbrt takes the two in either order.
                let (zmin, zmax) = (z0.min(z1), z0.max(z1));
                let mesh = quadrics::cylinder(radius.into(), zmin.into(), zmax.into(), phimax);
                ShapeKind::Quadric(Arc::new(mesh))
            }
            other @ ("loopsubdiv" | "curve" | "bilinearpatch") => {
                let what = format!("Shape '{other}' not supported", other = snippet(other));
                self.skip_shape(loc, what);
                p.mark_all_used();
                return Ok(());
            }
            other => {
                return Err(self.at(
                    loc,
                    format!("unknown shape '{other}'", other = snippet(other)),
                ))
            }
        };
        let mut alpha = self.shape_alpha(loc, p)?;
        if alpha.is_some() && matches!(kind, ShapeKind::Sphere { .. }) {
            self.warn(
                loc,
                "Shape sphere: alpha (cut-outs) ignored; rendered opaque",
            );
            alpha = None;
        }
        let base = self.current_material()?;
        if self.interfaces.contains(&base) {
            p.mark_all_used();
            self.skip_shape(
                loc,
                "Shape with an 'interface' material: no surface, rays pass; the medium it bounds is ignored (participating media are not supported)".to_string(),
            );
            return Ok(());
        }
        let material = self.shape_material()?;
        let record = ShapeRecord {
            kind,
            ctm: self.state.ctm,
            reverse_orientation: self.state.reverse_orientation,
            material,
            loc,
            alpha,
        };
        match &mut self.current_object {
            Some((_, shapes)) => shapes.push(record),
            None => self.shapes.push(record),
        }
        Ok(())
    }

    /// A shape left out of the scene: warned (once per kind, with a count), and remembered in
    /// case nothing else is left.
    pub(super) fn skip_shape(&mut self, loc: Loc, what: String) {
        self.warn(loc, format!("{what}; skipped"));
        self.skipped_shapes.push((loc, what));
    }

    /// A quadric's `phimax` in radians; pbrt clamps it to 360 degrees.
    fn phimax(&self, loc: Loc, shape: &str, p: &ParamList) -> Result<f64, SceneError> {
        let phimax = p.float("phimax", 360.0).map_err(self.pe(loc.file))?;
        if phimax.is_nan() || phimax <= 0.0 {
            return Err(self.at(
                loc,
                format!("Shape {shape}: phimax {phimax} is not positive"),
            ));
        }
        Ok(f64::from(phimax.min(360.0)).to_radians())
    }

    /// pbrt-v4's `interface` material: no surface at all. Shapes with it are dropped; the
    /// material exists so that NamedMaterial and the graphics state can refer to it.
    pub(super) fn interface_material(&mut self, loc: Loc, name: &str) -> Result<u32, SceneError> {
        let origin = Origin {
            file: self.files[loc.file].clone(),
            line: Some(loc.line),
            entry: format!("material '{name}'", name = snippet(name)),
        };
        let params = Params::new().with_color("kd", Rgb::BLACK);
        let index = self
            .builder
            .material(&origin, MaterialDesc::new(name, "lambert", params))?;
        self.material_textures.push(None);
        self.interfaces.insert(index);
        Ok(index)
    }

    /// Reads the PLY files (in parallel, each once), then lays all shapes out in order.
    pub(super) fn lay_out_shapes(&mut self) -> Result<Laid, SceneError> {
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
                    self.skip_shape(loc, format!("Shape plymesh: {} is missing", path.display()));
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
        let mut alpha_images = HashMap::new();
        let shapes = std::mem::take(&mut self.shapes);
        for s in &shapes {
            let mesh = match &s.kind {
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
                    // pbrt's dp/du is the object z axis crossed with the point, which the
                    // transform turns into its image crossed with the normal, reversed by a
                    // transform that swaps handedness.
                    let pole = m.z_axis * m.determinant().signum();
                    shading.sphere_poles.push(pole.normalize().as_vec3());
                    continue;
                }
                ShapeKind::Mesh(source) => match &**source {
                    MeshSource::Inline(m) => Arc::clone(m),
                    MeshSource::Ply(path) => match meshes.get(path) {
                        Some(m) => Arc::clone(m),
                        None => continue,
                    },
                },
                ShapeKind::Quadric(m) => {
                    // place_mesh turns each triangle to its vertex normals, which carry
                    // pbrt's flips of a quadric's normal.
                    let swaps = DMat3::from_mat4(s.ctm).determinant() < 0.0;
                    if s.reverse_orientation ^ swaps {
                        Arc::new(quadrics::flipped(m))
                    } else {
                        Arc::clone(m)
                    }
                }
            };
            let first = geometry.positions.len();
            let first_triangle = geometry.triangles.len();
            dropped += place_mesh(
                &mesh,
                s,
                &mut geometry,
                &mut triangle_materials,
                &mut shading,
            );
            if let Some(tex) = &s.alpha {
                if let Some(a) = self.cutout_alpha(tex, &mut alpha_images)? {
                    let triangles = first_triangle..geometry.triangles.len();
                    alpha::cut_out(&mut geometry, &shading, triangles, &a);
                }
            }
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
        Ok(Laid {
            geometry,
            triangle_materials,
            sphere_materials,
            shading,
            dropped,
        })
    }
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
    // A patch's vertices are p00, p10, p01, p11: each half starts with an edge along pbrt's
    // u, p10 - p00 and p01 - p11, which pbrt's default uvs of a triangle take for dp/du.
    let triangles = if bilinear {
        indices
            .chunks_exact(4)
            .flat_map(|q| [[q[0], q[1], q[3]], [q[3], q[2], q[0]]])
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
        // Turned by swapping the first two vertices: the first edge, along which pbrt's default
        // uvs put dp/du, stays on its line.
        let t = if front.dot(ng) < 0.0 {
            [b, a, c]
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
