//! The triplet-cell hash grid of 000 sec. 2.4.9: fixed-radius queries over light vertices.
//!
//! Points are sorted by cell (z, y, x) with cells of side r (000 eq. 2.87), so the points of one
//! cell, and of three cells adjacent along x, are contiguous. The hash map stores for each cell
//! the range spanning the cell and its two x-neighbours, so a query visits 3 x 3 ranges (9
//! lookups) instead of 27 cells, in long streaming runs.

use glam::Vec3;
use hashbrown::HashMap;
use rayon::prelude::*;
use rustc_hash::FxBuildHasher;

/// A cell's (z, y, x) coordinates, each offset to unsigned, in 32 bits apiece: ordering the
/// keys orders the cells (z, y, x), and a key with the point's index in the low 32 bits sorts as
/// one integer.
type CellKey = u128;

const X: CellKey = 1;
const Y: CellKey = 1 << 32;
const Z: CellKey = 1 << 64;

pub struct HashGrid {
    radius: f32,
    radius_sq: f32,
    inv_cell: f32,
    /// Point coordinates in cell order, one array per axis so a range streams through
    /// distance tests in SIMD lanes, and the points' indices in the input.
    xs: Vec<f32>,
    ys: Vec<f32>,
    zs: Vec<f32>,
    indices: Vec<u32>,
    /// Cell -> range of points covering the cell and its x-neighbours.
    triplets: HashMap<CellKey, (u32, u32), FxBuildHasher>,
}

