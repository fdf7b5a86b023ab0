//! The density map of 002 sec. 5.1: how many light vertices a merge at x can expect, k(x), for
//! the VCM+ and VCM* weights (`mis.rs`, [`VcmWeights::with_density`]) of density-estimate and
//! UPG merges alike.
//!
//! A hash grid of counters over cells of side r_c = 2 r_1 (twice the first iteration's merge
//! radius: cells that hold several merges' worth of light vertices, yet stay local). After
//! each iteration's eye pass every stored light vertex of the iteration increments its cell,
//! for the first `density_map_iterations` iterations (002 uses 50); afterwards the map, and so
//! every weight, is fixed. Counts are integers summed per cell, so the map does not depend on
//! the thread count, and it is a pure function of the seed and the iterations: `continue`
//! rebuilds it by tracing the light passes of those iterations again.
//!
//! A lookup (one hash probe: the counts are also kept by 2 x 2 x 2 blocks) filters the
//! 2 x 2 x 2 cells around x (those whose centres bound x, as bilinear
//! filtering would) with weights w_c = exp(-|x - x_c| / r_c) over the cells that counted
//! anything (002 sec. 5.1; distances in cell sides, so the filter does not depend on the
//! scene's units), giving q, the count per cell over n_it iterations; regularised to at least
//! one vertex over all iterations (002's q' = max(q, 1 / n_it) per iteration), it becomes the
//! expected count within radius r per iteration, k = q pi r^2 / (r_c^2 n_it), clamped to
//! [1, n_VM] so that c = n_VM / k stays in 002's [1, n_Phi].
//!
//! Most merges on small images expect k < 1, where the clamp makes the lookup's answer 1
//! whatever the counts; yet each probe misses the caches (the map outgrows them). So after
//! every insertion a 64 KiB bit set, small enough to stay cached, marks the blocks whose
//! largest count could give k > 1 at the first radius; a lookup in an unmarked block answers 1
//! without the probe while the radius is at most the first (it shrinks: k only falls). The
//! answers are the probe's exactly (tested below). With per-pixel radii each lookup takes the
//! path's radius, which may exceed the first: those lookups always probe.
//!
//! [`VcmWeights::with_density`]: super::mis::VcmWeights::with_density

use glam::Vec3;
use hashbrown::HashMap;
use rayon::prelude::*;
use rustc_hash::FxBuildHasher;

type Cell = [i32; 3];

pub struct DensityMap {
    cell_size: f32,
    inv_cell: f32,
    counts: HashMap<Cell, u32, FxBuildHasher>,
    /// The counts again, by 2 x 2 x 2 blocks keyed by their lowest cell, so that a lookup is
    /// one probe instead of eight.
    blocks: HashMap<Cell, [u32; 8], FxBuildHasher>,
    /// Blocks whose counts may give k > 1 at the first radius, by a hash of their key (one
    /// bit may stand for several blocks: a false mark only costs the probe).
    hot: Vec<u64>,
    /// pi r_1^2 / r_c^2: the area ratio the marks were set for.
    hot_area_ratio: f32,
    /// Iterations inserted so far, and how many the map takes.
    iterations: u32,
    max_iterations: u32,
}

/// log2 of the bits in [`DensityMap::hot`] (2^19 bits: 64 KiB).
const HOT_BITS: u32 = 19;

/// A block is marked when its largest count gives k above this at the first radius; below
/// 1, so that the rounding of the filter's weighted mean cannot push an unmarked block's k
/// over 1.
const HOT_K: f32 = 0.999;

