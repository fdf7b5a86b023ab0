//! Glass on meshes: thin walls, faces wound against the rest of their shell, total internal
//! reflection inside a wall, and the real lamp-bulb case these come from.
//!
//! The rule under test (src/bsdf/glass.rs): each hit decides from the geometric normal alone
//! whether it enters (`wo . ng > 0`) or leaves the glass, with no memory of earlier hits.

mod common;

use common::{assert_agree, assert_means_agree, load_file, options, render_stats, PixelStats};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use vmerge::accel::{AccelKind, Geometry};
use vmerge::bsdf::{Material, MaterialKind};
use vmerge::color::Rgb;
use vmerge::options::Technique;
use vmerge::options::{RenderOptions, SamplerKind};
use vmerge::sampling::Rng;
use vmerge::scene::{Camera, CameraDesc, FovAxis, RenderDefaults, Scene, SceneParts};

const IOR: f64 = 1.5;
const MAX_PATH_LENGTH: u32 = 10;
/// Half the side of the square glass panes and of the emitter behind them.
const HALF: f64 = 2.0;
/// Cells per side of each pane's grid; each cell is two triangles.
const CELLS: usize = 40;
/// Wall thickness: that of the lamp bulbs (58 um), at coordinates of the same size (~2).
const WALL: f64 = 5.8e-5;
const EMITTER_Z: f64 = -2.0;

/// The four interfaces of a double-walled pane: (z, the z of the normal pointing out of the
/// glass). Wall one spans [-1 - WALL, -1], wall two [-1.3 - WALL, -1.3]; between them, air.
const INTERFACES: [(f64, f64); 4] = [
    (-1.0, 1.0),
    (-1.0 - WALL, -1.0),
    (-1.3, 1.0),
    (-1.3 - WALL, -1.0),
];

/// Whether triangle `half` (0 below the cell's diagonal, 1 above) of cell `(i, j)` of
/// interface `k` is wound the other way, its normal pointing into the glass: about one face
/// in six, scattered.
fn flipped(k: usize, i: usize, j: usize, half: usize) -> bool {
    (7 * i + 13 * j + 5 * k + 3 * half).is_multiple_of(6)
}

/// The cell and half of the point `(x, y)` of a pane, `None` off the pane.
fn face_at(x: f64, y: f64) -> Option<(usize, usize, usize)> {
    let size = 2.0 * HALF / CELLS as f64;
    let (fx, fy) = ((x + HALF) / size, (y + HALF) / size);
    if !(0.0..CELLS as f64).contains(&fx) || !(0.0..CELLS as f64).contains(&fy) {
        return None;
    }
    let (i, j) = (fx.floor(), fy.floor());
    let half = usize::from(fy - j > fx - i);
    Some((i as usize, j as usize, half))
}

