//! Fixed-radius queries: the hash grid (its default, which takes pairs of cells unless the
//! points crowd them, and 000's triplets of cells whatever the density) against SmallVCM's grid
//! layout and a kd-tree (kiddo's `ImmutableKdTree`), on two workloads.
//!
//! - 000 Table 2.1: two independent point sets sampled area-uniformly over the triangles of the
//!   Cornell box; the structures are built over the first and queried at points of the second.
//!   Radii are 0.01 and 0.1 of the scene size, the diagonal of its bounding box (the diameter
//!   of the bounding sphere the renderer uses).
//! - Light vertices: the positions a vcm iteration stores (one light sub-path per pixel of a
//!   512 x 512 image, traced with the library's lights, BSDFs and accelerator) on cornell-box
//!   and SmallVCM's scene g1, queried at the eye sub-paths' vertices in pixel order, with the
//!   scene's default radius and 0.01 of its size.
//!
//! Each query counts its neighbours and sums their indices; all structures must agree on the
//! totals. Timings are single-threaded; the grid's parallel build, its design, is measured as
//! well. The grids and SmallVCM layout rebuild into their buffers of the previous sample, as
//! they do across a render's iterations; the kd-tree is built anew. The grids' and SmallVCM's
//! layout's builds, and the four structures' queries of each batch, run in turn within every
//! sample, so a slow spell of a shared machine falls on all of them alike; the ratios (other /
//! grid, medians of the samples' ratios where timed in turn) are printed at the end.
//!
//! Run: `cargo bench --bench hashgrid`.

use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use glam::Vec3;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use std::cell::{Cell, RefCell};
use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use vmerge::accel::{AccelKind, Ray};
use vmerge::bsdf::TransportMode;
use vmerge::hashgrid::{CellRuns, GroupedPoints, HashGrid};
use vmerge::light::Aim;
use vmerge::sampling::{uniform_triangle, Distribution1D, Rng};
use vmerge::scene::{self, Camera, LoadOptions, Scene};

/// kiddo's fastest tree for static points: SoA leaves scanned in chunks, with the default
/// bucket size; `u32` items, as the grid's indices.
type KdTree = ImmutableKdTree<f32, u32, 3, 32>;

const SIZES: [usize; 3] = [1_000_000, 3_000_000, 10_000_000];
/// Radii as fractions of the scene size, with the number of query points and how many of them
/// one timed iteration answers (the next batch each time, cycling): the larger radius returns
/// 100 times more neighbours, so it gets 100 times fewer.
const RADII: [(f32, usize, usize); 2] = [(0.01, 100_000, 1_000), (0.1, 1_000, 10)];
/// Queries per timed iteration on the light-vertex sets.
const LIGHT_BATCH: usize = 1_000;
/// The light-vertex sets' image: one light sub-path per pixel.
const LIGHT_RESOLUTION: u32 = 512;

/// SmallVCM's grid layout (its hashgrid.hxx), re-implemented from its description: cells of
/// side 2r, a counting sort of the points into a flat table of cell ranges indexed by a hash
/// of the cell coordinates, as many slots as points (no comparison sort, no key compare:
/// cells that share a slot share its range, and the distance test rejects the strangers); a
/// query visits the 2 x 2 x 2 cells nearest to it. Two changes make it comparable: the points
/// are copied into slot order in the grid's own point store, four to a cache line, and scanned
/// by its vectorised distance test (SmallVCM reads them through their indices, one at a
/// time); cells are those
/// of the world grid, not of the points' bounding box, so no query outside the box is
/// skipped; and a slot two of a query's cells share is scanned once, so results are exact.
#[derive(Default)]
struct FlatGrid {
    radius_sq: f32,
    inv_cell: f32,
    /// Per slot the end of its range (its start is the previous slot's end); counts and
    /// then starts while building.
    ends: Vec<u32>,
    points: GroupedPoints,
}

impl FlatGrid {
    fn rebuild(&mut self, points: &[Vec3], radius: f32) {
        self.radius_sq = radius * radius;
        self.inv_cell = 1.0 / (2.0 * radius);
        let n = points.len();
        self.ends.clear();
        self.ends.resize(n.max(1), 0);
        for &p in points {
            let slot = self.slot(self.cell(p));
            self.ends[slot] += 1;
        }
        let mut sum = 0;
        for count in &mut self.ends {
            (*count, sum) = (sum, sum + *count);
        }
        self.points.reset(n);
        for (i, &p) in points.iter().enumerate() {
            let slot = self.slot(self.cell(p));
            let at = self.ends[slot] as usize;
            self.ends[slot] += 1;
            self.points.set(at, p, i as u32);
        }
    }

