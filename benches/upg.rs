//! UPG's tentative-ray stage (000 sec. 2.4.3): estimates of 1/p_acc per second with tentative
//! rays traced 8 at a time against one at a time, on the glossy Cornell box and on a large real
//! mesh (the 331k-triangle conference room from ../shared/scenes, skipped when absent).
//! Run: `cargo bench --bench upg`.
//!
//! The merges are realistic ones: the origin is a vertex of a random walk from the camera and
//! the target lies within the merge radius of where a BSDF-sampled ray from it lands, as when a
//! light sub-path ends near an eye vertex. After criterion's figures a table compares both
//! widths measured alternately in one run.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};
use vmerge::accel::{AccelKind, Ray};
use vmerge::bsdf::{Bsdf, TransportMode};
use vmerge::frame::Frame;
use vmerge::integrator::upg::acceptance::{AngularBound, Estimator, PacketWidth};
use vmerge::sampling::{concentric_disk, Rng, Stream};
use vmerge::scene::{self, Camera, LoadOptions, Scene};

const MERGES: usize = 4096;
const WALK_LENGTH: usize = 4;

/// One merge: the origin vertex (position, normal, material, `wo`) and the target point.
struct Merge {
    position: Vec3,
    ng: Vec3,
    material: u32,
    wo: Vec3,
    target: Vec3,
}

/// Merges along random walks from the camera: each non-delta vertex with a BSDF-sampled
/// continuation that hits something gives one, its target a uniform point of the disc of the
/// merge radius in the tangent plane of that hit.
fn merges(scene: &Scene, radius: f32) -> Vec<Merge> {
    let camera = Camera::new(scene.camera(None).expect("camera"), 256, 256);
    let mut rng = Rng::for_sample(1, 0, 0, Stream::Eye);
    let mut merges = Vec::with_capacity(MERGES);
    while merges.len() < MERGES {
        let (x, y) = (rng.next_f32() * 256.0, rng.next_f32() * 256.0);
        let mut ray = camera.generate_ray(x, y);
        let Some(mut hit) = scene.intersect(&ray) else {
            continue;
        };
        for _ in 0..WALK_LENGTH {
            let wo = -ray.dir.normalize();
            let kind = &scene.material(hit.material).kind;
            let Some(bsdf) = Bsdf::new(kind, hit.ng, wo, TransportMode::Importance) else {
                break;
            };
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let Some(sample) = bsdf.sample(u) else {
                break;
            };
            ray = Ray::spawn(hit.position, hit.ng, sample.wi);
            let Some(next) = scene.intersect(&ray) else {
                break;
            };
            if !bsdf.is_delta() && merges.len() < MERGES {
                let frame = Frame::from_z(next.ng);
                let d = concentric_disk(rng.next_2d()) * radius;
                merges.push(Merge {
                    position: hit.position,
                    ng: hit.ng,
                    material: hit.material,
                    wo,
                    target: next.position + frame.x * d.x + frame.y * d.y,
                });
            }
            hit = next;
        }
    }
    merges
}

#[derive(Default)]
struct Totals {
    trials: u64,
    rays: u64,
    capped: u64,
}

/// Estimates 1/p_acc for every merge once. Each merge has its own random stream, as a pixel has
/// in rendering: packets draw numbers past the first success, which must not shift the next
/// merge's trials.
fn run(scene: &Scene, merges: &[Merge], radius: f32, estimator: &Estimator, pass: u64) -> Totals {
    let mut totals = Totals::default();
    for (index, m) in merges.iter().enumerate() {
        let mut rng = Rng::for_sample(3, pass, index as u64, Stream::Tentative);
        let kind = &scene.material(m.material).kind;
        let Some(bsdf) = Bsdf::new(kind, m.ng, m.wo, TransportMode::Importance) else {
            continue;
        };
        let Ok(bound) = AngularBound::new(m.position, m.ng, &bsdf, m.target, radius) else {
            continue;
        };
        let e = estimator.estimate(scene, &bound, &mut rng);
        black_box(e.inv_p_acc());
        totals.trials += e.trials as u64;
        totals.rays += e.rays as u64;
        totals.capped += e.capped() as u64;
    }
    totals
}

fn estimator(packet: PacketWidth) -> Estimator {
    Estimator {
        packet,
        ..Estimator::default()
    }
}

