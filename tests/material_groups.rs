//! A hit names its material and light through its triangle's group (the runs of triangles
//! with one material) where the scene has few runs, and through the per-triangle tables where
//! materials change too often: either way every hit gets its triangle's own.

use glam::Vec3;
use std::path::PathBuf;
use vmerge::accel::{AccelKind, Geometry, Primitive, Ray};
use vmerge::bsdf::{Material, MaterialKind};
use vmerge::color::Rgb;
use vmerge::sampling::{Rng, Stream};
use vmerge::scene::{CameraDesc, FovAxis, RenderDefaults, Scene, SceneParts};

/// Cells per side of the ground grid; each cell is two triangles.
const CELLS: u32 = 72;

/// A flat grid of `CELLS` x `CELLS` cells at y = 0, facing up, its triangle `t` of material
/// `material(t)`; materials 0 and 1 are grey and red, 2 emits.
fn grid(material: impl Fn(u32) -> u32, accel: AccelKind) -> Scene {
    let mut geometry = Geometry::default();
    for j in 0..=CELLS {
        for i in 0..=CELLS {
            geometry
                .positions
                .push(Vec3::new(i as f32, 0.0, j as f32) / CELLS as f32);
        }
    }
    let at = |i: u32, j: u32| j * (CELLS + 1) + i;
    for j in 0..CELLS {
        for i in 0..CELLS {
            geometry
                .triangles
                .push([at(i, j), at(i + 1, j + 1), at(i + 1, j)]);
            geometry
                .triangles
                .push([at(i, j), at(i, j + 1), at(i + 1, j + 1)]);
        }
    }
    let lambert = |name: &str, kd: Rgb, emission: Rgb| Material {
        name: name.into(),
        kind: MaterialKind::Lambert { kd },
        emission,
        two_sided: false,
    };
    let parts = SceneParts {
        source: PathBuf::from("grid"),
        triangle_materials: (0..geometry.triangles.len() as u32).map(material).collect(),
        geometry,
        materials: vec![
            lambert("grey", Rgb::splat(0.5), Rgb::BLACK),
            lambert("red", Rgb::new(0.8, 0.1, 0.1), Rgb::BLACK),
            lambert("lamp", Rgb::BLACK, Rgb::WHITE),
        ],
        material_textures: vec![Default::default(); 3],
        cameras: vec![CameraDesc {
            name: "above".into(),
            position: Vec3::new(0.5, 2.0, 0.5),
            look_at: Vec3::new(0.5, 0.0, 0.5),
            up: Vec3::Z,
            fov_deg: 60.0,
            fov_axis: FovAxis::Vertical,
            mirrored: false,
        }],
        defaults: RenderDefaults {
            resolution: [16, 16],
            max_path_length: 4,
            radius: None,
        },
        ..Default::default()
    };
    Scene::build(parts, accel).unwrap_or_else(|e| panic!("{e}"))
}

/// Every hit of 20,000 rays falling on the grid from random points above it, one by one and
/// in packets, has its triangle's material and light.
fn hits_have_their_triangles_materials(scene: &Scene, label: &str) {
    let mut rng = Rng::for_sample(5, 0, 0, Stream::Eye);
    let rays: Vec<Ray> = (0..20_000)
        .map(|_| {
            let from = Vec3::new(rng.next_f32(), 1.0, rng.next_f32());
            let to = Vec3::new(rng.next_f32(), 0.0, rng.next_f32());
            Ray::new(from, to - from)
        })
        .collect();
    let mut hits = 0;
    let mut check = |hit: vmerge::accel::Hit, ray: &Ray| {
        let surface = scene.surface_hit(ray, hit);
        let Primitive::Triangle(t) = hit.primitive else {
            panic!("{label}: a sphere hit in a scene without spheres");
        };
        assert_eq!(
            surface.material, scene.triangle_materials[t as usize],
            "{label}: triangle {t}"
        );
        assert_eq!(
            surface.light,
            scene.lights.triangle_light(t),
            "{label}: triangle {t}"
        );
        hits += 1;
    };
    for ray in &rays {
        check(
            scene
                .accel
                .intersect(ray)
                .expect("the ray ends on the grid"),
            ray,
        );
    }
    for chunk in rays.chunks_exact(8) {
        let packet: [Ray; 8] = std::array::from_fn(|i| chunk[i]);
        let mut out = [None; 8];
        scene.intersect8(&packet, 0xff, &mut out);
        for (hit, ray) in out.iter().zip(&packet) {
            check(hit.expect("the ray ends on the grid"), ray);
        }
    }
    assert_eq!(hits, 2 * rays.len(), "{label}");
}

fn accels() -> Vec<AccelKind> {
    AccelKind::ALL
        .into_iter()
        .filter(|&k| k == AccelKind::Bvh || cfg!(feature = "embree"))
        .collect()
}

#[test]
fn runs_of_materials_name_each_hits_material() {
    // Rows of cells in runs of uneven length, two of them lamps.
    let material = |t: u32| match t / (2 * CELLS) {
        row if row % 7 == 3 => 2,
        row => (row / 2 + row / 5) % 2,
    };
    for accel in accels() {
        let scene = grid(material, accel);
        hits_have_their_triangles_materials(&scene, accel.name());
    }
}

#[test]
fn materials_changing_at_every_triangle_still_name_each_hits_material() {
    // More runs than the scene makes groups of: every triangle differs from the one before.
    let material = |t: u32| if t.is_multiple_of(97) { 2 } else { t % 2 };
    for accel in accels() {
        let scene = grid(material, accel);
        hits_have_their_triangles_materials(&scene, accel.name());
    }
}
