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
    assert!((ks.r - 0.04).abs() < 1e-6 && (kd.r - 0.96).abs() < 1e-6 && (kd.b - 0.24).abs() < 1e-6);
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

/// Triangle `t`'s area and unit normal (its counter-clockwise side: the side that emits).
fn triangle(p: &SceneParts, t: usize) -> (f32, Vec3) {
    let [a, b, c] = p.geometry.triangles[t].map(|i| p.geometry.positions[i as usize]);
    let n = (b - a).cross(c - a);
    (0.5 * n.length(), n.normalize())
}

/// The warnings, each as `FILE:LINE: message` with the file's name alone.
fn warnings(p: &SceneParts) -> Vec<String> {
    p.warnings
        .iter()
        .map(|w| {
            let file = w.file.as_ref().and_then(|f| f.file_name()).unwrap();
            let line = w.line.map(|l| format!(":{l}")).unwrap_or_default();
            format!("{}{line}: {}", file.to_string_lossy(), w.message)
        })
        .collect()
}

#[test]
fn disks_and_cylinders_as_pbrt_defines_them() {
    // A disk light turned to face -y: pbrt's normal is object +z, through the transform.
    let src = "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [2 2 2]\n\
               Translate 0 1 0\nRotate 90 1 0 0\n\
               Shape \"disk\" \"float radius\" 0.5 \"float innerradius\" 0.2 \"float phimax\" 270\n\
               AttributeEnd\n\
               Shape \"cylinder\" \"float radius\" 0.25 \"float zmin\" 0.5 \"float zmax\" -0.25\n";
    let p = parts(src);
    let disk: Vec<usize> = (0..p.geometry.triangles.len())
        .filter(|&t| p.materials[p.triangle_materials[t] as usize].emission == Rgb::splat(2.0))
        .collect();
    let area: f32 = disk.iter().map(|&t| triangle(&p, t).0).sum();
    let exact = 0.75 * std::f32::consts::PI * (0.25 - 0.04);
    assert!((area / exact - 1.0).abs() < 1e-5, "{area} {exact}");
    assert!(disk.iter().all(|&t| triangle(&p, t).1.y < -0.999));
    let uvs = &p.shading.uvs;
    let (us, vs): (Vec<f32>, Vec<f32>) = disk
        .iter()
        .flat_map(|&t| p.shading.triangle_uvs[t])
        .map(|i| (uvs[i as usize].x, uvs[i as usize].y))
        .unzip();
    let range = |x: &[f32]| {
        x.iter()
            .fold((1.0f32, 0.0f32), |(a, b), &v| (a.min(v), b.max(v)))
    };
    assert_eq!((range(&us), range(&vs)), ((0.0, 1.0), (0.0, 1.0)));
    // The cylinder takes zmin and zmax in either order and faces outwards.
    let cylinder: Vec<usize> = (0..p.geometry.triangles.len())
        .filter(|t| !disk.contains(t))
        .collect();
    let area: f32 = cylinder.iter().map(|&t| triangle(&p, t).0).sum();
    let exact = std::f32::consts::TAU * 0.25 * 0.75;
    assert!((area / exact - 1.0).abs() < 1e-5, "{area} {exact}");
    for &t in &cylinder {
        let [a, ..] = p.geometry.triangles[t].map(|i| p.geometry.positions[i as usize]);
        assert!(triangle(&p, t).1.dot(Vec3::new(a.x, a.y, 0.0)) > 0.0);
        assert!((-0.25..=0.5).contains(&a.z));
    }
    // ReverseOrientation flips a quadric, and so does a transform that swaps handedness (its
    // normal is then the other side of the transformed normal, as pbrt's is).
    let facing = |prefix: &str| {
        let p = parts(&format!("WorldBegin\n{prefix}\nShape \"disk\"\n"));
        triangle(&p, 0).1.z
    };
    assert!(facing("") > 0.999);
    assert!(facing("ReverseOrientation") < -0.999);
    assert!(facing("Scale -1 1 1") < -0.999);
    assert!(facing("Scale -1 1 1\nReverseOrientation") > 0.999);
    // Bad sizes name the line.
    for (shape, what) in [
        (
            "\"disk\" \"float innerradius\" 1",
            "innerradius 1 is not in [0, radius 1)",
        ),
        ("\"disk\" \"float radius\" 0", "radius 0 is not positive"),
        (
            "\"cylinder\" \"float zmin\" 1",
            "zmin 1 and zmax 1 leave no height",
        ),
        (
            "\"cylinder\" \"float phimax\" -5",
            "phimax -5 is not positive",
        ),
    ] {
        let src = format!("WorldBegin\n\nShape {shape}\n");
        let e = error(&[("scene.pbrt", src.as_bytes())]);
        assert!(
            e.contains("scene.pbrt:3: Shape ") && e.contains(what),
            "{e}"
        );
    }
}