/// The cells of a block, as offsets from its lowest cell.
const BLOCK: [[i32; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [1, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [0, 1, 1],
    [1, 1, 1],
];

/// Light vertices counted by one parallel task before the counts are summed.
const CHUNK: usize = 1 << 14;

impl DensityMap {
    /// An empty map for merges of first radius `base_radius`, filled for `max_iterations`.
    pub fn new(base_radius: f32, max_iterations: u32) -> Self {
        let cell_size = 2.0 * base_radius;
        let inv_cell = 1.0 / cell_size;
        DensityMap {
            cell_size,
            inv_cell,
            counts: HashMap::default(),
            blocks: HashMap::default(),
            hot: vec![0; 1 << (HOT_BITS - 6)],
            hot_area_ratio: area_ratio(base_radius, inv_cell),
            iterations: 0,
            max_iterations,
        }
    }

    /// Iterations inserted so far.
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// Whether the map still takes iterations.
    pub fn is_filling(&self) -> bool {
        self.iterations < self.max_iterations
    }

    /// Counts one iteration's light vertices.
    pub fn insert(&mut self, positions: &[Vec3]) {
        let inv_cell = self.inv_cell;
        let partial: Vec<HashMap<Cell, u32, FxBuildHasher>> = positions
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut counts = HashMap::default();
                for &p in chunk {
                    *counts.entry(cell_of(p, inv_cell)).or_insert(0) += 1;
                }
                counts
            })
            .collect();
        for counts in partial {
            for (cell @ [x, y, z], n) in counts {
                *self.counts.entry(cell).or_insert(0) += n;
                for (slot, [dx, dy, dz]) in BLOCK.iter().enumerate() {
                    self.blocks
                        .entry([x - dx, y - dy, z - dz])
                        .or_insert([0; 8])[slot] += n;
                }
            }
        }
        self.iterations += 1;
        self.mark_hot_blocks();
    }

    /// Marks the blocks whose largest count, as q at the first radius, gives k > [`HOT_K`].
    fn mark_hot_blocks(&mut self) {
        self.hot.fill(0);
        let scale = self.hot_area_ratio / self.iterations as f32;
        for (&key, counts) in &self.blocks {
            let largest = counts.iter().copied().max().unwrap_or(0);
            if largest as f32 * scale > HOT_K {
                let bit = hot_bit(key);
                self.hot[bit >> 6] |= 1 << (bit & 63);
            }
        }
    }

    /// 1 / k(x) for merges of radius `radius` among `light_paths` light sub-paths, or `None`
    /// while the map is empty.
    pub fn inv_expected_count(&self, x: Vec3, radius: f32, light_paths: f32) -> Option<f32> {
        if self.iterations == 0 {
            return None;
        }
        let s = x * self.inv_cell - Vec3::splat(0.5);
        let key = block_of(s);
        // An unmarked block's counts give q pi r^2 / (r_c^2 n_it) < 1 for any radius up to
        // the first: k is clamped to 1, as the probe would find.
        let bit = hot_bit(key);
        if area_ratio(radius, self.inv_cell) <= self.hot_area_ratio
            && self.hot[bit >> 6] & (1 << (bit & 63)) == 0
        {
            return Some(1.0);
        }
        Some(self.probe(s, radius, light_paths))
    }

    /// 1 / k(x) from the block's counts, `s` being x in cell units less one half.
    fn probe(&self, s: Vec3, radius: f32, light_paths: f32) -> f32 {
        // The cell whose centre is the lower corner of the 2 x 2 x 2 block around x.
        let base = s.floor();
        let (mut weighted, mut weights) = (0.0f32, 0.0f32);
        let key = block_of(s);
        if let Some(counts) = self.blocks.get(&key) {
            for (&count, [dx, dy, dz]) in counts.iter().zip(BLOCK) {
                if count == 0 {
                    continue;
                }
                let corner = base + Vec3::new(dx as f32, dy as f32, dz as f32);
                let w = (-(s - corner).length()).exp();
                weighted += w * count as f32;
                weights += w;
            }
        }
        let q = if weights > 0.0 {
            (weighted / weights).max(1.0)
        } else {
            1.0
        };
        let area_ratio = area_ratio(radius, self.inv_cell);
        let k = (q * area_ratio / self.iterations as f32).clamp(1.0, light_paths.max(1.0));
        1.0 / k
    }

    /// Occupied cells, and the bytes the counters and the marks take.
    pub fn statistics(&self) -> Vec<(String, String)> {
        let bytes = self.counts.capacity() * (std::mem::size_of::<(Cell, u32)>() + 1)
            + self.blocks.capacity() * (std::mem::size_of::<(Cell, [u32; 8])>() + 1)
            + self.hot.len() * std::mem::size_of::<u64>();
        vec![
            ("density_map_cells".into(), self.counts.len().to_string()),
            ("density_map_bytes".into(), bytes.to_string()),
            ("density_map_cell_size".into(), self.cell_size.to_string()),
            ("density_map_iterations".into(), self.iterations.to_string()),
        ]
    }
}

fn cell_of(p: Vec3, inv_cell: f32) -> Cell {
    let c = (p * inv_cell).floor();
    [c.x as i32, c.y as i32, c.z as i32]
}

