//! How the order of a path tracer's rays moves Embree's closest-hit rate on real scenes: the
//! rays after the camera ray of material-free paths (each bounce cosine-distributed about the
//! side of the surface the path arrived from), traced as the pixels make them, sorted by the
//! Morton code of their origins (what a wavefront that sorts its paths would hand the backend),
//! and shuffled. Scenes: the conference room and every scene file given as an argument.
//! Run: `cargo bench --bench ray_order [-- SCENE.toml...]`.

use cpu_time::ThreadTime;
use glam::Vec3;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use vmerge::accel::{AccelKind, Ray};
use vmerge::frame::Frame;
use vmerge::sampling::{cosine_hemisphere, Rng, Stream};
use vmerge::scene::{Camera, Scene};

mod common;
use common::{best_mrays, load_scene, paired_ratio};

/// Paths through a scene's first camera at this resolution, this many a pixel.
const RESOLUTION: u32 = 256;
const SAMPLES: u32 = 4;
/// Bounces a path takes at most.
const BOUNCES: usize = 5;
/// Timed rounds, each tracing the three orders in turn.
const ROUNDS: usize = 7;

/// The rays after the camera ray of the paths, in the order the pixels make them.
fn path_rays(scene: &Scene) -> Vec<Ray> {
    let camera = Camera::new(&scene.cameras[0], RESOLUTION, RESOLUTION);
    let mut rng = Rng::for_sample(11, 0, 0, Stream::Eye);
    let mut rays = Vec::new();
    for y in 0..RESOLUTION {
        for x in 0..RESOLUTION {
            for _ in 0..SAMPLES {
                let [dx, dy] = rng.next_2d();
                let mut ray = camera.generate_ray(x as f32 + dx, y as f32 + dy);
                for bounce in 0..=BOUNCES {
                    if bounce > 0 {
                        rays.push(ray);
                    }
                    let Some(hit) = scene.intersect(&ray) else {
                        break;
                    };
                    let n = if hit.ng.dot(ray.dir) < 0.0 {
                        hit.ng
                    } else {
                        -hit.ng
                    };
                    let dir = Frame::from_z(n).to_world(cosine_hemisphere(rng.next_2d()));
                    ray = Ray::spawn(hit.position, hit.ng, dir);
                }
            }
        }
    }
    rays
}

/// 30-bit Morton code of `p` in the cube around the sphere `(centre, radius)`.
fn morton(p: Vec3, (centre, radius): (Vec3, f32)) -> u32 {
    let spread = |x: f32| {
        let mut v = (x.clamp(0.0, 1.0) * 1023.0) as u32;
        v = (v | (v << 16)) & 0x0300_00ff;
        v = (v | (v << 8)) & 0x0300_f00f;
        v = (v | (v << 4)) & 0x030c_30c3;
        (v | (v << 2)) & 0x0924_9249
    };
    let q = (p - centre) / (2.0 * radius) + 0.5;
    spread(q.x) | (spread(q.y) << 1) | (spread(q.z) << 2)
}

/// One scene's row: the three orders timed round by round, each round starting with another.
fn measure(name: &str, scene: &Scene) {
    let pixel = path_rays(scene);
    let mut sorted = pixel.clone();
    sorted.sort_by_key(|r| morton(r.origin, scene.bounding_sphere));
    let mut shuffled = pixel.clone();
    let mut rng = Rng::for_sample(13, 0, 0, Stream::Eye);
    for i in (1..shuffled.len()).rev() {
        shuffled.swap(i, rng.next_u32() as usize % (i + 1));
    }
    let orders = [&pixel, &sorted, &shuffled];
    let mut times: [Vec<f64>; 3] = Default::default();
    for round in 0..ROUNDS {
        for k in 0..3 {
            let i = (round + k) % 3;
            let start = ThreadTime::now();
            let hits = orders[i]
                .iter()
                .filter(|r| scene.accel.intersect(black_box(r)).is_some())
                .count();
            black_box(hits);
            times[i].push(start.elapsed().as_secs_f64());
        }
    }
    let rate = |t: &[f64]| best_mrays(t, pixel.len()).map_or("-".into(), |v| format!("{v:.2}"));
    let ratio = |t: &[f64]| paired_ratio(&times[0], t).map_or("-".into(), |r| format!("{r:.2}x"));
    println!(
        "{name:<24} {:>9} {:>8} {:>8} {:>9} {:>9} {:>10}",
        pixel.len(),
        rate(&times[0]),
        rate(&times[1]),
        rate(&times[2]),
        ratio(&times[1]),
        ratio(&times[2])
    );
}

/// A scene's short name: for a `scene.toml`, its two innermost folders (a converted scene's
/// name and variant); else its file stem.
fn short_name(path: &Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
    if stem.as_deref() != Some("scene") {
        return stem.unwrap_or_else(|| path.display().to_string());
    }
    let folders: Vec<_> = path
        .parent()
        .into_iter()
        .flat_map(|d| d.iter().rev().take(2))
        .map(|c| c.to_string_lossy())
        .collect();
    if folders.is_empty() {
        return path.display().to_string();
    }
    folders.into_iter().rev().collect::<Vec<_>>().join("/")
}

fn main() {
    let kind = if cfg!(feature = "embree") {
        AccelKind::Embree
    } else {
        AccelKind::Bvh
    };
    let mut paths =
        vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/scenes/conference.toml")];
    // Cargo passes `--bench` to a bench without a harness; every other argument is a scene.
    paths.extend(
        std::env::args()
            .skip(1)
            .filter(|a| !a.starts_with("--"))
            .map(PathBuf::from),
    );
    println!(
        "closest hits of path rays after the camera ray ({RESOLUTION}x{RESOLUTION}, {SAMPLES} paths \
         a pixel, up to {BOUNCES} bounces), {} backend, Mrays/s on 1 thread, best of {ROUNDS} \
         rounds in thread CPU time; ratios: median over rounds of the pixel order's time over the \
         other's",
        kind.name()
    );
    println!(
        "{:<24} {:>9} {:>8} {:>8} {:>9} {:>9} {:>10}",
        "scene", "rays", "pixel", "morton", "shuffled", "morton x", "shuffled x"
    );
    for path in paths {
        let name = short_name(&path);
        let Some(scene) = load_scene(&name, &path, kind) else {
            continue;
        };
        if scene.cameras.is_empty() {
            eprintln!("skipping {name}: it has no camera");
            continue;
        }
        measure(&name, &scene);
    }
}
