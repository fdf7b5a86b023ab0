//! Ray-query throughput (million rays per second, one thread) of both backends on incoherent,
//! path-tracing-like rays: closest hit and any hit, single rays and packets of 8, on a
//! generated 1M-triangle mesh and on the Cornell box. Embree is also called through raw
//! `embree-sys` on the same rays to measure what the safe wrapper costs.
//! Run: `cargo bench --bench accel`.

use cpu_time::ThreadTime;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};
use vmerge::accel::{self, Accel, AccelKind, Geometry, Ray, PACKET};
use vmerge::frame::Frame;
use vmerge::sampling::{cosine_hemisphere, uniform_sphere, Rng, Stream};
use vmerge::scene::{self, LoadOptions};

mod common;
use common::{best_mrays, paired_ratio};

/// Rays per workload: a multiple of the packet width.
const RAYS: usize = 100_000;
/// Timed rounds of the summary table.
const ROUNDS: usize = 25;

/// A bumpy heightfield of about 1M triangles (sums of sines, so it needs no files and no noise
/// library) closed by a box of 12 large triangles, so that almost every ray hits something.
fn bumpy_terrain() -> Geometry {
    const N: u32 = 708; // 2 * 707^2 = 999,698 triangles
    let mut g = Geometry::default();
    for j in 0..N {
        for i in 0..N {
            let (x, z) = (
                i as f32 / (N - 1) as f32 * 2.0 - 1.0,
                j as f32 / (N - 1) as f32 * 2.0 - 1.0,
            );
            let y = 0.12 * (3.1 * x).sin() * (2.7 * z).cos()
                + 0.04 * (11.3 * x + 2.0 * z).sin() * (9.7 * z - 1.3 * x).cos()
                + 0.01 * (47.0 * x).sin() * (53.0 * z).sin();
            g.positions.push(Vec3::new(x, y, z));
        }
    }
    for j in 0..N - 1 {
        for i in 0..N - 1 {
            let a = j * N + i;
            g.triangles.push([a, a + N, a + 1]);
            g.triangles.push([a + 1, a + N, a + N + 1]);
        }
    }
    let base = g.positions.len() as u32;
    for k in 0..8 {
        g.positions.push(Vec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -0.5 } else { 1.5 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        ));
    }
    for [a, b, c, d] in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        g.triangles.push([base + a, base + b, base + c]);
        g.triangles.push([base + a, base + c, base + d]);
    }
    g
}

/// The workloads of one scene, generated once: `bounce` rays leave surface points in
/// cosine-distributed directions (closest hit); `shadow` segments join two surface points
/// (any hit), like next-event estimation or bidirectional connections. Surface points are
/// found by tracing random rays from random points of `region`, so they cover what is visible
/// from inside the scene.
struct Workload {
    bounce: Vec<Ray>,
    shadow: Vec<Ray>,
}

fn workload(accel: &dyn Accel, region: (Vec3, Vec3), seed: u64) -> Workload {
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let mut points = Vec::with_capacity(2 * RAYS);
    while points.len() < 2 * RAYS {
        let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let origin = region.0 + u * (region.1 - region.0);
        let ray = Ray::new(origin, uniform_sphere(rng.next_2d()));
        if let Some(hit) = accel.intersect(&ray) {
            // The side the ray arrived from, where a path would continue.
            let ng = hit.ng.normalize();
            let n = if ng.dot(ray.dir) < 0.0 { ng } else { -ng };
            points.push((ray.at(hit.t), n));
        }
    }
    let bounce = points[..RAYS]
        .iter()
        .map(|&(p, n)| {
            let dir = Frame::from_z(n).to_world(cosine_hemisphere(rng.next_2d()));
            Ray::spawn(p, n, dir)
        })
        .collect();
    let shadow = points[..RAYS]
        .iter()
        .zip(&points[RAYS..])
        .map(|(&(p, n), &(q, m))| Ray::spawn_between(p, n, q, m))
        .collect();
    Workload { bounce, shadow }
}

/// A scene under test: both backends (Embree when built), raw Embree, its rays.
struct Subject {
    name: &'static str,
    backends: Vec<(AccelKind, Box<dyn Accel>)>,
    raw: Option<Raw>,
    work: Workload,
}