    fn cell(&self, p: Vec3) -> [i32; 3] {
        let c = (p * self.inv_cell).floor();
        [c.x as i32, c.y as i32, c.z as i32]
    }

    /// SmallVCM's hash, modulo the table size.
    fn slot(&self, [x, y, z]: [i32; 3]) -> usize {
        let h = (x as u32).wrapping_mul(73_856_093)
            ^ (y as u32).wrapping_mul(19_349_663)
            ^ (z as u32).wrapping_mul(83_492_791);
        (h % self.ends.len() as u32) as usize
    }

    fn query(&self, q: Vec3, mut visit: impl FnMut(usize, f32)) {
        let scaled = q * self.inv_cell;
        let c = scaled.floor();
        let fraction = scaled - c;
        let base = [c.x as i32, c.y as i32, c.z as i32];
        // The neighbour on the side of the cell's half the query lies in.
        let other = |axis: usize| base[axis] + if fraction[axis] < 0.5 { -1 } else { 1 };
        let (xo, yo, zo) = (other(0), other(1), other(2));
        let [x, y, z] = base;
        let slots = [
            [x, y, z],
            [x, y, zo],
            [x, yo, z],
            [x, yo, zo],
            [xo, y, z],
            [xo, y, zo],
            [xo, yo, z],
            [xo, yo, zo],
        ]
        .map(|cell| self.slot(cell));
        for (j, &slot) in slots.iter().enumerate() {
            if slots[..j].contains(&slot) {
                continue;
            }
            let begin = if slot == 0 { 0 } else { self.ends[slot - 1] };
            let points = &self.points;
            points.scan(
                begin as usize..self.ends[slot] as usize,
                q,
                self.radius_sq,
                &mut |slot, d2| visit(points.index_of(slot) as usize, d2),
            );
        }
    }
}

fn load(path: &Path) -> Scene {
    scene::load(
        path,
        &LoadOptions {
            accel: AccelKind::default_kind(),
            lenient: true,
            shading_normals: true,
        },
    )
    .expect("bench scene loads")
}

/// Area-uniform points on the triangles of a scene.
struct Surfaces {
    triangles: Vec<[Vec3; 3]>,
    areas: Distribution1D,
}

impl Surfaces {
    fn new(scene: &Scene) -> Self {
        let geometry = &scene.geometry;
        assert!(geometry.spheres.is_empty(), "only triangles are sampled");
        let triangles: Vec<[Vec3; 3]> = (0..geometry.triangles.len() as u32)
            .map(|i| geometry.triangle_vertices(i))
            .collect();
        let areas = triangles
            .iter()
            .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
            .collect();
        Surfaces {
            triangles,
            areas: Distribution1D::new(areas).expect("scene has area"),
        }
    }

    fn diagonal(&self) -> f32 {
        let (min, max) = self
            .triangles
            .iter()
            .flatten()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(min, max), &p| {
                (min.min(p), max.max(p))
            });
        (max - min).length()
    }

    /// `n` points from the generator `seed`, in parallel chunks with their own streams so the
    /// set does not depend on the number of threads.
    fn sample(&self, n: usize, seed: u64) -> Vec<Vec3> {
        const CHUNK: usize = 1 << 16;
        let mut points = vec![Vec3::ZERO; n];
        points
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                let mut rng = Rng::from_seed(seed, chunk as u64);
                for p in out {
                    let (i, _) = self.areas.sample(rng.next_f32());
                    let (b1, b2) = uniform_triangle(rng.next_2d());
                    let [a, b, c] = self.triangles[i];
                    *p = (1.0 - b1 - b2) * a + b1 * b + b2 * c;
                }
            });
        points
    }
}