fn width_name(packet: PacketWidth) -> &'static str {
    match packet {
        PacketWidth::One => "packet 1",
        PacketWidth::Eight => "packet 8",
    }
}

/// One row of the final table: a width measured on a scene.
struct Row {
    scene: &'static str,
    packet: PacketWidth,
    merges_per_s: f64,
    rays_per_s: f64,
    trials_per_merge: f64,
    rays_per_merge: f64,
    capped: u64,
}

/// Several passes per width, alternating; pass `p` draws the same random numbers at both
/// widths, so both count the same trials and only the tracing differs.
fn table_rows(name: &'static str, scene: &Scene, merges: &[Merge], radius: f32) -> Vec<Row> {
    const PASSES: u64 = 8;
    let widths = [PacketWidth::One, PacketWidth::Eight];
    let mut time = [Duration::ZERO; 2];
    let mut totals = [Totals::default(), Totals::default()];
    for pass in 0..PASSES {
        for k in 0..widths.len() {
            // Alternate which width goes first, so load from other processes weighs on both.
            let i = (k + pass as usize) % widths.len();
            let start = Instant::now();
            let t = run(scene, merges, radius, &estimator(widths[i]), pass);
            time[i] += start.elapsed();
            totals[i].trials += t.trials;
            totals[i].rays += t.rays;
            totals[i].capped += t.capped;
        }
    }
    assert_eq!(
        totals[0].trials, totals[1].trials,
        "same trials at both widths"
    );
    let n = merges.len() as f64 * PASSES as f64;
    widths
        .iter()
        .zip(time.iter().zip(&totals))
        .map(|(&packet, (time, t))| {
            let seconds = time.as_secs_f64();
            Row {
                scene: name,
                packet,
                merges_per_s: n / seconds,
                rays_per_s: t.rays as f64 / seconds,
                trials_per_merge: t.trials as f64 / n,
                rays_per_merge: t.rays as f64 / n,
                capped: t.capped,
            }
        })
        .collect()
}

fn bench_scene(c: &mut Criterion, name: &'static str, path: &Path, rows: &mut Vec<Row>) {
    if !path.exists() {
        eprintln!("skipping {name}: {} is absent", path.display());
        return;
    }
    let options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: true,
    };
    // The conference room's mesh lives outside the project and may be absent too.
    let scene = match scene::load(path, &options) {
        Ok(scene) => scene,
        Err(e) => {
            eprintln!("skipping {name}: {e}");
            return;
        }
    };
    let radius = scene.default_radius();
    let merges = merges(&scene, radius);
    let mut group = c.benchmark_group(format!("upg-acceptance/{name}"));
    group.throughput(Throughput::Elements(merges.len() as u64));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(5));
    for packet in [PacketWidth::One, PacketWidth::Eight] {
        let estimator = estimator(packet);
        let mut pass = 1000;
        group.bench_function(width_name(packet), |b| {
            b.iter(|| {
                pass += 1;
                run(&scene, &merges, radius, &estimator, pass)
            })
        });
    }
    group.finish();
    rows.extend(table_rows(name, &scene, &merges, radius));
}

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut rows = Vec::new();
    bench_scene(
        c,
        "cornell-glossy",
        &root.join("scenes/cornell-glossy/scene.toml"),
        &mut rows,
    );
    bench_scene(
        c,
        "conference",
        &root.join("benches/scenes/conference.toml"),
        &mut rows,
    );
    println!(
        "\nUPG tentative rays ({} backend, {MERGES} merges per pass, alternating passes)",
        AccelKind::default_kind().name()
    );
    println!(
        "{:16} {:9} {:>12} {:>12} {:>8} {:>8} {:>7} {:>9}",
        "scene", "width", "merges/s", "rays/s", "trials", "rays", "capped", "speed-up"
    );
    for pair in rows.chunks(2) {
        let single = pair[0].merges_per_s;
        for row in pair {
            println!(
                "{:16} {:9} {:>12.0} {:>12.0} {:>8.2} {:>8.2} {:>7} {:>9.2}",
                row.scene,
                width_name(row.packet),
                row.merges_per_s,
                row.rays_per_s,
                row.trials_per_merge,
                row.rays_per_merge,
                row.capped,
                row.merges_per_s / single
            );
        }
    }
}

criterion_group! {
    name = upg;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(upg);