/// The panes as triangles (each face wound so its normal is the interface's outward normal,
/// or the opposite where [`flipped`]), a one-sided emitter of radiance 1 facing them at
/// z = -2, and a camera at the origin looking down -z. No sky: what leaves is lost.
fn pane_scene(accel: AccelKind) -> Scene {
    let mut geometry = Geometry::default();
    let mut materials = Vec::new();
    let size = 2.0 * HALF / CELLS as f64;
    for (k, &(z, normal_z)) in INTERFACES.iter().enumerate() {
        let base = geometry.positions.len() as u32;
        for j in 0..=CELLS {
            for i in 0..=CELLS {
                let (x, y) = (-HALF + i as f64 * size, -HALF + j as f64 * size);
                geometry.positions.push(DVec3::new(x, y, z).as_vec3());
            }
        }
        let at = |i: usize, j: usize| base + (j * (CELLS + 1) + i) as u32;
        for j in 0..CELLS {
            for i in 0..CELLS {
                // Counter-clockwise seen from +z: normal +z.
                let halves = [
                    [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                    [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
                ];
                for (half, [a, b, c]) in halves.into_iter().enumerate() {
                    let up = (normal_z > 0.0) != flipped(k, i, j, half);
                    geometry
                        .triangles
                        .push(if up { [a, b, c] } else { [a, c, b] });
                    materials.push(0);
                }
            }
        }
    }
    let base = geometry.positions.len() as u32;
    for (x, y) in [(-HALF, -HALF), (HALF, -HALF), (HALF, HALF), (-HALF, HALF)] {
        geometry
            .positions
            .push(DVec3::new(x, y, EMITTER_Z).as_vec3());
    }
    geometry.triangles.push([base, base + 1, base + 2]);
    geometry.triangles.push([base, base + 2, base + 3]);
    materials.extend([1, 1]);
    let parts = SceneParts {
        source: PathBuf::from("thin double-walled pane"),
        geometry,
        triangle_materials: materials,
        materials: vec![
            Material {
                name: "glass".into(),
                kind: MaterialKind::Glass { ior: IOR as f32 },
                emission: Rgb::BLACK,
                two_sided: false,
            },
            Material {
                name: "light".into(),
                kind: MaterialKind::Lambert { kd: Rgb::BLACK },
                emission: Rgb::WHITE,
                two_sided: false,
            },
        ],
        material_textures: vec![Default::default(); 2],
        cameras: vec![CameraDesc {
            name: "pane".into(),
            position: Vec3::ZERO,
            look_at: -Vec3::Z,
            up: Vec3::Y,
            fov_deg: 60.0,
            fov_axis: FovAxis::Vertical,
            mirrored: false,
        }],
        defaults: RenderDefaults {
            resolution: [32, 32],
            max_path_length: MAX_PATH_LENGTH,
            radius: None,
        },
        ..Default::default()
    };
    Scene::build(parts, accel).unwrap_or_else(|e| panic!("{e}"))
}

/// pbrt-v4's FrDielectric: unpolarised Fresnel reflectance at `cos_i` (negative from the
/// side the normal points away from) for `eta` = n on the far side of the normal / n on its
/// side.
fn fresnel(cos_i: f64, eta: f64) -> f64 {
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (parallel * parallel + perpendicular * perpendicular)
}

/// The exact expected radiance along a ray in the pane scene, by following both the
/// reflected and the refracted branch at every glass hit with their Fresnel weights (no
/// sampling), in f64 on the analytic planes: pbrt-v4's DielectricBxDF applied per hit
/// (entering iff `wo . n > 0`, relative index 1.5 or 1/1.5 accordingly, radiance scaled by
/// 1/etap^2 on refraction), path length counted as vmerge's `max_path_length` counts it.
/// With `flips` false every face is taken as wound outward (the check that the flipped faces
/// change the image). Returns the radiance and the expected number of total internal
/// reflections on the way.
fn expected_radiance(
    origin: DVec3,
    dir: DVec3,
    from: Option<usize>,
    length: u32,
    flips: bool,
) -> (f64, f64) {
    // The nearest plane ahead, skipping the one the ray starts on (no offsets needed).
    let mut nearest: Option<(f64, Option<usize>)> = None;
    let planes = INTERFACES
        .iter()
        .enumerate()
        .map(|(k, &(z, _))| (z, Some(k)))
        .chain([(EMITTER_Z, None)]);
    for (z, k) in planes {
        if k.is_some() && k == from || dir.z == 0.0 {
            continue;
        }
        let t = (z - origin.z) / dir.z;
        if t > 0.0 && nearest.is_none_or(|(best, _)| t < best) {
            nearest = Some((t, k));
        }
    }
    let Some((t, hit)) = nearest else {
        return (0.0, 0.0);
    };
    let p = origin + t * dir;
    let Some((i, j, half)) = face_at(p.x, p.y) else {
        return (0.0, 0.0);
    };
    let Some(k) = hit else {
        // The emitter: radiance 1 on its front (+z) side; black otherwise, and it ends the path.
        return (if dir.z < 0.0 { 1.0 } else { 0.0 }, 0.0);
    };
    if length >= MAX_PATH_LENGTH {
        return (0.0, 0.0);
    }
    let outward = INTERFACES[k].1;
    let n = DVec3::Z
        * if flips && flipped(k, i, j, half) {
            -outward
        } else {
            outward
        };
    let wo = -dir;
    let cos_o = wo.dot(n);
    let r = fresnel(cos_o, IOR);
    let reflected = dir - 2.0 * dir.dot(n) * n;
    let (value, tir) = expected_radiance(p, reflected, Some(k), length + 1, flips);
    if r == 1.0 {
        return (value, 1.0 + tir);
    }
    // pbrt-v4's Refract: flip to the side of wo, etap = n_t / n_i.
    let (cos_i, etap, n) = if cos_o > 0.0 {
        (cos_o, IOR, n)
    } else {
        (-cos_o, 1.0 / IOR, -n)
    };
    let sin2_t = (1.0 - cos_i * cos_i) / (etap * etap);
    let cos_t = (1.0 - sin2_t).sqrt();
    let refracted = -wo / etap + (cos_i / etap - cos_t) * n;
    let (through, through_tir) = expected_radiance(p, refracted, Some(k), length + 1, flips);
    (
        r * value + (1.0 - r) / (etap * etap) * through,
        r * tir + (1.0 - r) * through_tir,
    )
}

/// Each pixel's expected value under the box filter: the mean of [`expected_radiance`] over
/// `samples` uniform positions in the pixel, with the variance of that mean (nonzero only
/// where a face boundary crosses the pixel); and the mean number of total internal
/// reflections per camera ray.
fn expected_image(scene: &Scene, size: u32, samples: u32, flips: bool) -> (PixelStats, f64) {
    let camera = Camera::new(scene.camera(None).unwrap(), size, size);
    let k = samples as f64;
    let pixels: Vec<(f64, f64, f64)> = (0..size * size)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % size, i / size);
            let mut rng = Rng::from_seed(77, i as u64);
            let (values, tir): (Vec<f64>, Vec<f64>) = (0..samples)
                .map(|_| {
                    let [jx, jy] = rng.next_2d();
                    let ray = camera.generate_ray(x as f32 + jx, y as f32 + jy);
                    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
                    expected_radiance(o, d, None, 1, flips)
                })
                .unzip();
            let m = values.iter().sum::<f64>() / k;
            let var = values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (k - 1.0);
            (m, var / k, tir.iter().sum::<f64>() / k)
        })
        .collect();
    let stats = PixelStats {
        mean: pixels.iter().map(|p| p.0).collect(),
        var_of_mean: pixels.iter().map(|p| p.1).collect(),
        dropped: 0,
    };
    let tir = pixels.iter().map(|p| p.2).sum::<f64>() / pixels.len() as f64;
    (stats, tir)
}