fn subject(name: &'static str, geometry: Geometry, region: (Vec3, Vec3)) -> Subject {
    let mut kinds = vec![AccelKind::Bvh];
    if cfg!(feature = "embree") {
        kinds.insert(0, AccelKind::Embree);
    }
    let backends: Vec<_> = kinds
        .into_iter()
        .map(|kind| {
            let start = Instant::now();
            let accel = accel::build(kind, &geometry).expect("bench geometry builds");
            eprintln!(
                "{name}: {} triangles, {} build {:.2} s",
                geometry.triangles.len(),
                kind.name(),
                start.elapsed().as_secs_f64()
            );
            (kind, accel)
        })
        .collect();
    let work = workload(backends[0].1.as_ref(), region, 7);
    let raw = build_raw(&geometry);
    Subject {
        name,
        backends,
        raw,
        work,
    }
}

fn subjects() -> Vec<Subject> {
    let mut out = vec![subject(
        "terrain-1M",
        bumpy_terrain(),
        (Vec3::new(-0.95, 0.2, -0.95), Vec3::new(0.95, 1.45, 0.95)),
    )];
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    let options = LoadOptions {
        accel: AccelKind::Bvh,
        lenient: true,
        shading_normals: true,
    };
    match scene::load(&path, &options) {
        Ok(scene) => match scene.geometry.bounds() {
            Some((min, max)) => {
                // Origins inside the room, clear of its walls.
                let margin = 0.02 * (max - min);
                out.push(subject(
                    "cornell-box",
                    scene.geometry,
                    (min + margin, max - margin),
                ))
            }
            None => eprintln!("skipping cornell-box: it has no geometry"),
        },
        Err(e) => eprintln!("skipping cornell-box: {e}"),
    }
    out
}

/// What is asked of each ray, one at a time or 8 at a time.
#[derive(Clone, Copy, PartialEq)]
enum Query {
    Closest,
    Any,
    Closest8,
    Any8,
}

impl Query {
    const ALL: [Query; 4] = [Query::Closest, Query::Any, Query::Closest8, Query::Any8];

    fn name(self) -> &'static str {
        match self {
            Query::Closest => "closest/1",
            Query::Any => "any/1",
            Query::Closest8 => "closest/8",
            Query::Any8 => "any/8",
        }
    }

    fn rays(self, work: &Workload) -> &[Ray] {
        match self {
            Query::Closest | Query::Closest8 => &work.bounce,
            Query::Any | Query::Any8 => &work.shadow,
        }
    }
}

/// One measured loop over a workload; returns a checksum so nothing is optimised away.
fn run(accel: &dyn Accel, query: Query, rays: &[Ray]) -> u64 {
    let mut sum = 0u64;
    match query {
        Query::Closest => {
            for ray in rays {
                sum += accel.intersect(ray).is_some() as u64;
            }
        }
        Query::Any => {
            for ray in rays {
                sum += accel.occluded(ray) as u64;
            }
        }
        Query::Closest8 => {
            let mut hits = [None; PACKET];
            for chunk in rays.chunks_exact(PACKET) {
                let packet: &[Ray; PACKET] = chunk.try_into().expect("chunks of 8");
                accel.intersect8(packet, 0xff, &mut hits);
                sum += hits.iter().filter(|h| h.is_some()).count() as u64;
            }
        }
        Query::Any8 => {
            for chunk in rays.chunks_exact(PACKET) {
                let packet: &[Ray; PACKET] = chunk.try_into().expect("chunks of 8");
                sum += accel.occluded8(packet, 0xff).count_ones() as u64;
            }
        }
    }
    sum
}

/// Embree called through raw `embree-sys`; a type without values when Embree is not built.
#[cfg(feature = "embree")]
type Raw = vmerge::accel::embree::RawScene;
#[cfg(not(feature = "embree"))]
enum Raw {}

#[cfg(feature = "embree")]
fn build_raw(geometry: &Geometry) -> Option<Raw> {
    Some(Raw::build(geometry).expect("raw Embree scene builds"))
}

#[cfg(not(feature = "embree"))]
fn build_raw(_: &Geometry) -> Option<Raw> {
    None
}

#[cfg(feature = "embree")]
fn run_raw(raw: &Raw, query: Query, rays: &[Ray]) -> u64 {
    match query {
        Query::Closest => raw.intersect1(rays),
        Query::Any => raw.occluded1(rays),
        Query::Closest8 => raw.intersect8(rays),
        Query::Any8 => raw.occluded8(rays),
    }
}

