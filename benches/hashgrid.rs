//! The workload of 000 Table 2.1: the hash grid against a kd-tree (kiddo's `ImmutableKdTree`)
//! for fixed-radius queries over points scattered uniformly over the surfaces of the Cornell box.
//!
//! Two independent point sets are sampled area-uniformly over the scene's triangles: both
//! structures are built over the first and queried at points of the second. Radii are 0.01 and
//! 0.1 of the scene size, the diagonal of its bounding box (the diameter of the bounding sphere
//! the renderer uses). Each query counts its neighbours and sums their indices; both structures
//! must agree on the totals. Timings are single-threaded; the grid's parallel build, its design,
//! is measured as well. The ratios (kd-tree time / grid time) are printed at the end.
//!
//! Run: `cargo bench --bench hashgrid`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode};
use glam::Vec3;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use rayon::prelude::*;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};
use vmerge::accel::AccelKind;
use vmerge::hashgrid::HashGrid;
use vmerge::sampling::{uniform_triangle, Distribution1D, Rng};
use vmerge::scene::{self, LoadOptions};

/// kiddo's fastest tree for static points: SoA leaves scanned in chunks, with the default
/// bucket size; `u32` items, as the grid's indices.
type KdTree = ImmutableKdTree<f32, u32, 3, 32>;

const SIZES: [usize; 3] = [1_000_000, 3_000_000, 10_000_000];
/// Radii as fractions of the scene size, with the number of query points and how many of them
/// one timed iteration answers (the next batch each time, cycling): the larger radius returns
/// 100 times more neighbours, so it gets 100 times fewer.
const RADII: [(f32, usize, usize); 2] = [(0.01, 100_000, 1_000), (0.1, 1_000, 10)];

/// Area-uniform points on the triangles of a scene.
struct Surfaces {
    triangles: Vec<[Vec3; 3]>,
    areas: Distribution1D,
}

impl Surfaces {
    fn load(path: &Path) -> Self {
        let scene = scene::load(
            path,
            &LoadOptions {
                accel: AccelKind::Bvh,
                lenient: true,
                shading_normals: true,
            },
        )
        .expect("bench scene loads");
        let geometry = scene.geometry;
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

/// Neighbour count and index sum over all queries: the work both structures do, and their
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
        let start = Instant::now();
        for _ in 0..iters {
            black_box(f());
        }
        let elapsed = start.elapsed();
        self.0
            .borrow_mut()
            .entry(key.to_string())
            .or_default()
            .push(elapsed.as_secs_f64() / iters as f64);
        elapsed
    }

    fn median(&self, key: &str) -> Option<f64> {
        let mut times = self.0.borrow().get(key)?.clone();
        times.sort_by(f64::total_cmp);
        Some(times[times.len() / 2])
    }
}

fn benches(c: &mut Criterion) {
    let surfaces = Surfaces::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml"),
    );
    let diagonal = surfaces.diagonal();
    let max_queries = RADII.iter().map(|&(_, n, _)| n).max().unwrap_or(0);
    let queries = surfaces.sample(max_queries, 2);
    let query_arrays: Vec<[f32; 3]> = queries.iter().map(|q| q.to_array()).collect();
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool");
    let threads = rayon::current_num_threads();
    let record = Record::default();

    for n in SIZES {
        let points = surfaces.sample(n, 1);
        let arrays: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
        let mut group = c.benchmark_group(format!("hashgrid/{n}"));
        group
            .sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_millis(200))
            .measurement_time(Duration::from_secs(2));
        group.bench_function("build/kd-tree", |b| {
            b.iter_custom(|iters| {
                record.time(&format!("{n}/build/kd-tree"), iters, || {
                    KdTree::new_from_slice(&arrays)
                })
            })
        });
        let tree = KdTree::new_from_slice(&arrays);
        for (fraction, query_count, batch) in RADII {
            let radius = fraction * diagonal;
            let key = format!("{n}/{fraction}");
            group.bench_function(BenchmarkId::new("build/grid", fraction), |b| {
                b.iter_custom(|iters| {
                    record.time(&format!("{key}/build/grid"), iters, || {
                        single.install(|| HashGrid::build(&points, radius))
                    })
                })
            });
            group.bench_function(
                BenchmarkId::new(format!("build/grid-{threads}-threads"), fraction),
                |b| {
                    b.iter_custom(|iters| {
                        record.time(&format!("{key}/build/grid-par"), iters, || {
                            HashGrid::build(&points, radius)
                        })
                    })
                },
            );
            let grid = HashGrid::build(&points, radius);
            let queries = &queries[..query_count];
            let query_arrays = &query_arrays[..query_count];
            let expected = query_tree(&tree, query_arrays, radius);
            assert_eq!(
                query_grid(&grid, queries),
                expected,
                "{n} points, r {radius}"
            );
            record
                .0
                .borrow_mut()
                .insert(format!("{key}/neighbours"), vec![expected.count as f64]);
            let batches = query_count / batch;
            let mut next = 0;
            group.bench_function(BenchmarkId::new("query/kd-tree", fraction), |b| {
                b.iter_custom(|iters| {
                    record.time(&format!("{key}/query/kd-tree"), iters, || {
                        next = (next + 1) % batches;
                        query_tree(&tree, &query_arrays[next * batch..][..batch], radius)
                    })
                })
            });
            group.bench_function(BenchmarkId::new("query/grid", fraction), |b| {
                b.iter_custom(|iters| {
                    record.time(&format!("{key}/query/grid"), iters, || {
                        next = (next + 1) % batches;
                        query_grid(&grid, &queries[next * batch..][..batch])
                    })
                })
            });
        }
        group.finish();
    }

    println!("\nScene size (bounding-box diagonal) {diagonal:.3}; times are medians over samples.");
    println!(
        "{:>10} {:>6} {:>9} | {:>9} {:>9} {:>9} {:>6} {:>6} | {:>10} {:>10} {:>6}",
        "points",
        "r",
        "nbrs/q",
        "kd ms",
        "grid ms",
        format!("grid {threads}t"),
        "ratio",
        format!("{threads}t"),
        "kd us/q",
        "grid us/q",
        "ratio"
    );
    for n in SIZES {
        let build_kd = record.median(&format!("{n}/build/kd-tree"));
        for (fraction, query_count, batch) in RADII {
            let key = format!("{n}/{fraction}");
            let get = |what: &str| record.median(&format!("{key}/{what}"));
            let (
                Some(build_kd),
                Some(build_grid),
                Some(build_par),
                Some(query_kd),
                Some(query_grid),
                Some(neighbours),
            ) = (
                build_kd,
                get("build/grid"),
                get("build/grid-par"),
                get("query/kd-tree"),
                get("query/grid"),
                get("neighbours"),
            )
            else {
                continue;
            };
            let per_query = 1e6 / batch as f64;
            println!(
                "{:>10} {:>6} {:>9.0} | {:>9.1} {:>9.1} {:>9.1} {:>6.2} {:>6.2} | {:>10.3} {:>10.3} {:>6.2}",
                n,
                fraction,
                neighbours / query_count as f64,
                build_kd * 1e3,
                build_grid * 1e3,
                build_par * 1e3,
                build_kd / build_grid,
                build_kd / build_par,
                query_kd * per_query,
                query_grid * per_query,
                query_kd / query_grid
            );
        }
    }
}

criterion_group! {
    name = hashgrid;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(hashgrid);