/// A thin double-walled pane (two 58 um walls, every sixth face wound into the glass) in front
/// of an emitter: pt (on both ray-query backends), bpt, vcm and upg render what the exact
/// branch-by-branch expectation says. The flipped faces matter: taking every face as wound
/// outward moves the expectation by more than 20 standard errors of the render, and only the
/// flipped faces bring total internal reflection inside a wall (a face wound inward, entered
/// at more than 26 degrees, bends the ray past the critical angle of the wall's other face).
#[test]
fn thin_double_wall_with_flipped_faces_matches_the_exact_expectation() {
    let size = 32;
    let reference_scene = pane_scene(AccelKind::Bvh);
    let (expected, tir) = expected_image(&reference_scene, size, 1024, true);
    let (unflipped, unflipped_tir) = expected_image(&reference_scene, size, 16, false);
    assert!(tir > 0.01 && unflipped_tir == 0.0, "{tir}, {unflipped_tir}");
    let mut runs = vec![(Technique::Pt, AccelKind::Bvh)];
    if AccelKind::default_kind() != AccelKind::Bvh {
        runs.push((Technique::Pt, AccelKind::default_kind()));
    }
    for technique in [Technique::Bpt, Technique::Vcm, Technique::Upg] {
        runs.push((technique, AccelKind::default_kind()));
    }
    for (run, (technique, accel)) in runs.into_iter().enumerate() {
        let scene = pane_scene(accel);
        let stats = render_stats(&scene, &options(technique, size), 1024);
        assert_eq!(stats.dropped, 0);
        let label = format!("{technique:?} ({accel:?}) vs exact");
        eprintln!(
            "{label}: {} vs {}",
            stats.image_mean(),
            expected.image_mean()
        );
        assert_agree(&label, &stats, &expected);
        if run == 0 {
            let (m, u, se) = (
                expected.image_mean(),
                unflipped.image_mean(),
                stats.image_se(),
            );
            eprintln!("all faces wound outward: {u}; {tir} total internal reflections a ray");
            assert!((m - u).abs() > 20.0 * se, "{m} vs {u} (se {se})");
        }
    }
}

/// The lamp-bulb case: five bulbs of a real mesh (../shared/cases/glass-bulbs, not part of the
/// project), or `None` with a message when it is absent.
fn bulbs_case() -> Option<Scene> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/cases/glass-bulbs/scene.toml");
    if !path.exists() {
        eprintln!("skipping: {} is absent", path.display());
        return None;
    }
    Some(load_file(&path))
}

/// Mean and standard error of the pixels in rows `rows` of a `width`-wide image.
fn region(stats: &PixelStats, width: usize, rows: std::ops::Range<usize>) -> (f64, f64) {
    let pixels = rows.start * width..rows.end * width;
    let n = pixels.len() as f64;
    let mean = stats.mean[pixels.clone()].iter().sum::<f64>() / n;
    let se = stats.var_of_mean[pixels].iter().sum::<f64>().sqrt() / n;
    (mean, se)
}