/// The non-delta vertices of one random walk from `ray`, as vcm's sub-paths are traced: BSDF
/// sampling, Russian roulette from path length 3 (the default) by the BSDF's continuation
/// probability, at most the scene's maximum path length.
fn walk(scene: &Scene, mut ray: Ray, mode: TransportMode, rng: &mut Rng, out: &mut Vec<Vec3>) {
    let max_length = match scene.defaults.max_path_length {
        0 => u32::MAX,
        n => n,
    };
    let mut path_length = 1;
    while let Some(hit) = scene.intersect(&ray) {
        let Some(bsdf) = scene.bsdf_at(&hit, -ray.dir.normalize(), mode) else {
            break;
        };
        if !bsdf.is_delta() {
            out.push(hit.position);
        }
        let Some(s) = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()]) else {
            break;
        };
        if path_length + 2 > max_length
            || (path_length >= 3 && rng.next_f32() >= bsdf.continuation_probability())
            || s.f.is_black()
        {
            break;
        }
        ray = Ray::spawn(hit.position, hit.ng, s.wi);
        path_length += 1;
    }
}

/// A vcm iteration's light vertices (one light sub-path per pixel) and its eye vertices (one
/// eye sub-path per pixel, in pixel order), in parallel chunks of paths with their own streams.
fn vertex_sets(scene: &Scene, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    const CHUNK: usize = 1 << 12;
    let camera = Camera::new(&scene.cameras[0], LIGHT_RESOLUTION, LIGHT_RESOLUTION);
    let pixels = camera.pixel_count();
    let gather = |trace: &(dyn Fn(usize, &mut Rng, &mut Vec<Vec3>) + Sync), stream: u64| {
        (0..pixels.div_ceil(CHUNK))
            .into_par_iter()
            .flat_map_iter(|chunk| {
                let mut rng = Rng::from_seed(seed, 2 * chunk as u64 + stream);
                let mut out = Vec::new();
                for pixel in chunk * CHUNK..((chunk + 1) * CHUNK).min(pixels) {
                    trace(pixel, &mut rng, &mut out);
                }
                out
            })
            .collect::<Vec<Vec3>>()
    };
    let light = gather(
        &|_, rng, out| {
            let lights = &scene.lights;
            let Some((index, _)) = lights.pick(rng.next_f32()) else {
                return;
            };
            let light = lights.get(index);
            let (u_pos, u_dir) = (rng.next_2d(), rng.next_2d());
            let Some(e) = light.emit(u_pos, u_dir, Aim::Disc) else {
                return;
            };
            let origin = if light.is_finite() && !light.is_delta() {
                Ray::spawn(e.position, e.normal, e.dir).origin
            } else {
                e.position
            };
            walk(
                scene,
                Ray::new(origin, e.dir),
                TransportMode::Importance,
                rng,
                out,
            );
        },
        0,
    );
    let width = camera.width as usize;
    let eye = gather(
        &|pixel, rng, out| {
            let [jx, jy] = rng.next_2d();
            let ray = camera.generate_ray((pixel % width) as f32 + jx, (pixel / width) as f32 + jy);
            walk(scene, ray, TransportMode::Radiance, rng, out);
        },
        1,
    );
    (light, eye)
}

/// Neighbour count and index sum over all queries: the work every structure does, and their
/// agreement check.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Totals {
    count: u64,
    index_sum: u64,
}

fn query_grid(grid: &HashGrid, queries: &[Vec3]) -> Totals {
    let mut totals = Totals::default();
    for &q in queries {
        grid.query(q, |i, _| {
            totals.count += 1;
            totals.index_sum += i as u64;
        });
    }
    totals
}

fn query_flat(grid: &FlatGrid, queries: &[Vec3]) -> Totals {
    let mut totals = Totals::default();
    for &q in queries {
        grid.query(q, |i, _| {
            totals.count += 1;
            totals.index_sum += i as u64;
        });
    }
    totals
}

fn query_tree(tree: &KdTree, queries: &[[f32; 3]], radius: f32) -> Totals {
    let mut totals = Totals::default();
    for q in queries {
        for neighbour in tree.within_unsorted::<SquaredEuclidean>(q, radius * radius) {
            totals.count += 1;
            totals.index_sum += neighbour.item as u64;
        }
    }
    totals
}

/// Seconds per iteration of every sample criterion takes, by measurement.
#[derive(Default)]
struct Record(RefCell<BTreeMap<String, Vec<f64>>>);

impl Record {
    /// Times `iters` runs of `f` for criterion and keeps the time per run.
    fn time<R>(&self, key: &str, iters: u64, mut f: impl FnMut() -> R) -> Duration {
        self.time_interleaved(&mut [(key, &mut || drop(black_box(f())))], iters)
    }

