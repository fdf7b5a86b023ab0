//! pbrt-v4's float image textures on the parameters pbrt takes as textures: a texture on a
//! roughness (both axes, or u and v apart), a coated conductor's conductor roughness, a
//! diffuse transmitter's transmittance and a mix's amount reaches the BSDF at each point. The
//! BSDF at a texel's centre is the one the importer builds for that texel's value given as a
//! constant, and a mix picks its second material at the rate its amount texture gives there.
//! The TOML format's roughness textures of one axis each do the same, and a material's
//! textures stay its own after an emitting mix (which adds three materials at once).

mod common;

use common::load_file;
use glam::{Vec2, Vec3};
use std::path::Path;
use vmerge::accel::Ray;
use vmerge::bsdf::{Bsdf, Bxdf, MaterialKind, TransportMode};
use vmerge::color::Rgb;
use vmerge::sampling::Rng;
use vmerge::scene::Scene;
use vmerge::texture::{write_pfm, Texture};

/// The centres of the left and right halves of an image whose left half holds one value and
/// right half another (8 texels wide, so bilinear lookups there see one value only).
const LEFT: Vec2 = Vec2::new(0.25, 0.5);
const RIGHT: Vec2 = Vec2::new(0.75, 0.5);

/// Writes an 8 x 1 PFM: `left` in its left half, `right` in its right half.
fn halves(dir: &Path, name: &str, left: f32, right: f32) {
    let texels = (0..8)
        .map(|x| Rgb::splat(if x < 4 { left } else { right }))
        .collect();
    let image = Texture::new(8, 1, texels).unwrap();
    std::fs::write(dir.join(name), write_pfm(&image)).unwrap();
}

/// Loads a scene of one unit-uv quad in the z = 0 plane (u along x, v along y) with the
/// material `material`, after the directives `textures`.
fn quad(dir: &Path, textures: &str, material: &str) -> Scene {
    let text = format!(
        r#"LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 30
Film "rgb" "integer xresolution" 8 "integer yresolution" 8
WorldBegin
LightSource "point" "point3 from" [0 0 3] "rgb I" [1 1 1]
{textures}
MakeNamedMaterial "a" "string type" "diffuse" "rgb reflectance" [0.2 0.2 0.2]
MakeNamedMaterial "b" "string type" "diffuse" "rgb reflectance" [0.8 0.8 0.8]
{material}
Shape "trianglemesh" "integer indices" [0 1 2 0 2 3]
  "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "point2 uv" [0 0  1 0  1 1  0 1]
"#
    );
    let path = dir.join("scene.pbrt");
    std::fs::write(&path, text).unwrap();
    load_file(&path)
}

/// The quad's material as the BSDF sees it at `uv`: its kind with the textures there.
fn kind_at(scene: &Scene, uv: Vec2) -> MaterialKind {
    let m = scene.triangle_materials[0];
    scene.materials[m as usize]
        .kind
        .with_albedo(scene.albedo(m, uv))
}

/// The quad's material where `material` gives every parameter as a constant.
fn constant(material: &str) -> MaterialKind {
    let dir = tempfile::tempdir().unwrap();
    let scene = quad(dir.path(), "", material);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    scene.materials[scene.triangle_materials[0] as usize]
        .kind
        .clone()
}

/// Value of the kind's BSDF on the quad for a fixed pair of directions off the normal (in
/// reflection, or in transmission where `transmit`).
fn value(kind: &MaterialKind, transmit: bool) -> Rgb {
    let wo = Vec3::new(0.3, 0.2, 0.9).normalize();
    let wi = Vec3::new(-0.4, 0.1, if transmit { -0.8 } else { 0.8 }).normalize();
    Bsdf::new(kind, Vec3::Z, wo, TransportMode::Radiance)
        .unwrap()
        .eval(wi)
        .f
}

/// The material's kind at the two halves equals its constant twins', and their BSDFs differ.
fn assert_texture_reaches_bsdf(scene: &Scene, left: &str, right: &str, transmit: bool) {
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let (at_left, at_right) = (kind_at(scene, LEFT), kind_at(scene, RIGHT));
    assert_eq!(at_left, constant(left), "left half");
    assert_eq!(at_right, constant(right), "right half");
    let (a, b) = (value(&at_left, transmit), value(&at_right, transmit));
    assert!(
        (a.r - b.r).abs() > 0.05 * a.r.max(b.r),
        "the two halves scatter alike: {a:?} {b:?}"
    );
}

#[test]
fn roughness_texture_reaches_a_conductor() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "r.pfm", 0.05, 0.4);
    let scene = quad(
        dir.path(),
        r#"Texture "r" "float" "imagemap" "string filename" "r.pfm""#,
        r#"Material "conductor" "texture roughness" "r""#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "conductor" "float roughness" 0.05"#,
        r#"Material "conductor" "float roughness" 0.4"#,
        false,
    );
}

