//! Both scene formats go through one builder: the same over-energetic diffuse transmitter
//! (reflectance 0.75 beside transmittance 0.5), written as a TOML table and as the pbrt
//! material, gives the same materials and the same warning, or without `--lenient` the same
//! refusal; and loading returns its warnings, which the CLI prints.

use std::path::{Path, PathBuf};
use std::process::Command;
use vmerge::accel::AccelKind;
use vmerge::bsdf::{Material, MaterialKind};
use vmerge::color::Rgb;
use vmerge::scene::{self, LoadOptions, Scene, Warning};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/builder-twin")
        .join(name)
}

fn load(name: &str, lenient: bool) -> Result<Scene, scene::SceneError> {
    let options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient,
        shading_normals: true,
    };
    scene::load(&fixture(name), &options)
}

/// The materials of the triangles, then of the spheres, as (kind, emission): what the twins
/// share (their names follow each format's conventions).
fn surfaces(scene: &Scene) -> Vec<(MaterialKind, Rgb)> {
    let of = |m: &u32| {
        let Material { kind, emission, .. } = scene.material(*m);
        (kind.clone(), *emission)
    };
    scene
        .triangle_materials
        .iter()
        .chain(&scene.sphere_materials)
        .map(of)
        .collect()
}

fn energy_warnings(scene: &Scene) -> Vec<&Warning> {
    scene
        .warnings
        .iter()
        .filter(|w| w.message.contains("exceeds 1"))
        .collect()
}

#[test]
fn both_formats_build_the_same_materials_and_warnings() {
    let toml = load("scene.toml", true).unwrap_or_else(|e| panic!("{e}"));
    let pbrt = load("scene.pbrt", true).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (surfaces(&toml), surfaces(&pbrt));
    assert_eq!(a.len(), 5, "{a:?}");
    assert_eq!(a, b);
    // Scaled per channel by 1 / (r + t), the ratio of r to t kept.
    let sum = 0.75f32 + 0.5;
    assert_eq!(
        a[4].0,
        MaterialKind::DiffuseTransmission {
            r: Rgb::splat(0.75 * (1.0 / sum)),
            t: Rgb::splat(0.5 * (1.0 / sum)),
        }
    );
    // One warning each, the same words; only where it points differs with the format.
    let (wa, wb) = (energy_warnings(&toml), energy_warnings(&pbrt));
    assert_eq!((wa.len(), wb.len()), (1, 1), "{wa:?} {wb:?}");
    assert_eq!(wa[0].message, wb[0].message);
    assert_eq!(
        wa[0].message,
        "reflectance + transmittance = [1.25, 1.25, 1.25] exceeds 1; scaled down to conserve energy"
    );
    assert_eq!(wa[0].file.as_deref(), Some(fixture("scene.toml").as_path()));
    assert_eq!(wa[0].entry.as_deref(), Some("material.shiny"));
    assert_eq!(wb[0].file.as_deref(), Some(fixture("scene.pbrt").as_path()));
    assert_eq!(
        (wb[0].line, wb[0].entry.as_deref()),
        (Some(7), Some("material 'shiny'"))
    );
}

#[test]
fn without_lenient_both_formats_refuse_the_material() {
    for (name, place) in [
        ("scene.toml", "scene.toml: material.shiny: "),
        ("scene.pbrt", "scene.pbrt:7: material 'shiny': "),
    ] {
        let e = match load(name, false) {
            Ok(_) => panic!("{name} loaded"),
            Err(e) => e.to_string(),
        };
        let expected =
            format!("{place}reflectance + transmittance = [1.25, 1.25, 1.25] exceeds 1 and would create energy");
        assert!(e.contains(&expected), "{e}");
    }
}

#[test]
fn the_cli_prints_the_warnings_the_library_returns() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["scene.toml", "scene.pbrt"] {
        let scene = fixture(name);
        let loaded = load(name, true).unwrap_or_else(|e| panic!("{e}"));
        assert!(!loaded.warnings.is_empty());
        let out = Command::new(env!("CARGO_BIN_EXE_vmerge"))
            .arg("render")
            .arg(&scene)
            .args(["--lenient", "-n", "1", "--no-png", "-o"])
            .arg(dir.path().join("out.exr"))
            .output()
            .unwrap();
        assert!(out.status.success(), "{out:?}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        let printed: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with("warning: "))
            .collect();
        let returned: Vec<String> = loaded
            .warnings
            .iter()
            .map(|w| format!("warning: {w}"))
            .collect();
        assert_eq!(printed, returned, "{stderr}");
    }
}
