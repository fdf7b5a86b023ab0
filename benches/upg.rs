//! UPG's tentative-ray stage (000 sec. 2.4.3): estimates of 1/p_acc per second with tentative
//! rays traced 8 at a time against one at a time, on the glossy Cornell box and on a large real
//! mesh (the 331k-triangle conference room from ../shared/scenes, skipped when absent).
//! Run: `cargo bench --bench upg`.
//!
//! Merges come in gathers, as in rendering: all the merges found around one eye vertex are
//! estimated together, so packets can fill their lanes from all of them. A gather's geometry is
//! real: a vertex of a random walk from the camera and the point x where a BSDF-sampled ray
//! from it lands. `upg-camera` gathers have one origin (that vertex) and K targets within the
//! merge radius of x (the light vertices found there); `upg` gathers have one target (x) and K
//! origins (the walk vertex, and surface points seen from x: the light vertices'
//! predecessors). The number K of merges per gather grows with the light paths per iteration
//! (the pixel count) times pi r^2: about 1.5 at 256x256 and 15 at 768x768 on `cornell-glossy`
//! at its default radius. After criterion's figures a table compares both widths measured
//! alternately in one run (thread CPU time: the machine is shared), for K = 1, 4, 8 and 16, and
//! the tracing alone.

use cpu_time::ThreadTime;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use std::cell::RefCell;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;
use vmerge::accel::{AccelKind, Ray, PACKET};
use vmerge::bsdf::{Bsdf, TransportMode};
use vmerge::frame::Frame;
use vmerge::integrator::upg::acceptance::{AngularBound, Estimator, PacketWidth, TentativeTracer};
use vmerge::sampling::{concentric_disk, cosine_hemisphere, Rng, Stream};
use vmerge::scene::{Camera, Scene};

mod common;
use common::load_scene;

/// Merges per pass, whatever the gather size.
const MERGES: usize = 4096;
const GATHER_SIZES: [usize; 4] = [1, 4, 8, 16];
const WALK_LENGTH: usize = 4;
const PASSES: u64 = 8;

/// A non-delta surface vertex tentative rays can leave from.
#[derive(Clone, Copy)]
struct Vertex {
    position: Vec3,
    ng: Vec3,
    material: u32,
    wo: Vec3,
}

impl Vertex {
    fn bsdf<'s>(&self, scene: &'s Scene) -> Option<Bsdf<'s>> {
        let kind = &scene.material(self.material).kind;
        Bsdf::new(kind, self.ng, self.wo, TransportMode::Importance)
    }
}

/// Which side gathers: one origin and many targets, or one target and many origins.
#[derive(Clone, Copy, PartialEq)]
enum Side {
    Camera,
    Light,
}

impl Side {
    fn name(self) -> &'static str {
        match self {
            Side::Camera => "upg-camera",
            Side::Light => "upg",
        }
    }
}

/// The merges around one eye vertex.
enum Gather {
    /// `upg-camera`: from the previous eye vertex towards each light vertex found.
    OneOrigin { origin: Vertex, targets: Vec<Vec3> },
    /// `upg`: from each light vertex's predecessor towards the eye vertex.
    OneTarget { origins: Vec<Vertex>, target: Vec3 },
}

/// A point where a walk vertex's BSDF-sampled ray lands, with its geometric normal.
struct Landing {
    from: Vertex,
    position: Vec3,
    ng: Vec3,
}