#[test]
fn u_and_v_roughness_textures_reach_a_conductor_apart() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "u.pfm", 0.05, 0.4);
    halves(dir.path(), "v.pfm", 0.3, 0.02);
    let textures = r#"Texture "u" "float" "imagemap" "string filename" "u.pfm"
Texture "v" "float" "imagemap" "string filename" "v.pfm""#;
    let scene = quad(
        dir.path(),
        textures,
        r#"Material "conductor" "texture uroughness" "u" "texture vroughness" "v" "bool remaproughness" false"#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "conductor" "float uroughness" 0.05 "float vroughness" 0.3 "bool remaproughness" false"#,
        r#"Material "conductor" "float uroughness" 0.4 "float vroughness" 0.02 "bool remaproughness" false"#,
        false,
    );
    // One axis an image, the other a number (on either side).
    let scene = quad(
        dir.path(),
        textures,
        r#"Material "conductor" "texture uroughness" "u" "float vroughness" 0.2"#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "conductor" "float uroughness" 0.05 "float vroughness" 0.2"#,
        r#"Material "conductor" "float uroughness" 0.4 "float vroughness" 0.2"#,
        false,
    );
    let scene = quad(
        dir.path(),
        textures,
        r#"Material "conductor" "float uroughness" 0.2 "texture vroughness" "v""#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "conductor" "float uroughness" 0.2 "float vroughness" 0.3"#,
        r#"Material "conductor" "float uroughness" 0.2 "float vroughness" 0.02"#,
        false,
    );
}

#[test]
fn scaled_roughness_texture_reaches_a_dielectric() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "r.pfm", 0.1, 0.8);
    let scene = quad(
        dir.path(),
        r#"Texture "r" "float" "imagemap" "string filename" "r.pfm"
Texture "half" "float" "scale" "texture tex" "r" "float scale" 0.5"#,
        r#"Material "dielectric" "texture roughness" "half""#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "dielectric" "float roughness" 0.05"#,
        r#"Material "dielectric" "float roughness" 0.4"#,
        true,
    );
}

/// Where a roughness texture is 0 the dielectric is glass (a delta), elsewhere rough: the
/// BSDF and what `upg`'s tentative rays see of the surface agree on which.
#[test]
fn roughness_texture_makes_a_dielectric_smooth_where_it_is_zero() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "r.pfm", 0.0, 0.3);
    let scene = quad(
        dir.path(),
        r#"Texture "r" "float" "imagemap" "string filename" "r.pfm""#,
        r#"Material "dielectric" "texture roughness" "r""#,
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    assert!(kind_at(&scene, LEFT).is_delta());
    assert!(!kind_at(&scene, RIGHT).is_delta());
    assert_eq!(
        kind_at(&scene, RIGHT),
        constant(r#"Material "dielectric" "float roughness" 0.3"#)
    );
    // x = -0.5 and 0.5 are u = 0.25 and 0.75.
    let delta = |x: f32| {
        let hit = scene
            .intersect(&Ray::new(Vec3::new(x, 0.0, 1.0), -Vec3::Z))
            .expect("the quad is hit");
        scene.hits_delta_surface(&hit.hit)
    };
    assert!(delta(-0.5));
    assert!(!delta(0.5));
}

#[test]
fn conductor_roughness_texture_reaches_a_coated_conductor() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "r.pfm", 0.02, 0.5);
    let scene = quad(
        dir.path(),
        r#"Texture "r" "float" "imagemap" "string filename" "r.pfm""#,
        r#"Material "coatedconductor" "texture conductor.roughness" "r" "float interface.roughness" 0.1"#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "coatedconductor" "float conductor.roughness" 0.02 "float interface.roughness" 0.1"#,
        r#"Material "coatedconductor" "float conductor.roughness" 0.5 "float interface.roughness" 0.1"#,
        false,
    );
}

#[test]
fn transmittance_texture_reaches_a_diffuse_transmitter() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "t.pfm", 0.1, 0.6);
    let scene = quad(
        dir.path(),
        r#"Texture "t" "spectrum" "imagemap" "string filename" "t.pfm""#,
        r#"Material "diffusetransmission" "texture transmittance" "t" "rgb reflectance" [0.3 0.3 0.3] "float scale" 0.5"#,
    );
    assert_texture_reaches_bsdf(
        &scene,
        r#"Material "diffusetransmission" "rgb transmittance" [0.1 0.1 0.1] "rgb reflectance" [0.3 0.3 0.3] "float scale" 0.5"#,
        r#"Material "diffusetransmission" "rgb transmittance" [0.6 0.6 0.6] "rgb reflectance" [0.3 0.3 0.3] "float scale" 0.5"#,
        true,
    );
}

