//! The importer over whole files: transforms and blocks, materials, lights, meshes, textures,
//! includes and instances.

use super::import::import;
use super::ply::tests::binary_ply;
use crate::bsdf::MaterialKind;
use crate::color::Rgb;
use crate::scene::{SceneError, SceneParts, Warning};
use crate::texture;
use glam::Vec3;

/// Writes `files` (name, contents) to a fresh folder and imports the first.
fn import_files(files: &[(&str, &[u8])]) -> (tempfile::TempDir, Result<SceneParts, SceneError>) {
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
    let src = "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 30\nWorldBegin\n\
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
fn named_materials_map_onto_their_bsdfs() {
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
    let MaterialKind::CoatedDiffuse { r, coating } = kinds[1] else {
        panic!("{:?}", kinds[1])
    };
    assert_eq!(r, Rgb::new(1.0, 0.5, 0.25));
    // pbrt's defaults, and the roughness on both axes (remapped when the BSDF is built).
    assert_eq!(
        (coating.eta, coating.thickness, coating.max_depth),
        (1.5, 0.01, 10)
    );
    assert_eq!((coating.roughness.u, coating.roughness.v), (0.01, 0.01));
    assert!(coating.roughness.remap);
    assert!(
        matches!(kinds[2], MaterialKind::Conductor { .. }),
        "{:?}",
        kinds[2]
    );
    assert!(
        matches!(kinds[3], MaterialKind::Conductor { .. }),
        "{:?}",
        kinds[3]
    );
    assert_eq!(kinds[4], MaterialKind::Glass { ior: 1.33 });
    assert_eq!(
        kinds[5],
        MaterialKind::DiffuseTransmission {
            r: Rgb::splat(0.25),
            t: Rgb::splat(0.125)
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
    // Every one of these has its own model: nothing is approximated.
    assert!(warned.is_empty(), "{warned:?}");
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
    let src = "WorldBegin\nTranslate 0 0 2\nShape \"plymesh\" \"string filename\" \"mesh.ply\"\n";
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
         Material \"diffusetransmission\" \"texture reflectance\" \"half\" \"float scale\" 0.96\nShape \"trianglemesh\" {QUAD}\n"
    );
    let (_dir, result) = import_files(&[("scene.pbrt", src.as_bytes()), ("t.pfm", &pfm)]);
    let p = result.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(p.textures.len(), 2);
    let kd = |m: usize| p.material_textures[m].kd.unwrap() as usize;
    assert_eq!(p.textures[kd(0)].texels, image.texels);
    // The scale texture's 0.5, times diffusetransmission's scale 0.96.
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