/// Pairs (walk vertex, landing point) along random walks from the camera.
fn landings(scene: &Scene, count: usize, rng: &mut Rng) -> Vec<Landing> {
    let camera = Camera::new(scene.camera(None).expect("camera"), 256, 256);
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let (x, y) = (rng.next_f32() * 256.0, rng.next_f32() * 256.0);
        let mut ray = camera.generate_ray(x, y);
        let Some(mut hit) = scene.intersect(&ray) else {
            continue;
        };
        for _ in 0..WALK_LENGTH {
            let from = Vertex {
                position: hit.position,
                ng: hit.ng,
                material: hit.material,
                wo: -ray.dir.normalize(),
            };
            let Some(bsdf) = from.bsdf(scene) else {
                break;
            };
            let Some(sample) = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()]) else {
                break;
            };
            ray = Ray::spawn(hit.position, hit.ng, sample.wi);
            let Some(next) = scene.intersect(&ray) else {
                break;
            };
            if !bsdf.is_delta() && out.len() < count {
                out.push(Landing {
                    from,
                    position: next.position,
                    ng: next.ng,
                });
            }
            hit = next;
        }
    }
    out
}

/// A non-delta surface point that sees `x`: where a cosine-distributed ray from `x` (on the
/// side facing `toward`) lands, with a random incident direction.
fn seen_from(scene: &Scene, x: &Landing, toward: Vec3, rng: &mut Rng) -> Option<Vertex> {
    let n = if x.ng.dot(toward - x.position) >= 0.0 {
        x.ng
    } else {
        -x.ng
    };
    let ray = Ray::spawn(
        x.position,
        n,
        Frame::from_z(n).to_world(cosine_hemisphere(rng.next_2d())),
    );
    let hit = scene.intersect(&ray)?;
    let facing = if hit.ng.dot(ray.dir) < 0.0 {
        hit.ng
    } else {
        -hit.ng
    };
    let vertex = Vertex {
        position: hit.position,
        ng: hit.ng,
        material: hit.material,
        wo: Frame::from_z(facing).to_world(cosine_hemisphere(rng.next_2d())),
    };
    vertex.bsdf(scene).filter(|b| !b.is_delta()).map(|_| vertex)
}

fn gathers(scene: &Scene, side: Side, size: usize, radius: f32) -> Vec<Gather> {
    let mut rng = Rng::for_sample(1, size as u64, side as u64, Stream::Eye);
    landings(scene, MERGES / size, &mut rng)
        .into_iter()
        .map(|landing| {
            let frame = Frame::from_z(landing.ng);
            match side {
                Side::Camera => Gather::OneOrigin {
                    origin: landing.from,
                    targets: (0..size)
                        .map(|_| {
                            let d = concentric_disk(rng.next_2d()) * radius;
                            landing.position + frame.x * d.x + frame.y * d.y
                        })
                        .collect(),
                },
                Side::Light => {
                    let mut origins = vec![landing.from];
                    while origins.len() < size {
                        origins.extend(seen_from(scene, &landing, landing.from.position, &mut rng));
                    }
                    Gather::OneTarget {
                        origins,
                        target: landing.position,
                    }
                }
            }
        })
        .collect()
}

#[derive(Default)]
struct Totals {
    merges: u64,
    trials: u64,
    rays: u64,
    packed: u64,
    capped: u64,
}

/// Estimates 1/p_acc for every merge once, a gather at a time: the bounds (one BSDF per
/// origin, as rendering has), then the estimates. Each merge has its own random
/// stream, as in rendering, so both widths count the same trials.
fn run<'s, T: TentativeTracer>(
    scene: &'s Scene,
    tracer: &T,
    gathers: &[Gather],
    radius: f32,
    estimator: &Estimator,
    pass: u64,
) -> Totals {
    let mut totals = Totals::default();
    let mut index = 0;
    let mut bounds = Vec::new();
    let mut rngs = Vec::new();
    for g in gathers {
        bounds.clear();
        rngs.clear();
        let mut add = |origin: &Vertex, bsdf: &Bsdf<'s>, target: Vec3| {
            if let Ok(bound) = AngularBound::new(origin.position, origin.ng, bsdf, target, radius) {
                index += 1;
                bounds.push(bound);
                rngs.push(Rng::for_sample(3, pass, index, Stream::Tentative));
            }
        };
        match g {
            Gather::OneOrigin { origin, targets } => {
                if let Some(bsdf) = origin.bsdf(scene) {
                    for &target in targets {
                        add(origin, &bsdf, target);
                    }
                }
            }
            Gather::OneTarget { origins, target } => {
                for origin in origins {
                    if let Some(bsdf) = origin.bsdf(scene) {
                        add(origin, &bsdf, *target);
                    }
                }
            }
        }
        estimator.estimate_all(tracer, &bounds, &mut rngs, |_, e| {
            black_box(e.inv_p_acc());
            totals.merges += 1;
            totals.trials += e.trials as u64;
            totals.rays += e.rays as u64;
            totals.packed += e.packed as u64;
            totals.capped += e.capped() as u64;
        });
    }
    totals
}