/// The image mean and the means of the bulbs' rows (90..170) and of the floor's (180..256) of
/// the 256x256 bulbs case with the walls resolved, from Mitsuba 3.9.1 (scalar_rgb, path
/// tracer, max_depth 10, 8 seeds x 256 spp), with their standard errors across seeds. Mitsuba
/// offsets a ray's origin by (1 + max |p_i|) 1500 2^-24 along the normal: 2.9e-4 at the
/// case's coordinates, five times the bulbs' 58 um walls, so every ray leaving one face of a
/// wall starts beyond the other and the wall's second face is never seen (which is what its
/// own reference image, mitsuba-reference.exr, shows). Rendered with the scene translated by
/// (1.356, -1.895, 2.2) and scaled by 100 instead (an image-preserving change), its offset is
/// 0.68 of a wall and both faces are seen.
const RESOLVED_WALLS: [(&str, std::ops::Range<usize>, f64, f64); 3] = [
    ("whole image", 0..256, 2.20958, 0.00015),
    ("bulbs' rows", 90..170, 0.98056, 0.00022),
    ("floor's rows", 180..256, 1.24767, 0.00025),
];

/// mitsuba-reference.exr's means over the same rows: what one renders when each wall's second
/// face goes unseen.
const SECOND_FACE_UNSEEN: [f64; 3] = [2.12026, 0.81436, 1.14443];

/// pt on the bulbs case agrees with Mitsuba's image of it with the walls resolved, over the
/// whole image and over the bulbs' and the floor's rows: within 0.5%, with 4 combined standard
/// errors under 0.25% so noise cannot hide a 1% bias. The 0.5% is not noise: even scaled up,
/// Mitsuba's offset (3.9e-5 in the case's units) skips a few close faces that vmerge's
/// (5e-6) resolves; giving vmerge that offset moves its means by -0.04% (whole), -0.19%
/// (bulbs' rows) and -0.05% (floor), onto Mitsuba's within noise. It stays far from
/// mitsuba-reference.exr (4%, 20% and 9% away), where the walls' second faces are unseen.
#[test]
fn bulbs_case_agrees_with_mitsuba_with_the_walls_resolved() {
    let Some(scene) = bulbs_case() else {
        return;
    };
    let options = RenderOptions {
        technique: Technique::Pt,
        resolution: Some([256, 256]),
        seed: 21,
        sampler: SamplerKind::Independent,
        ..Default::default()
    };
    let stats = render_stats(&scene, &options, 256);
    for ((label, rows, reference, reference_se), unseen) in
        RESOLVED_WALLS.into_iter().zip(SECOND_FACE_UNSEEN)
    {
        let (mean, se) = region(&stats, 256, rows);
        let se = (se * se + reference_se * reference_se).sqrt();
        eprintln!("{label}: vmerge {mean} (se {se}), Mitsuba {reference}, unseen {unseen}");
        assert!(
            4.0 * se <= 0.0025 * reference,
            "{label}: too noisy (se {se})"
        );
        assert!(
            (mean - reference).abs() <= 0.005 * reference,
            "{label}: vmerge {mean}, Mitsuba with the walls resolved {reference} (se {se})"
        );
        assert!((mean - unseen).abs() > 0.03 * unseen);
    }
}

/// bpt, vcm and upg render the bulbs case as pt does, at 64x64: per pixel for the unbiased bpt
/// and upg, in the image mean for vcm (its merging is biased at a finite radius), and for all
/// three in the mean of the bulbs' rows.
#[test]
fn bulbs_case_is_the_same_for_every_technique() {
    let Some(scene) = bulbs_case() else {
        return;
    };
    let size = 64;
    let pt = render_stats(&scene, &options(Technique::Pt, size), 1024);
    for technique in [Technique::Bpt, Technique::Vcm, Technique::Upg] {
        let stats = render_stats(&scene, &options(technique, size), 256);
        let label = format!("{technique:?} vs pt");
        eprintln!("{label}: {} vs {}", stats.image_mean(), pt.image_mean());
        if technique == Technique::Vcm {
            assert_means_agree(&label, &stats, &pt);
        } else {
            assert_agree(&label, &stats, &pt);
        }
        // The bulbs' rows alone, by assert_means_agree's rule: within 1% or 4 standard errors.
        let bulbs = 22..43;
        let ((m, se), (m_pt, se_pt)) = (region(&stats, 64, bulbs.clone()), region(&pt, 64, bulbs));
        let se = (se * se + se_pt * se_pt).sqrt();
        eprintln!("{label}, bulbs' rows: {m} vs {m_pt} (se {se})");
        assert!(4.0 * se <= 0.02 * m_pt, "{label}: too noisy (se {se})");
        assert!(
            (m - m_pt).abs() <= (0.01 * m_pt).max(4.0 * se),
            "{label}, bulbs' rows: {m} vs {m_pt} (se {se})"
        );
    }
}