/// The key of the block around a point at `s` (cell units less one half).
fn block_of(s: Vec3) -> Cell {
    let base = s.floor();
    [base.x as i32, base.y as i32, base.z as i32]
}

/// pi r^2 / r_c^2: the merge disc's area in cell areas.
fn area_ratio(radius: f32, inv_cell: f32) -> f32 {
    std::f32::consts::PI * radius * radius * inv_cell * inv_cell
}

fn hot_bit(key: Cell) -> usize {
    let [x, y, z] = key.map(|c| u64::from(c as u32));
    let h = (x.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ y.wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ z.wrapping_mul(0x1656_67B1_9E37_79F9))
    .wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    (h >> (64 - HOT_BITS)) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_map_has_no_density() {
        let map = DensityMap::new(0.01, 50);
        assert_eq!(map.inv_expected_count(Vec3::ZERO, 0.01, 100.0), None);
    }

    /// Vertices spread evenly over a plane at d per cell area give k = d pi r^2 / r_c^2.
    #[test]
    fn uniform_plane_gives_its_density() {
        let radius = 0.05;
        let mut map = DensityMap::new(radius, 50);
        let cell = 2.0 * radius;
        let per_side = 40;
        let per_cell = 16;
        let step = cell / 4.0;
        let mut points = Vec::new();
        for i in 0..per_side * 4 {
            for j in 0..per_side * 4 {
                points.push(Vec3::new(
                    (i as f32 + 0.5) * step,
                    0.5 * cell,
                    (j as f32 + 0.5) * step,
                ));
            }
        }
        map.insert(&points);
        let x = Vec3::new(20.3 * cell, 0.5 * cell, 19.7 * cell);
        let inv_k = map.inv_expected_count(x, radius, 1e9).unwrap();
        let expected = per_cell as f32 * std::f32::consts::PI * radius * radius / (cell * cell);
        assert!(
            ((1.0 / inv_k) / expected - 1.0).abs() < 1e-4,
            "k = {}, expected {expected}",
            1.0 / inv_k
        );
    }

    /// The unmarked-block shortcut answers what the probe answers, bit for bit, over points
    /// in empty, sparse and dense regions and radii from the first down.
    #[test]
    fn shortcut_matches_the_probe() {
        let radius = 0.02;
        let mut map = DensityMap::new(radius, 50);
        let mut seed = 1u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for _ in 0..3 {
            // A sparse plane and a dense spot on it.
            let mut points: Vec<Vec3> = (0..20_000)
                .map(|_| Vec3::new(next() * 4.0, 0.5, next() * 4.0))
                .collect();
            points.extend(
                (0..20_000).map(|_| Vec3::new(1.0 + next() * 0.1, 0.5, 1.0 + next() * 0.1)),
            );
            map.insert(&points);
        }
        let (mut skipped, mut probed) = (0, 0);
        for i in 0..200_000 {
            let x = Vec3::new(next() * 4.4 - 0.2, 0.45 + next() * 0.1, next() * 4.4 - 0.2);
            let r = radius * [1.0, 0.9, 0.5, 0.1][i % 4];
            let fast = map.inv_expected_count(x, r, 1e6).unwrap();
            let s = x * map.inv_cell - Vec3::splat(0.5);
            assert_eq!(
                fast.to_bits(),
                map.probe(s, r, 1e6).to_bits(),
                "at {x} r {r}"
            );
            let bit = hot_bit(block_of(s));
            if map.hot[bit >> 6] & (1 << (bit & 63)) == 0 {
                skipped += 1;
            } else {
                probed += 1;
            }
        }
        // Both paths taken, so the comparison covers the shortcut.
        assert!(
            skipped > 1000 && probed > 1000,
            "{skipped} skipped, {probed} probed"
        );
    }

    #[test]
    fn counts_do_not_depend_on_order() {
        let points: Vec<Vec3> = (0..50_000)
            .map(|i| {
                let t = i as f32 * 0.001;
                Vec3::new(t.sin(), (3.0 * t).cos(), t.fract())
            })
            .collect();
        let mut reversed = points.clone();
        reversed.reverse();
        let (mut a, mut b) = (DensityMap::new(0.01, 50), DensityMap::new(0.01, 50));
        a.insert(&points);
        b.insert(&reversed);
        assert_eq!(a.counts, b.counts);
    }
}