#[test]
fn interface_shapes_are_no_surface() {
    let src = "WorldBegin\nMakeNamedMaterial \"boundary\" \"string type\" \"interface\"\n\
               MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\n\
               AttributeBegin\nNamedMaterial \"boundary\"\nMediumInterface \"fog\" \"\"\n\
               Shape \"sphere\"\nShape \"trianglemesh\" {QUAD}\nAttributeEnd\n\
               Shape \"trianglemesh\" {QUAD}\n"
        .replace("{QUAD}", QUAD);
    let p = parts(&src);
    assert_eq!(p.geometry.spheres.len(), 0);
    assert_eq!(p.geometry.triangles.len(), 2);
    let w = warnings(&p);
    let find = |s: &str| {
        w.iter()
            .filter(|x| x.contains(s))
            .cloned()
            .collect::<Vec<_>>()
    };
    let dropped = find("'interface' material");
    assert_eq!(dropped.len(), 1, "{w:?}");
    assert!(
        dropped[0].contains("scene.pbrt:7: ")
            && dropped[0].contains("the medium it bounds is ignored")
            && dropped[0].ends_with("(1 more like this)"),
        "{w:?}"
    );
    assert!(
        find("scene.pbrt:3: MakeNamedMedium: participating media are not supported").len() == 1
    );
    assert!(
        find("scene.pbrt:6: MediumInterface: participating media are not supported").len() == 1
    );
    // Nothing but interfaces: the error says what was there.
    let only = "WorldBegin\nMaterial \"interface\"\nShape \"sphere\"\n";
    let e = error(&[("scene.pbrt", only.as_bytes())]);
    assert!(
        e.contains(
            "scene.pbrt:3: the scene has no geometry left: Shape with an 'interface' material"
        ),
        "{e}"
    );
}

#[test]
fn skipped_shapes_are_warned_once_at_their_line() {
    let curve = "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"float width\" 0.1\n";
    let src = format!(
        "WorldBegin\nAttribute \"shape\" \"float radius\" 2\n{curve}{curve}{curve}\
         Shape \"loopsubdiv\" {QUAD}\nShape \"sphere\"\n"
    );
    let p = parts(&src);
    let w = warnings(&p);
    let about = |s: &str| {
        w.iter()
            .filter(|x| x.contains(s))
            .cloned()
            .collect::<Vec<_>>()
    };
    assert_eq!(
        about("curve"),
        ["scene.pbrt:3: Shape 'curve' not supported; skipped (2 more like this)"],
        "{w:?}"
    );
    assert_eq!(
        about("loopsubdiv"),
        ["scene.pbrt:6: Shape 'loopsubdiv' not supported; skipped"]
    );
    assert_eq!(about("scene.pbrt:2: Attribute: ").len(), 1, "{w:?}");
    // A scene of curves alone says so, at the first curve.
    let src = format!("WorldBegin\n{curve}{curve}");
    let e = error(&[("scene.pbrt", src.as_bytes())]);
    assert!(
        e.contains("scene.pbrt:2: the scene has no geometry left: Shape 'curve' not supported; skipped (1 more shapes skipped)"),
        "{e}"
    );
}
