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

type Cell = (i32, i32, i32);

pub struct HashGrid {
    radius: f32,
    radius_sq: f32,
    inv_cell: f32,
    /// Point positions in cell order, and their indices in the input.
    positions: Vec<Vec3>,
    indices: Vec<u32>,
    /// Cell -> range of `positions` covering the cell and its x-neighbours.
    triplets: HashMap<Cell, (u32, u32), FxBuildHasher>,
}

impl HashGrid {
    /// Builds the grid over `points` for queries of the given radius (> 0).
    pub fn build(points: &[Vec3], radius: f32) -> Self {
        let inv_cell = 1.0 / radius;
        let mut order: Vec<(Cell, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, &p)| (cell_of(p, inv_cell), i as u32))
            .collect();
        // (z, y, x) order keeps the cells of one x-row contiguous.
        order.par_sort_unstable_by_key(|&((x, y, z), i)| (z, y, x, i));
        let positions: Vec<Vec3> = order.par_iter().map(|&(_, i)| points[i as usize]).collect();
        let indices: Vec<u32> = order.iter().map(|&(_, i)| i).collect();
        let mut triplets: HashMap<Cell, (u32, u32), FxBuildHasher> =
            HashMap::with_capacity_and_hasher(order.len().min(1 << 22), FxBuildHasher);
        let mut begin = 0usize;
        while begin < order.len() {
            let cell = order[begin].0;
            let mut end = begin + 1;
            while end < order.len() && order[end].0 == cell {
                end += 1;
            }
            // The cell's own points belong to the triplets centred on it and on both x-neighbours;
            // sorted order makes each triplet's union of ranges one contiguous range.
            for dx in -1..=1 {
                let key = (cell.0.saturating_add(dx), cell.1, cell.2);
                let range = triplets.entry(key).or_insert((begin as u32, end as u32));
                range.0 = range.0.min(begin as u32);
                range.1 = range.1.max(end as u32);
            }
            begin = end;
        }
        HashGrid {
            radius,
            radius_sq: radius * radius,
            inv_cell,
            positions,
            indices,
            triplets,
        }
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Calls `visit(index, distance_squared)` for every point within the radius of `q`
    /// (distance <= radius), with `index` into the `points` the grid was built from.
    #[inline]
    pub fn query(&self, q: Vec3, mut visit: impl FnMut(usize, f32)) {
        let (x, y, z) = cell_of(q, self.inv_cell);
        for dz in -1..=1 {
            for dy in -1..=1 {
                let key = (x, y.saturating_add(dy), z.saturating_add(dz));
                let Some(&(begin, end)) = self.triplets.get(&key) else {
                    continue;
                };
                let (begin, end) = (begin as usize, end as usize);
                for (offset, p) in self.positions[begin..end].iter().enumerate() {
                    let d2 = (*p - q).length_squared();
                    if d2 <= self.radius_sq {
                        visit(self.indices[begin + offset] as usize, d2);
                    }
                }
            }
        }
    }
}

/// Cell of a point (000 eq. 2.87), floored so negative coordinates are right, and clamped so
/// far-away points cannot overflow.
#[inline]
fn cell_of(p: Vec3, inv_cell: f32) -> Cell {
    let c = (p * inv_cell).floor();
    let clamp = |v: f32| v.clamp(i32::MIN as f32 / 2.0, i32::MAX as f32 / 2.0) as i32;
    (clamp(c.x), clamp(c.y), clamp(c.z))
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