fn estimator(packet: PacketWidth) -> Estimator {
    Estimator {
        packet,
        ..Estimator::default()
    }
}

/// The scene as a tracer that also keeps every packet it traces, to replay the tracing alone.
struct Recording<'a> {
    scene: &'a Scene,
    packets: RefCell<Vec<([Ray; PACKET], u8)>>,
}

impl TentativeTracer for Recording<'_> {
    fn closest(&self, ray: &Ray) -> Option<f32> {
        self.scene.closest(ray)
    }

    fn closest8(&self, rays: &[Ray; PACKET], active: u8) -> [Option<f32>; PACKET] {
        self.packets.borrow_mut().push((*rays, active));
        self.scene.closest8(rays, active)
    }
}

/// CPU nanoseconds per ray of the recorded packets' rays traced one by one and as the
/// packets, best of 5 (thread CPU time: the machine is shared); `None` without packets.
fn tracing_alone(scene: &Scene, packets: &[([Ray; PACKET], u8)]) -> Option<(f64, f64)> {
    let rays: u32 = packets.iter().map(|(_, a)| a.count_ones()).sum();
    if rays == 0 {
        return None;
    }
    let mut best = [f64::INFINITY; 2];
    for _ in 0..5 {
        let start = ThreadTime::now();
        for (packet, active) in packets {
            for (i, ray) in packet.iter().enumerate() {
                if active & (1 << i) != 0 {
                    black_box(scene.closest(ray));
                }
            }
        }
        best[0] = best[0].min(start.elapsed().as_secs_f64());
        let start = ThreadTime::now();
        for (packet, active) in packets {
            black_box(scene.closest8(packet, *active));
        }
        best[1] = best[1].min(start.elapsed().as_secs_f64());
    }
    let [one, eight] = best.map(|s| s * 1e9 / rays as f64);
    Some((one, eight))
}

/// One row of the final table: both widths on one kind and size of gather.
struct Row {
    scene: &'static str,
    side: Side,
    size: usize,
    merges_per_s: [f64; 2],
    trials_per_merge: f64,
    rays_per_merge: [f64; 2],
    /// Share of the packet width's rays traced in packets.
    packed: f64,
    capped: u64,
    /// ns per ray of the packets' rays traced alone, one by one and as packets; `None` where
    /// no gather made a packet.
    tracing: Option<(f64, f64)>,
}