    /// Times `iters` rounds of `runs`, each round running them in turn, and keeps each one's
    /// time per run under its key: all see the same spells of a shared machine, so their
    /// ratios are taken sample by sample ([`Record::median_ratio`]).
    fn time_interleaved(&self, runs: &mut [(&str, &mut dyn FnMut())], iters: u64) -> Duration {
        let mut elapsed = vec![Duration::ZERO; runs.len()];
        for _ in 0..iters {
            for ((_, run), elapsed) in runs.iter_mut().zip(&mut elapsed) {
                let start = Instant::now();
                run();
                *elapsed += start.elapsed();
            }
        }
        let mut record = self.0.borrow_mut();
        for ((key, _), elapsed) in runs.iter().zip(&elapsed) {
            record
                .entry(key.to_string())
                .or_default()
                .push(elapsed.as_secs_f64() / iters as f64);
        }
        elapsed.iter().sum()
    }

    /// The median over samples of `numerator`'s time over `denominator`'s, for two keys timed
    /// together by [`Record::time_interleaved`].
    fn median_ratio(&self, numerator: &str, denominator: &str) -> Option<f64> {
        let record = self.0.borrow();
        let (n, d) = (record.get(numerator)?, record.get(denominator)?);
        let mut ratios: Vec<f64> = n.iter().zip(d).map(|(n, d)| n / d).collect();
        ratios.sort_by(f64::total_cmp);
        ratios.get(ratios.len() / 2).copied()
    }

    fn median(&self, key: &str) -> Option<f64> {
        let mut times = self.0.borrow().get(key)?.clone();
        times.sort_by(f64::total_cmp);
        Some(times[times.len() / 2])
    }
}

/// One workload: points, queries (in batches timed one per iteration, cycling) and a radius.
struct Workload<'a> {
    name: String,
    points: &'a [Vec3],
    queries: &'a [Vec3],
    batch: usize,
    radius: f32,
}

/// Times the builds and queries of one workload under `key`; the kd-tree's build once per
/// point set (`tree_key`), as it does not depend on the radius. Returns the runs the default
/// grid took.
fn measure(
    c: &mut Criterion,
    record: &Record,
    single: &rayon::ThreadPool,
    w: &Workload,
    tree: &KdTree,
    tree_key: &str,
) -> CellRuns {
    let threads = rayon::current_num_threads();
    let key = &w.name;
    let mut group = c.benchmark_group(format!("hashgrid/{key}"));
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(200))
        .measurement_time(Duration::from_secs(2));
    if record
        .median(&format!("{tree_key}/build/kd-tree"))
        .is_none()
    {
        let arrays: Vec<[f32; 3]> = w.points.iter().map(|p| p.to_array()).collect();
        group.bench_function("build/kd-tree", |b| {
            b.iter_custom(|iters| {
                record.time(&format!("{tree_key}/build/kd-tree"), iters, || {
                    KdTree::new_from_slice(&arrays)
                })
            })
        });
    }
    let (mut grid, mut triplets, mut flat) = (
        HashGrid::default(),
        HashGrid::default(),
        FlatGrid::default(),
    );
    group.bench_function("build/grids-and-smallvcm-layout", |b| {
        b.iter_custom(|iters| {
            record.time_interleaved(
                &mut [
                    (&format!("{key}/build/grid"), &mut || {
                        single.install(|| grid.rebuild(w.points, w.radius))
                    }),
                    (&format!("{key}/build/triplets"), &mut || {
                        single
                            .install(|| triplets.rebuild_as(w.points, w.radius, CellRuns::Triplets))
                    }),
                    (&format!("{key}/build/flat"), &mut || {
                        flat.rebuild(w.points, w.radius)
                    }),
                ],
                iters,
            )
        })
    });
    group.bench_function(format!("build/grid-{threads}-threads"), |b| {
        b.iter_custom(|iters| {
            record.time(&format!("{key}/build/grid-par"), iters, || {
                grid.rebuild(w.points, w.radius)
            })
        })
    });
    grid.rebuild(w.points, w.radius);
    triplets.rebuild_as(w.points, w.radius, CellRuns::Triplets);
    flat.rebuild(w.points, w.radius);
    let query_arrays: Vec<[f32; 3]> = w.queries.iter().map(|q| q.to_array()).collect();
    let expected = query_tree(tree, &query_arrays, w.radius);
    assert_eq!(query_grid(&grid, w.queries), expected, "grid, {key}");
    assert_eq!(
        query_grid(&triplets, w.queries),
        expected,
        "triplets, {key}"
    );
    assert_eq!(
        query_flat(&flat, w.queries),
        expected,
        "SmallVCM layout, {key}"
    );
    record.0.borrow_mut().insert(
        format!("{key}/neighbours"),
        vec![expected.count as f64 / w.queries.len() as f64],
    );
    let batches = w.queries.len() / w.batch;
    let batch = |next: usize| next * w.batch..(next + 1) * w.batch;
    let mut next = 0;
    group.bench_function("query/kd-tree-grids-and-smallvcm-layout", |b| {
        b.iter_custom(|iters| {
            // All four answer the same batch, the next one each round.
            let current = Cell::new(next);
            let queries = || batch(current.get());
            let elapsed = record.time_interleaved(
                &mut [
                    (&format!("{key}/query/kd-tree"), &mut || {
                        current.set((current.get() + 1) % batches);
                        black_box(query_tree(tree, &query_arrays[queries()], w.radius));
                    }),
                    (&format!("{key}/query/grid"), &mut || {
                        black_box(query_grid(&grid, &w.queries[queries()]));
                    }),
                    (&format!("{key}/query/triplets"), &mut || {
                        black_box(query_grid(&triplets, &w.queries[queries()]));
                    }),
                    (&format!("{key}/query/flat"), &mut || {
                        black_box(query_flat(&flat, &w.queries[queries()]));
                    }),
                ],
                iters,
            );
            next = current.get();
            elapsed
        })
    });
    group.finish();
    grid.runs()
}