/// A mix whose amount texture is 0.2 on the left half and 0.7 on the right picks its second
/// material there at those rates (within 4 standard errors of a binomial count).
#[test]
fn amount_texture_picks_materials_by_region() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "amount.pfm", 0.2, 0.7);
    let scene = quad(
        dir.path(),
        r#"Texture "amount" "float" "imagemap" "string filename" "amount.pfm""#,
        r#"MakeNamedMaterial "m" "string type" "mix" "string materials" ["a" "b"] "texture amount" "amount"
NamedMaterial "m""#,
    );
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let second = scene.materials.iter().position(|m| m.name == "b").unwrap() as u32;
    let mut rng = Rng::from_seed(7, 1);
    let n = 20_000;
    // u in [0.1, 0.4] and [0.6, 0.9]: where the bilinear lookup sees one half's value.
    for (u0, expected) in [(0.1f32, 0.2f64), (0.6, 0.7)] {
        let mut count = 0;
        for _ in 0..n {
            let u = u0 + 0.3 * rng.next_f32();
            let y = 2.0 * rng.next_f32() - 1.0;
            let hit = scene
                .intersect(&Ray::new(Vec3::new(2.0 * u - 1.0, y, 1.0), -Vec3::Z))
                .expect("the quad is hit");
            count += usize::from(hit.material == second);
        }
        let rate = count as f64 / n as f64;
        let sigma = (expected * (1.0 - expected) / n as f64).sqrt();
        assert!(
            (rate - expected).abs() < 4.0 * sigma,
            "u from {u0}: second material at rate {rate}, expected {expected}"
        );
    }
}

/// The material "m" of a TOML scene of one sphere whose `[material.m]` table has `keys`.
fn toml_material(dir: &Path, keys: &str) -> (Scene, u32) {
    let text = format!(
        "[render]\nresolution = [8, 8]\n\
         [[camera]]\nposition = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nfov = 30.0\n\
         [[light]]\ntype = \"point\"\nposition = [0.0, 0.0, 3.0]\nintensity = [1.0, 1.0, 1.0]\n\
         [[sphere]]\ncenter = [0.0, 0.0, 0.0]\nradius = 1.0\nmaterial = \"m\"\n\
         [material.m]\ntype = \"conductor\"\n{keys}\n"
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    let scene = load_file(&path);
    let m = scene.materials.iter().position(|m| m.name == "m").unwrap() as u32;
    (scene, m)
}

/// `uroughness_texture` and `vroughness_texture` replace one axis each, the other axis keeping
/// its number.
#[test]
fn toml_roughness_textures_of_one_axis_each() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "u.pfm", 0.05, 0.4);
    halves(dir.path(), "v.pfm", 0.3, 0.02);
    let at = |keys: &str, uv: Vec2| {
        let (scene, m) = toml_material(dir.path(), keys);
        scene.materials[m as usize]
            .kind
            .with_albedo(scene.albedo(m, uv))
    };
    let constant = |keys: &str| {
        let (scene, m) = toml_material(dir.path(), keys);
        scene.materials[m as usize].kind.clone()
    };
    let u_only = "uroughness_texture = \"u.pfm\"\nvroughness = 0.2";
    assert_eq!(
        at(u_only, LEFT),
        constant("uroughness = 0.05\nvroughness = 0.2")
    );
    assert_eq!(
        at(u_only, RIGHT),
        constant("uroughness = 0.4\nvroughness = 0.2")
    );
    let v_only = "uroughness = 0.2\nvroughness_texture = \"v.pfm\"";
    assert_eq!(
        at(v_only, LEFT),
        constant("uroughness = 0.2\nvroughness = 0.3")
    );
    let both = "uroughness_texture = \"u.pfm\"\nvroughness_texture = \"v.pfm\"";
    assert_eq!(
        at(both, RIGHT),
        constant("uroughness = 0.4\nvroughness = 0.02")
    );
}

/// An emitting mix adds variants of its two materials before its own: a textured material
/// defined after it still gets its own texture.
#[test]
fn textures_stay_with_their_material_after_an_emitting_mix() {
    let dir = tempfile::tempdir().unwrap();
    halves(dir.path(), "r.pfm", 0.05, 0.4);
    let scene = quad(
        dir.path(),
        r#"Texture "r" "float" "imagemap" "string filename" "r.pfm"
MakeNamedMaterial "c" "string type" "diffuse"
MakeNamedMaterial "d" "string type" "conductor"
MakeNamedMaterial "m" "string type" "mix" "string materials" ["c" "d"]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [1 1 1]
NamedMaterial "m"
Shape "sphere" "float radius" 0.1
AttributeEnd"#,
        r#"Material "conductor" "texture roughness" "r""#,
    );
    assert_eq!(
        kind_at(&scene, RIGHT),
        constant(r#"Material "conductor" "float roughness" 0.4"#)
    );
}