/// Several passes per width, alternating; pass `p` draws the same random numbers at both
/// widths, so both count the same trials and only the tracing differs.
fn table_row(
    name: &'static str,
    scene: &Scene,
    side: Side,
    size: usize,
    gathers: &[Gather],
    radius: f32,
) -> Row {
    let widths = [PacketWidth::One, PacketWidth::Eight];
    let mut time = [Duration::ZERO; 2];
    let mut totals = [Totals::default(), Totals::default()];
    for pass in 0..PASSES {
        for k in 0..widths.len() {
            // Alternate which width goes first, so load from other processes weighs on both.
            let i = (k + pass as usize) % widths.len();
            let start = ThreadTime::now();
            let t = run(scene, scene, gathers, radius, &estimator(widths[i]), pass);
            time[i] += start.elapsed();
            totals[i].merges += t.merges;
            totals[i].trials += t.trials;
            totals[i].rays += t.rays;
            totals[i].capped += t.capped;
            totals[i].packed += t.packed;
        }
    }
    assert_eq!(
        totals[0].trials, totals[1].trials,
        "same trials at both widths"
    );
    let recording = Recording {
        scene,
        packets: RefCell::new(Vec::new()),
    };
    let packet = estimator(PacketWidth::Eight);
    run(scene, &recording, gathers, radius, &packet, 0);
    let n = totals[0].merges as f64;
    Row {
        scene: name,
        side,
        size,
        merges_per_s: [0, 1].map(|i| n / time[i].as_secs_f64()),
        trials_per_merge: totals[0].trials as f64 / n,
        rays_per_merge: [0, 1].map(|i| totals[i].rays as f64 / n),
        packed: totals[1].packed as f64 / totals[1].rays.max(1) as f64,
        capped: totals[0].capped,
        tracing: tracing_alone(scene, &recording.packets.into_inner()),
    }
}

fn bench_scene(c: &mut Criterion, name: &'static str, path: &Path, rows: &mut Vec<Row>) {
    let Some(scene) = load_scene(name, path, AccelKind::default_kind()) else {
        return;
    };
    let radius = scene.default_radius(&Camera::new(scene.camera(None).expect("camera"), 256, 256));
    for side in [Side::Camera, Side::Light] {
        for size in GATHER_SIZES {
            let gathers = gathers(&scene, side, size, radius);
            if size == 4 {
                let mut group = c.benchmark_group(format!("upg-acceptance/{name}/{}", side.name()));
                group.throughput(Throughput::Elements(MERGES as u64));
                group
                    .sample_size(10)
                    .measurement_time(Duration::from_secs(3));
                for (label, packet) in [
                    ("packet 1", PacketWidth::One),
                    ("packet 8", PacketWidth::Eight),
                ] {
                    let estimator = estimator(packet);
                    let mut pass = 1000;
                    group.bench_function(format!("{label}, 4 merges per gather"), |b| {
                        b.iter(|| {
                            pass += 1;
                            run(&scene, &scene, &gathers, radius, &estimator, pass)
                        })
                    });
                }
                group.finish();
            }
            rows.push(table_row(name, &scene, side, size, &gathers, radius));
        }
    }
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
        "\nUPG tentative rays ({} backend, {MERGES} merges per pass, {PASSES} alternating passes per width)",
        AccelKind::default_kind().name()
    );
    println!(
        "{:15} {:10} {:>3} {:>10} {:>10} {:>7} {:>6} {:>6} {:>6} {:>7} {:>6} {:>8} {:>8} {:>6}",
        "scene",
        "gathers",
        "K",
        "merges/s 1",
        "merges/s 8",
        "8 / 1",
        "trials",
        "rays 1",
        "rays 8",
        "packed",
        "capped",
        "ns/ray 1",
        "ns/ray 8",
        "1 / 8"
    );
    for r in &rows {
        let tracing = r
            .tracing
            .map_or("       -        -      -".to_string(), |(one, eight)| {
                format!("{one:>8.1} {eight:>8.1} {:>6.2}", one / eight)
            });
        println!(
            "{:15} {:10} {:>3} {:>10.0} {:>10.0} {:>7.2} {:>6.2} {:>6.2} {:>6.2} {:>7.2} {:>6} {tracing}",
            r.scene,
            r.side.name(),
            r.size,
            r.merges_per_s[0],
            r.merges_per_s[1],
            r.merges_per_s[1] / r.merges_per_s[0],
            r.trials_per_merge,
            r.rays_per_merge[0],
            r.rays_per_merge[1],
            r.packed,
            r.capped,
        );
    }
    println!(
        "(packed: the share of the packet width's rays traced in packets; ns/ray: those rays \
         traced alone, CPU time)"
    );
}

criterion_group! {
    name = upg;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(upg);