impl HashGrid {
    /// Builds the grid over `points` for queries of the given radius (> 0).
    pub fn build(points: &[Vec3], radius: f32) -> Self {
        assert!(points.len() <= u32::MAX as usize, "at most u32::MAX points");
        let inv_cell = 1.0 / radius;
        let mut keys: Vec<u128> = points
            .par_iter()
            .enumerate()
            .map(|(i, &p)| cell_key(p, inv_cell) << 32 | i as u128)
            .collect();
        // Unique keys make the order, and so the order of query results, independent of threads.
        keys.par_sort_unstable();
        // One pass gathers every point once (each in its own cache line, in random order).
        const CHUNK: usize = 1 << 12;
        let n = points.len();
        let (mut xs, mut ys, mut zs) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut indices = vec![0; n];
        keys.par_chunks(CHUNK)
            .zip(xs.par_chunks_mut(CHUNK))
            .zip(ys.par_chunks_mut(CHUNK))
            .zip(zs.par_chunks_mut(CHUNK))
            .zip(indices.par_chunks_mut(CHUNK))
            .for_each(|((((keys, xs), ys), zs), indices)| {
                for (i, &key) in keys.iter().enumerate() {
                    let index = key as u32;
                    let p = points[index as usize];
                    (xs[i], ys[i], zs[i], indices[i]) = (p.x, p.y, p.z, index);
                }
            });

        // Cells with the end of their range, in order.
        let mut cells: Vec<(CellKey, u32)> = Vec::new();
        for (i, pair) in keys.windows(2).enumerate() {
            if pair[0] >> 32 != pair[1] >> 32 {
                cells.push((pair[0] >> 32, i as u32 + 1));
            }
        }
        if let Some(&last) = keys.last() {
            cells.push((last >> 32, keys.len() as u32));
        }
        drop(keys);
        // Exact capacity: a cell adds the triplet keys its row predecessor did not (x is the low
        // 32 bits of a cell key, so a gap below 3 within a row shares keys).
        let key_count: usize = cells
            .iter()
            .zip(std::iter::once(None).chain(cells.iter().map(Some)))
            .map(|(&(cell, _), previous)| match previous {
                Some(&(previous, _)) if cell >> 32 == previous >> 32 => {
                    (cell - previous).min(3) as usize
                }
                _ => 3,
            })
            .sum();
        let mut triplets: HashMap<CellKey, (u32, u32), FxBuildHasher> =
            HashMap::with_capacity_and_hasher(key_count, FxBuildHasher);
        let mut begin = 0;
        for (cell, end) in cells {
            // The cell's own points belong to the triplets centred on it and on both x-neighbours;
            // sorted order makes each triplet's union of ranges one contiguous range.
            for key in [cell - X, cell, cell + X] {
                let range = triplets.entry(key).or_insert((begin, end));
                range.0 = range.0.min(begin);
                range.1 = range.1.max(end);
            }
            begin = end;
        }
        debug_assert_eq!(triplets.len(), key_count);
        HashGrid {
            radius,
            radius_sq: radius * radius,
            inv_cell,
            xs,
            ys,
            zs,
            indices,
            triplets,
        }
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    pub fn len(&self) -> usize {
        self.indices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The grid's order: for each slot, the index of its point in the `points` the grid was
    /// built from. Data a query's caller reads per point, laid out in this order and read by
    /// [`Self::query_slots`], streams through the cache instead of being fetched at random.
    pub fn indices(&self) -> &[u32] {
        &self.indices
    }

    /// Calls `visit(index, distance_squared)` for every point within the radius of `q`
    /// (distance <= radius), with `index` into the `points` the grid was built from.
    #[inline]
    pub fn query(&self, q: Vec3, mut visit: impl FnMut(usize, f32)) {
        self.query_slots(q, |slot, d2| visit(self.indices[slot] as usize, d2));
    }

    /// [`Self::query`] that names each point by its slot in [`Self::indices`], in the same
    /// order.
    #[inline]
    pub fn query_slots(&self, q: Vec3, mut visit: impl FnMut(usize, f32)) {
        let centre = cell_key(q, self.inv_cell);
        // All lookups first: their cache misses, and those of the ranges' first points, overlap
        // instead of each waiting for the previous range's scan.
        let ranges = [
            centre - Z - Y,
            centre - Z,
            centre - Z + Y,
            centre - Y,
            centre,
            centre + Y,
            centre + Z - Y,
            centre + Z,
            centre + Z + Y,
        ]
        .map(|row| {
            self.triplets
                .get(&row)
                .map_or(0..0, |&(b, e)| b as usize..e as usize)
        });
        for range in ranges {
            self.scan(range, q, &mut visit);
        }
    }

    /// Tests a range of points against the query sphere. Distances are computed a block at a
    /// time (vectorised) into a bit mask of the points inside, so no branch depends on whether
    /// one point is inside: with spheres half full it would mispredict half the time.
    #[inline]
    fn scan(&self, range: std::ops::Range<usize>, q: Vec3, visit: &mut impl FnMut(usize, f32)) {
        // One bit per point of a block in a u64.
        const BLOCK: usize = 64;
        let xs = &self.xs[range.clone()];
        let ys = &self.ys[range.clone()];
        let zs = &self.zs[range.clone()];
        for (block, ((xs, ys), zs)) in xs
            .chunks(BLOCK)
            .zip(ys.chunks(BLOCK))
            .zip(zs.chunks(BLOCK))
            .enumerate()
        {
            let first = range.start + block * BLOCK;
            let mut d2 = [0.0f32; BLOCK];
            for (((d2, &x), &y), &z) in d2.iter_mut().zip(xs).zip(ys).zip(zs) {
                let (dx, dy, dz) = (x - q.x, y - q.y, z - q.z);
                *d2 = dx * dx + dy * dy + dz * dz;
            }
            let mut inside = 0u64;
            for (j, &d2) in d2.iter().enumerate().take(xs.len()) {
                inside |= u64::from(d2 <= self.radius_sq) << j;
            }
            while inside != 0 {
                let j = inside.trailing_zeros() as usize;
                inside &= inside - 1;
                visit(first + j, d2[j]);
            }
        }
    }
}

/// Key of the cell of a point (000 eq. 2.87), floored so negative coordinates are right, and
/// clamped so far-away points cannot overflow the key or its neighbours'.
#[inline]
fn cell_key(p: Vec3, inv_cell: f32) -> CellKey {
    const LIMIT: f32 = (1u32 << 30) as f32;
    let axis = |v: f32| {
        let v = v.clamp(-LIMIT, LIMIT);
        // Floor by truncation and correction: without SSE4.1, f32::floor is a library call.
        let truncated = v as i32;
        let floor = truncated - i32::from(truncated as f32 > v);
        (floor as u32 ^ (1 << 31)) as CellKey
    };
    let c = p * inv_cell;
    axis(c.z) * Z + axis(c.y) * Y + axis(c.x) * X
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    fn brute_force(points: &[Vec3], q: Vec3, r: f32) -> Vec<usize> {
        (0..points.len())
            .filter(|&i| (points[i] - q).length_squared() <= r * r)
            .collect()
    }

    fn check(points: &[Vec3], queries: &[Vec3], r: f32) {
        let grid = HashGrid::build(points, r);
        for &q in queries {
            let mut found = Vec::new();
            grid.query(q, |i, d2| {
                assert!((d2 - (points[i] - q).length_squared()).abs() <= 1e-6 * d2.max(1e-30));
                found.push(i);
            });
            found.sort_unstable();
            assert_eq!(found, brute_force(points, q, r), "query {q} radius {r}");
        }
    }

    fn random_points(rng: &mut Rng, n: usize, kind: usize) -> Vec<Vec3> {
        (0..n)
            .map(|_| {
                let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                match kind {
                    // Uniform in a box across the origin.
                    0 => u * 4.0 - Vec3::splat(2.0),
                    // Clustered on three axis planes, as light vertices on walls are.
                    1 => {
                        let mut p = u * 2.0 - Vec3::ONE;
                        let axis = (rng.next_u32() % 3) as usize;
                        p[axis] = [-1.0, 0.0, 0.5][axis];
                        p
                    }
                    // Far from the origin, all coordinates negative.
                    _ => u * 0.5 - Vec3::splat(1000.0),
                }
            })
            .collect()
    }

    #[test]
    fn queries_match_brute_force() {
        let mut rng = Rng::for_sample(3, 0, 0, Stream::Eye);
        for kind in 0..3 {
            let points = random_points(&mut rng, 3000, kind);
            let mut queries = random_points(&mut rng, 200, kind);
            queries.extend(points.iter().take(100));
            for r in [1e-4f32, 1e-3, 0.01, 0.05, 0.2, 1.0] {
                // Queries exactly on cell faces and corners.
                let mut qs = queries.clone();
                qs.extend([
                    Vec3::ZERO,
                    Vec3::splat(r),
                    Vec3::new(-r, 2.0 * r, 0.0),
                    Vec3::splat(-1000.0),
                ]);
                check(&points, &qs, r);
            }
        }
    }

    #[test]
    fn points_on_cell_faces() {
        let r = 0.25;
        let points: Vec<Vec3> = (-8..=8)
            .flat_map(|i| (-2..=2).map(move |j| Vec3::new(i as f32 * r, j as f32 * r, 0.5 * r)))
            .collect();
        let queries: Vec<Vec3> = points
            .iter()
            .map(|p| *p + Vec3::new(0.0, 0.0, 0.25 * r))
            .collect();
        check(&points, &queries, r);
    }

    #[test]
    fn empty_and_single() {
        check(&[], &[Vec3::ZERO, Vec3::ONE], 0.1);
        check(
            &[Vec3::new(-0.05, 0.0, 0.0)],
            &[Vec3::ZERO, Vec3::new(0.049, 0.0, 0.0), Vec3::X],
            0.1,
        );
    }
}