/// A printed table's row: its label, the record's keys of the workload and of its point set's
/// kd-tree, the queries per timed iteration, and the runs the default grid took.
struct Row {
    label: String,
    key: String,
    tree_key: String,
    batch: usize,
    runs: CellRuns,
}

/// One table row per workload: the default grid's runs (pairs or triplets of cells), build
/// times in ms, query times in µs per query, ratios of the other structures' times to the
/// default grid's.
fn print_table(record: &Record, rows: &[Row]) {
    let threads = rayon::current_num_threads();
    println!(
        "{:>22} {:>9} {:>5} | {:>8} {:>8} {:>8} {:>8} {:>8} {:>6} {:>6} {:>6} | {:>8} {:>8} {:>8} {:>8} {:>6} {:>6} {:>6}",
        "workload",
        "nbrs/q",
        "runs",
        "kd ms",
        "grid ms",
        format!("grid {threads}t"),
        "trip ms",
        "flat ms",
        "kd/g",
        "trip/g",
        "flat/g",
        "kd us/q",
        "grid us/q",
        "trip us/q",
        "flat us/q",
        "kd/g",
        "trip/g",
        "flat/g"
    );
    for Row {
        label,
        key,
        tree_key,
        batch,
        runs,
    } in rows
    {
        let get = |what: &str| record.median(&format!("{key}/{what}"));
        // What was timed interleaved with the grid is compared by the median of the samples'
        // ratios: the other layouts' builds, and every query.
        let ratio = |other: &str, grid: &str| {
            record.median_ratio(&format!("{key}/{other}"), &format!("{key}/{grid}"))
        };
        let (
            Some(build_kd),
            Some(build_grid),
            Some(build_par),
            Some(build_triplets),
            Some(build_flat),
            Some(query_kd),
            Some(query_grid),
            Some(query_triplets),
            Some(query_flat),
            Some(neighbours),
        ) = (
            record.median(&format!("{tree_key}/build/kd-tree")),
            get("build/grid"),
            get("build/grid-par"),
            get("build/triplets"),
            get("build/flat"),
            get("query/kd-tree"),
            get("query/grid"),
            get("query/triplets"),
            get("query/flat"),
            get("neighbours"),
        )
        else {
            continue;
        };
        let (
            Some(build_triplets_ratio),
            Some(build_flat_ratio),
            Some(query_kd_ratio),
            Some(query_triplets_ratio),
            Some(query_flat_ratio),
        ) = (
            ratio("build/triplets", "build/grid"),
            ratio("build/flat", "build/grid"),
            ratio("query/kd-tree", "query/grid"),
            ratio("query/triplets", "query/grid"),
            ratio("query/flat", "query/grid"),
        )
        else {
            continue;
        };
        let per_query = 1e6 / *batch as f64;
        println!(
            "{:>22} {:>9.1} {:>5} | {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>6.2} {:>6.2} {:>6.2} | {:>8.3} {:>8.3} {:>8.3} {:>8.3} {:>6.2} {:>6.2} {:>6.2}",
            label,
            neighbours,
            match runs {
                CellRuns::Pairs => "pairs",
                CellRuns::Triplets => "trip",
            },
            build_kd * 1e3,
            build_grid * 1e3,
            build_par * 1e3,
            build_triplets * 1e3,
            build_flat * 1e3,
            build_kd / build_grid,
            build_triplets_ratio,
            build_flat_ratio,
            query_kd * per_query,
            query_grid * per_query,
            query_triplets * per_query,
            query_flat * per_query,
            query_kd_ratio,
            query_triplets_ratio,
            query_flat_ratio
        );
    }
}

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool");
    let record = Record::default();
    let mut rows = Vec::new();

    // 000 Table 2.1.
    let cornell = root.join("scenes/cornell-box/scene.toml");
    let surfaces = Surfaces::new(&load(&cornell));
    let diagonal = surfaces.diagonal();
    let max_queries = RADII.iter().map(|&(_, n, _)| n).max().unwrap_or(0);
    let queries = surfaces.sample(max_queries, 2);
    for n in SIZES {
        let points = surfaces.sample(n, 1);
        let arrays: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = KdTree::new_from_slice(&arrays);
        drop(arrays);
        for (fraction, query_count, batch) in RADII {
            let workload = Workload {
                name: format!("{n}/{fraction}"),
                points: &points,
                queries: &queries[..query_count],
                batch,
                radius: fraction * diagonal,
            };
            let runs = measure(c, &record, &single, &workload, &tree, &n.to_string());
            rows.push(Row {
                label: format!("{}M r {fraction}", n / 1_000_000),
                key: workload.name,
                tree_key: n.to_string(),
                batch,
                runs,
            });
        }
    }

    // Light vertices of a vcm iteration.
    let mut scenes = vec![("cornell-box", cornell.clone())];
    let g1: PathBuf =
        root.join("../shared/peers/smallvcm/scenes/g1_largemirror_ceiling/scene.toml");
    if g1.exists() {
        scenes.push(("g1", g1));
    } else {
        eprintln!("skipping scene g1: {} not found", g1.display());
    }
    let mut light_rows = Vec::new();
    for (name, path) in scenes {
        let scene = load(&path);
        let (points, queries) = vertex_sets(&scene, 1);
        let size = 2.0 * scene.bounding_sphere.1;
        let arrays: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let tree = KdTree::new_from_slice(&arrays);
        drop(arrays);
        let usable = queries.len() / LIGHT_BATCH * LIGHT_BATCH;
        let default_radius = scene.default_radius(&Camera::new(
            &scene.cameras[0],
            LIGHT_RESOLUTION,
            LIGHT_RESOLUTION,
        ));
        println!(
            "{name}: {} light vertices, {} eye vertices, size {size:.3}, default radius {:.5}",
            points.len(),
            queries.len(),
            default_radius
        );
        for (label, radius) in [("default r", default_radius), ("r 0.01", 0.01 * size)] {
            let workload = Workload {
                name: format!("{name}/{label}"),
                points: &points,
                queries: &queries[..usable],
                batch: LIGHT_BATCH,
                radius,
            };
            let runs = measure(c, &record, &single, &workload, &tree, name);
            light_rows.push(Row {
                label: format!("{name} {label}"),
                key: workload.name,
                tree_key: name.to_string(),
                batch: LIGHT_BATCH,
                runs,
            });
        }
    }

    println!(
        "\nTimes are medians over samples; grid = the default (runs: pairs or triplets of \
         cells), trip = triplets of cells (000), flat = SmallVCM's layout; ratios other / grid. \
         The other layouts' builds and all queries are timed interleaved with the grid's, \
         their ratios the medians of the samples' ratios."
    );
    println!("000 Table 2.1 (Cornell box surfaces, size {diagonal:.3}):");
    print_table(&record, &rows);
    println!(
        "Light vertices of a vcm iteration ({LIGHT_RESOLUTION}^2 paths), eye vertices as queries:"
    );
    print_table(&record, &light_rows);
}
criterion_group! {
    name = hashgrid;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(hashgrid);