#[cfg(not(feature = "embree"))]
fn run_raw(raw: &Raw, _: Query, _: &[Ray]) -> u64 {
    match *raw {}
}

/// What a measured configuration runs.
enum Target<'a> {
    Accel(&'a dyn Accel),
    Raw(&'a Raw),
}

impl Target<'_> {
    fn run(&self, query: Query, rays: &[Ray]) -> u64 {
        match self {
            Target::Accel(a) => run(*a, query, rays),
            Target::Raw(r) => run_raw(r, query, rays),
        }
    }
}

/// Seconds each target takes for `rays`, round by round: each round runs every target once,
/// starting with another one each time, so a load spike on the machine weighs on all of them.
/// Timed in thread CPU time, so time spent descheduled on a shared machine does not count.
fn round_times<const N: usize>(
    targets: &[Option<Target>; N],
    query: Query,
    rays: &[Ray],
) -> [Vec<f64>; N] {
    let mut times: [Vec<f64>; N] = std::array::from_fn(|_| Vec::with_capacity(ROUNDS));
    for round in 0..ROUNDS {
        for k in 0..N {
            let i = (round + k) % N;
            if let Some(target) = &targets[i] {
                let start = ThreadTime::now();
                black_box(target.run(query, black_box(rays)));
                times[i].push(start.elapsed().as_secs_f64());
            }
        }
    }
    times
}

fn benches(c: &mut Criterion) {
    let subjects = subjects();
    for s in &subjects {
        let mut group = c.benchmark_group(format!("rays/{}", s.name));
        group
            .throughput(Throughput::Elements(RAYS as u64))
            .sample_size(10)
            .warm_up_time(Duration::from_millis(500))
            .measurement_time(Duration::from_secs(2));
        let mut targets: Vec<(&str, Target)> = s
            .backends
            .iter()
            .map(|(kind, a)| (kind.name(), Target::Accel(a.as_ref())))
            .collect();
        if let Some(raw) = &s.raw {
            targets.push(("embree-sys", Target::Raw(raw)));
        }
        for query in Query::ALL {
            for (name, target) in &targets {
                let rays = query.rays(&s.work);
                group.bench_function(format!("{}/{name}", query.name()), |b| {
                    b.iter(|| target.run(query, black_box(rays)))
                });
            }
        }
        group.finish();
    }

    // The summary table, measured in one run so its ratios compare like with like.
    println!();
    println!(
        "Mrays/s, 1 thread, {RAYS} incoherent rays per workload (best of {ROUNDS} rounds, thread CPU \
         time; ratios: median over rounds of the ratio within a round)"
    );
    println!(
        "{:<12} {:<10} {:>8} {:>8} {:>11} {:>10} {:>9}",
        "scene", "query", "embree", "bvh", "embree/bvh", "embree-sys", "wrapper"
    );
    for s in &subjects {
        for query in Query::ALL {
            let rays = query.rays(&s.work);
            let backend = |kind: AccelKind| {
                s.backends
                    .iter()
                    .find(|(k, _)| *k == kind)
                    .map(|(_, a)| Target::Accel(a.as_ref()))
            };
            let targets = [
                backend(AccelKind::Embree),
                backend(AccelKind::Bvh),
                s.raw.as_ref().map(Target::Raw),
            ];
            let [embree, bvh, raw] = round_times(&targets, query, rays);
            let cell = |t: &[f64]| {
                best_mrays(t, rays.len()).map_or("-".to_string(), |v| format!("{v:.2}"))
            };
            let ratio = paired_ratio(&bvh, &embree).map_or("-".into(), |r| format!("{r:.2}x"));
            // The wrapper's cost: how much longer a ray takes through `Accel` than raw.
            let wrapper = paired_ratio(&embree, &raw)
                .map_or("-".into(), |r| format!("{:+.1}%", (r - 1.0) * 100.0));
            println!(
                "{:<12} {:<10} {:>8} {:>8} {:>11} {:>10} {:>9}",
                s.name,
                query.name(),
                cell(&embree),
                cell(&bvh),
                ratio,
                cell(&raw),
                wrapper
            );
        }
    }
}

criterion_group! {
    name = accel_benches;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(accel_benches);
