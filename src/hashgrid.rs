//! The run-of-cells hash grid of 000 sec. 2.4.9: fixed-radius queries over light vertices.
//!
//! Points are sorted by cell (z, y, x) (000 eq. 2.87), so the points of one cell, and of cells
//! adjacent along x, are contiguous. A hash table stores for each cell the range spanning a run
//! of cells along x starting there, so a query reads one range per row of cells it touches. The
//! thesis's runs are triplets of cells of side r: 3 x 3 ranges (9 lookups instead of 27 cells).
//! Pairs of cells of side 2r cover the same sphere in 2 x 2 ranges, 4 lookups into a table a
//! quarter as long, at the price of testing 16/9 as many points on a surface: on the sparse
//! light vertices of a render (about ten neighbours per query) the lookups, cache misses in a
//! table of tens of megabytes, cost more than the tests, on dense sets the tests do. A rebuild
//! takes pairs unless the points crowd their cells ([`DENSE_PAIR_CELL`]).
//!
//! Cell coordinates are taken relative to the points' lowest cell and packed into one u64 key
//! (x lowest), so the sort is a radix sort over only the key bits in use and the table is a flat
//! open-addressing array of (key, range) slots: one multiply to hash, one u64 compare to match.
//! The cells are those of the world grid (floor(p / side)), whatever the points' extent, so the
//! order of query results depends only on the points, never on threads.

use crate::prefetch::prefetch;
use glam::{Vec3, Vec3A, Vec4};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Cells further than this from the lowest cell along an axis merge into the last one (queries
/// there stay exact, they only test more points), so three padded coordinates fit 63 bits.
const SPAN_LIMIT: i64 = (1 << 21) - 8;
/// Cell coordinates before the span limit, clamped so far-away points cannot overflow.
const CELL_LIMIT: f32 = (1u32 << 30) as f32;
/// Bits of one radix-sort digit: the 2^12 counters of a pass (16 KiB) fit L1.
const DIGIT_BITS: u32 = 12;
/// Items per parallel chunk: points in the key and gather passes, cells in the table fill.
const CHUNK: usize = 1 << 12;
/// Most points in a batch of [`HashGrid::query_batches`]: one bit each in [`kept`]'s mask.
pub const QUERY_BATCH: usize = 32;
const _: () = assert!(QUERY_BATCH <= u64::BITS as usize);
/// Fewest items per part of a parallel radix-sort pass: smaller sets sort on one thread.
const SORT_PART_MIN: usize = 1 << 15;
/// Points per occupied cell of side 2r beyond which a rebuild takes triplets: there a query
/// finds about 200 neighbours, where the two layouts answer about as fast (`cargo bench --bench
/// hashgrid`).
pub const DENSE_PAIR_CELL: usize = 256;
/// Points the density estimate of a rebuild looks at, at most about.
const DENSITY_SAMPLE: usize = 1 << 12;

/// How the table's ranges run along x, which sets the cells' side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellRuns {
    /// Cells of side 2r, a range spanning a cell and its +x neighbour: 2 x 2 lookups a query.
    #[default]
    Pairs,
    /// Cells of side r, a range spanning a cell and its two +x neighbours (000 sec. 2.4.9):
    /// 3 x 3 lookups a query.
    Triplets,
}

impl CellRuns {
    pub const ALL: [CellRuns; 2] = [CellRuns::Pairs, CellRuns::Triplets];

    /// Rows of runs a query reads: `len` x `len`.
    const fn rows(self) -> usize {
        (self.len() * self.len()) as usize
    }

    /// Cells in one run.
    const fn len(self) -> i64 {
        match self {
            CellRuns::Pairs => 2,
            CellRuns::Triplets => 3,
        }
    }

    /// A cell side such that a sphere of radius r spans at most `len` cells per axis (but
    /// when rounding puts its centre on a face).
    fn cell_side(self, radius: f32) -> f32 {
        2.0 * radius / (self.len() - 1) as f32
    }
}

/// One table slot: a run's key (`EMPTY` when free) and the range of its points, begin in the
/// high half. Atomic so the runs are inserted by all threads at once: the table is tens of
/// megabytes on large sparse sets, and one thread inserting alone waits on a cache miss per
/// run while the others idle. Where a key lands depends on the threads; what a lookup
/// returns does not. Relaxed order suffices: the fill has ended (rayon joins its threads)
/// before any query starts.
struct Slot {
    key: AtomicU64,
    range: AtomicU64,
}

/// No valid key: keys are below 2^63.
const EMPTY: u64 = u64::MAX;

impl Slot {
    fn empty() -> Self {
        Slot {
            key: AtomicU64::new(EMPTY),
            range: AtomicU64::new(0),
        }
    }

    /// The word a slot stores for the range `begin..end`.
    fn pack_range(begin: u32, end: u32) -> u64 {
        u64::from(begin) << 32 | u64::from(end)
    }

    /// The range a slot's `range` word holds.
    #[inline]
    fn unpack_range(word: u64) -> std::ops::Range<usize> {
        (word >> 32) as usize..word as u32 as usize
    }
}

/// Points in one [`Group`].
const GROUP: usize = 4;
const _: () = assert!(CHUNK.is_multiple_of(GROUP));

/// Four consecutive points of the grid's order: their coordinates per axis, so the four are
/// tested at once in SIMD lanes, and their indices in the input. One cache line: the one or
/// two points of a range on a sparse set come in one fetch, not one per axis.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Group {
    x: [f32; GROUP],
    y: [f32; GROUP],
    z: [f32; GROUP],
    index: [u32; GROUP],
}

impl Group {
    /// No point: a NaN coordinate is inside no sphere.
    const EMPTY: Group = Group {
        x: [f32::NAN; GROUP],
        y: [f32::NAN; GROUP],
        z: [f32::NAN; GROUP],
        index: [u32::MAX; GROUP],
    };

    /// Puts the point at `position`, the input's `index`, in `lane`.
    #[inline]
    fn set(&mut self, lane: usize, [x, y, z]: [f32; 3], index: u32) {
        (self.x[lane], self.y[lane], self.z[lane]) = (x, y, z);
        self.index[lane] = index;
    }
}

/// Points in an order of their own (slots), four to a cache line: what a grid's ranges of
/// slots are scanned in.
#[derive(Default)]
pub struct GroupedPoints {
    groups: Vec<Group>,
    len: usize,
}

impl GroupedPoints {
    pub fn clear(&mut self) {
        self.reset(0);
    }

    /// `len` slots for [`Self::set`] to fill, every one of them. The previous points' groups
    /// are left as they are, not cleared in a pass of their own, as every slot is overwritten;
    /// the last group is emptied, so its lanes past `len` hold no stale point.
    pub fn reset(&mut self, len: usize) {
        self.groups.resize(len.div_ceil(GROUP), Group::EMPTY);
        if let Some(last) = self.groups.last_mut() {
            *last = Group::EMPTY;
        }
        self.len = len;
    }

    /// Puts point `p`, the input's `index`, in `slot`.
    pub fn set(&mut self, slot: usize, p: Vec3, index: u32) {
        self.groups[slot / GROUP].set(slot % GROUP, p.to_array(), index);
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The input's index of the point in `slot`.
    #[inline]
    pub fn index_of(&self, slot: usize) -> u32 {
        self.groups[slot / GROUP].index[slot % GROUP]
    }

    /// Prefetches the groups of the slots `range`, a cache line each.
    #[inline]
    pub fn prefetch(&self, range: std::ops::Range<usize>) {
        if !range.is_empty() {
            self.groups[range.start / GROUP..=(range.end - 1) / GROUP]
                .iter()
                .for_each(prefetch);
        }
    }

    /// Calls `visit(slot, distance_squared)` for the points of the slots `range` within
    /// distance sqrt(`radius_sq`) of `q`, in slot order. Sixteen groups (64 points) at a time,
    /// four points to a SIMD operation, into a bit mask of the points inside, so no branch
    /// depends on whether one point is inside: with spheres half full it would mispredict half
    /// the time.
    #[inline]
    pub fn scan(
        &self,
        range: std::ops::Range<usize>,
        q: Vec3,
        radius_sq: f32,
        visit: &mut impl FnMut(usize, f32),
    ) {
        // Groups whose inside bits fill a u64.
        const BLOCK: usize = u64::BITS as usize / GROUP;
        if range.is_empty() {
            return;
        }
        let first = range.start / GROUP;
        let groups = &self.groups[first..(range.end - 1) / GROUP + 1];
        let (qx, qy, qz) = (Vec4::splat(q.x), Vec4::splat(q.y), Vec4::splat(q.z));
        let radius_sq = Vec4::splat(radius_sq);
        for (block, groups) in groups.chunks(BLOCK).enumerate() {
            let base = (first + block * BLOCK) * GROUP;
            let mut d2 = [Vec4::ZERO; BLOCK];
            let mut inside = 0u64;
            for (j, (group, d2)) in groups.iter().zip(&mut d2).enumerate() {
                let (dx, dy, dz) = (
                    Vec4::from_array(group.x) - qx,
                    Vec4::from_array(group.y) - qy,
                    Vec4::from_array(group.z) - qz,
                );
                *d2 = dx * dx + dy * dy + dz * dz;
                inside |= u64::from(d2.cmple(radius_sq).bitmask()) << (GROUP * j);
            }
            // Only the range's points: from its start in the first group to its end in the
            // last.
            let from = range.start.saturating_sub(base);
            let to = (range.end - base).min(u64::BITS as usize);
            inside &= (u64::MAX >> (u64::BITS as usize - to)) & (u64::MAX << from);
            while inside != 0 {
                let lane = inside.trailing_zeros() as usize;
                inside &= inside - 1;
                visit(base + lane, d2[lane / GROUP][lane % GROUP]);
            }
        }
    }
}

/// The sphere a query takes the points of.
#[derive(Clone, Copy, Debug, Default)]
pub struct Within {
    radius_sq: f32,
    /// How far from a query its cells are taken: the radius and a margin for rounding.
    reach: f32,
}

impl Within {
    /// The points at distance <= `radius` (> 0).
    pub fn radius(radius: f32) -> Self {
        Within {
            radius_sq: radius * radius,
            reach: radius * (1.0 + 1e-6),
        }
    }
}

/// Rows of runs a query reads at most: triplets' 3 x 3.
const MAX_ROWS: usize = 9;

/// A query whose table slots are being fetched ([`HashGrid::begin_query`]), for
/// [`HashGrid::locate`] to read.
#[derive(Clone, Copy, Debug)]
pub struct BegunQuery {
    q: Vec3,
    within: Within,
    /// Per row, its run's key.
    keys: [u64; MAX_ROWS],
    rows: Rows,
}

/// Which cells a begun query reads.
#[derive(Clone, Copy, Debug)]
enum Rows {
    /// None: the sphere is off the points' cells.
    Nothing,
    /// The sphere touches one cell more along an axis: disjoint runs per row, looked up
    /// when scanned.
    Irregular,
    /// The runs x runs rows of runs, along y then z, their slots prefetched.
    Probed(CellRuns),
}

/// A query whose ranges are known and whose points are being fetched ([`HashGrid::locate`]),
/// for [`HashGrid::query_kept_slot_batches_located`] to scan.
#[derive(Clone, Debug)]
pub struct LocatedQuery {
    q: Vec3,
    within: Within,
    /// `None` for the irregular rows, looked up when scanned; otherwise the ranges of the rows.
    ranges: Option<([std::ops::Range<u32>; MAX_ROWS], usize)>,
}

/// A grid over no points; [`HashGrid::rebuild`] fills it.
#[derive(Default)]
pub struct HashGrid {
    radius: f32,
    /// The queries of the grid's own radius.
    within: Within,
    runs: CellRuns,
    inv_cell: f32,
    /// The points' lowest cell, per axis.
    low: [i64; 3],
    /// The highest cell offset from `low` in use (at most `SPAN_LIMIT`), per axis.
    span: [i64; 3],
    /// `low` and `span` as floats, for [`HashGrid::key_of`].
    low_f: Vec3A,
    span_f: Vec3A,
    /// Key steps of one cell along y and z (x's is 1).
    stride_y: u64,
    stride_z: u64,
    /// The points in cell order.
    points: GroupedPoints,
    /// Key of a run's first cell -> range of the run's points; linear probing, a power of
    /// two long.
    table: Vec<Slot>,
    shift: u32,
    /// The sort's and the table build's buffers, kept from one rebuild to the next: points
    /// with their (key, index) pairs packed into one integer, u64 while keys fit 32 bits, u128
    /// beyond.
    narrow: [Vec<Record<u64>>; 2],
    wide: [Vec<Record<u128>>; 2],
    /// Distinct cells in order, each with the end of its range.
    cells: Vec<(u64, u32)>,
    /// The pair-cell keys of the density estimate's sample.
    sample_keys: Vec<u64>,
    /// The sort's digit counts, then the number of cells ending in each chunk of points.
    histograms: Vec<u32>,
}

impl HashGrid {
    /// Builds the grid over `points` for queries of the given radius (> 0), the same grid as
    /// [`Self::rebuild`]'s, in less memory: the (key, index) pairs are sorted in place, 8 bytes
    /// a point (16 where cell keys take more than 32 bits) instead of the two 24-byte buffers
    /// of the radix sort, and the positions are fetched through the indices afterwards. What
    /// one-stage merging builds over the light vertices of an iteration, the largest set it
    /// holds; a one-off grid keeps only what queries read.
    pub fn build(points: &[Vec3], radius: f32) -> Self {
        let mut grid = HashGrid::default();
        let bounds = bounds(points);
        let runs = if grid.crowded(points, bounds, radius) {
            CellRuns::Triplets
        } else {
            CellRuns::Pairs
        };
        grid.set_cells(radius, runs);
        if !points.is_empty() {
            assert!(
                points.len() < u32::MAX as usize,
                "fewer than u32::MAX points"
            );
            if grid.fit_key_space(bounds) <= 32 {
                grid.sort_in_place::<u64>(points);
            } else {
                grid.sort_in_place::<u128>(points);
            }
        }
        grid.fill_table();
        grid.cells = Vec::new();
        grid.histograms = Vec::new();
        grid.sample_keys = Vec::new();
        grid
    }

    /// [`Self::arrange`] with the (key, index) pairs sorted in place: pairs are distinct, so
    /// any sort gives the stable sort's order.
    fn sort_in_place<T: Item>(&mut self, points: &[Vec3]) {
        let mut items: Vec<T> = Vec::with_capacity(points.len());
        let grid = &*self;
        items.par_extend(
            points
                .par_iter()
                .enumerate()
                .map(|(i, &p)| T::new(grid.key_of(p), i as u32)),
        );
        items.par_sort_unstable();
        let items = &items;
        self.place_sorted(
            points.len(),
            |i| items[i].key(),
            |i| {
                let index = items[i].index();
                (points[index as usize].to_array(), index)
            },
        );
    }

    /// Rebuilds the grid over `points` for the given radius (> 0), reusing its buffers: once
    /// they have grown to the largest point set, a rebuild allocates only the lists of output
    /// slices its parallel passes write to (one entry per chunk of points, or per thread and
    /// sort digit), nothing per point. Pairs of cells, or triplets where the points crowd
    /// them ([`DENSE_PAIR_CELL`]).
    pub fn rebuild(&mut self, points: &[Vec3], radius: f32) {
        let bounds = bounds(points);
        let runs = if self.crowded(points, bounds, radius) {
            CellRuns::Triplets
        } else {
            CellRuns::Pairs
        };
        self.arrange_as(points, bounds, radius, runs);
        self.fill_table();
    }

    /// [`Self::rebuild`] with the given runs, whatever the points' density.
    pub fn rebuild_as(&mut self, points: &[Vec3], radius: f32, runs: CellRuns) {
        self.arrange_as(points, bounds(points), radius, runs);
        self.fill_table();
    }

    /// The runs of the last rebuild.
    pub fn runs(&self) -> CellRuns {
        self.runs
    }

    /// Whether more than [`DENSE_PAIR_CELL`] points share an occupied cell of side 2r on
    /// average, judged by every k-th point (about [`DENSITY_SAMPLE`] of them), so the points
    /// are sorted once: the sample, thinned from cells of c points each, holds c / k points
    /// per occupied cell over the chance 1 - e^(-c / k) that a cell keeps one (Poisson
    /// thinning; exact for k = 1). Deterministic: the sample is taken in the input's order.
    fn crowded(&mut self, points: &[Vec3], bounds: (Vec3, Vec3), radius: f32) -> bool {
        if points.is_empty() {
            return false;
        }
        self.set_cells(radius, CellRuns::Pairs);
        self.fit_key_space(bounds);
        let step = (points.len() / DENSITY_SAMPLE).max(1);
        let mut keys = std::mem::take(&mut self.sample_keys);
        keys.clear();
        keys.extend(points.iter().step_by(step).map(|&p| self.key_of(p)));
        keys.sort_unstable();
        let sampled = keys.len();
        keys.dedup();
        let per_cell = DENSE_PAIR_CELL as f64 / step as f64;
        let threshold = per_cell / (1.0 - (-per_cell).exp());
        let crowded = sampled as f64 > threshold * keys.len() as f64;
        self.sample_keys = keys;
        crowded
    }

    /// The radius and cell side of the given runs.
    fn set_cells(&mut self, radius: f32, runs: CellRuns) {
        self.radius = radius;
        self.within = Within::radius(radius);
        self.runs = runs;
        self.inv_cell = 1.0 / runs.cell_side(radius);
    }

    /// Sorts the points into cells for the given runs and finds the distinct cells.
    fn arrange_as(&mut self, points: &[Vec3], bounds: (Vec3, Vec3), radius: f32, runs: CellRuns) {
        assert!(
            points.len() < u32::MAX as usize,
            "fewer than u32::MAX points"
        );
        self.set_cells(radius, runs);
        self.points.clear();
        self.cells.clear();
        if points.is_empty() {
            return;
        }
        let bits = self.fit_key_space(bounds);
        if bits <= 32 {
            let mut items = std::mem::take(&mut self.narrow);
            self.arrange(points, &mut items, bits);
            self.narrow = items;
        } else {
            let mut items = std::mem::take(&mut self.wide);
            self.arrange(points, &mut items, bits);
            self.wide = items;
        }
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The index in the `points` the grid was built from of the point in `slot` (slots run
    /// in the grid's order, 0 .. [`Self::len`]).
    #[inline]
    pub fn index_of(&self, slot: usize) -> u32 {
        self.points.index_of(slot)
    }

    /// [`Self::index_of`] of every slot, in order. Data a query's caller reads per point, laid
    /// out in this order and read by [`Self::query_slots`], streams through the cache instead
    /// of being fetched at random.
    pub fn indices(&self) -> impl IndexedParallelIterator<Item = u32> + '_ {
        (0..self.len())
            .into_par_iter()
            .map(|slot| self.index_of(slot))
    }

    /// Calls `visit(index, distance_squared)` for every point within the radius of `q`
    /// (distance <= radius), with `index` into the `points` the grid was built from, in the
    /// order of rows (z, y), then cells along x, then indices: an order of the results alone.
    #[inline]
    pub fn query(&self, q: Vec3, mut visit: impl FnMut(usize, f32)) {
        self.query_slots(q, |slot, d2| visit(self.index_of(slot) as usize, d2));
    }

    /// [`Self::query_slots`] a batch at a time: the slots of up to [`QUERY_BATCH`] points found,
    /// in the same order. A caller that reads a record of each point can read what decides
    /// whether it keeps the point for the whole batch first ([`kept`]), so those loads (points
    /// far apart in memory, each likely a cache miss) overlap instead of each waiting behind
    /// the work on the previous point.
    #[inline]
    pub fn query_slot_batches(&self, q: Vec3, visit: impl FnMut(&[u32])) {
        self.query_slot_batches_within(q, self.within, visit);
    }

    /// [`Self::query_slot_batches`] for the points within another radius than the grid's
    /// ([`Within::radius`]): a larger one visits more cells, a smaller one tests fewer points
    /// in the same cells. What per-pixel merge radii query a grid of one cell size with.
    #[inline]
    pub fn query_slot_batches_within(
        &self,
        q: Vec3,
        within: Within,
        mut visit: impl FnMut(&[u32]),
    ) {
        let mut batch = [0u32; QUERY_BATCH];
        let mut len = 0;
        self.query_slots_within(q, within, |slot, _| {
            batch[len] = slot as u32;
            len += 1;
            if len == QUERY_BATCH {
                visit(&batch);
                len = 0;
            }
        });
        if len > 0 {
            visit(&batch[..len]);
        }
    }

    /// Starts a query of the points within `within` of `q`: prefetches the table slots its
    /// runs hash to and returns at once. Where the caller begins a query before other work (an
    /// eye vertex's light sampling, which waits on Embree), the slots' cache misses (the table
    /// is tens of megabytes) overlap that work instead of being waited for.
    #[inline]
    pub fn begin_query(&self, q: Vec3, within: Within) -> BegunQuery {
        let mut query = BegunQuery {
            q,
            within,
            keys: [0; MAX_ROWS],
            rows: Rows::Nothing,
        };
        let Some((lo, hi)) = self.cell_bounds(q, within.reach) else {
            return query;
        };
        if !(0..3).all(|axis| hi[axis] - lo[axis] < self.runs.len()) {
            query.rows = Rows::Irregular;
            return query;
        }
        query.rows = Rows::Probed(self.runs);
        let first = self.key(lo);
        let run = self.runs.len() as u64;
        for (row, key) in query.keys[..self.runs.rows()].iter_mut().enumerate() {
            let (y, z) = (row as u64 % run, row as u64 / run);
            *key = first + y * self.stride_y + z * self.stride_z;
            prefetch(&self.table[self.slot_of(*key)]);
        }
        query
    }

    /// The second step of a begun query: reads its table slots (loads that wait, for as long
    /// as the prefetches have not arrived), prefetches the position groups of each range found
    /// and hands the range to `prefetch_records`, where a caller prefetches its own records of
    /// those slots. The misses of the points and records then overlap the work between this and
    /// the scan (the eye vertex's connections).
    #[inline]
    pub fn locate(
        &self,
        query: &BegunQuery,
        mut prefetch_records: impl FnMut(std::ops::Range<usize>),
    ) -> LocatedQuery {
        let ranges = match query.rows {
            Rows::Nothing => Some((Default::default(), 0)),
            Rows::Irregular => None,
            Rows::Probed(runs) => {
                let mut ranges: [std::ops::Range<u32>; MAX_ROWS] = Default::default();
                for (range, &key) in ranges.iter_mut().zip(&query.keys[..runs.rows()]) {
                    let found = self.lookup(key);
                    self.points.prefetch(found.clone());
                    prefetch_records(found.clone());
                    *range = found.start as u32..found.end as u32;
                }
                Some((ranges, runs.rows()))
            }
        };
        LocatedQuery {
            q: query.q,
            within: query.within,
            ranges,
        }
    }

    /// The slots of a located query's points, in [`Self::query_slots`]'s order, a batch at a
    /// time as [`Self::query_slot_batches`] gives them, less those `keep` rejects. `keep` is
    /// asked about each slot as the scan finds it: a caller whose `keep` reads the point's
    /// record starts that read (a cache miss, where not prefetched) while the scan goes on.
    #[inline]
    pub fn query_kept_slot_batches_located(
        &self,
        query: &LocatedQuery,
        mut keep: impl FnMut(u32) -> bool,
        mut visit: impl FnMut(&[u32]),
    ) {
        let mut batch = [0u32; QUERY_BATCH];
        let mut len = 0;
        let mut push = |slot: usize, _| {
            batch[len] = slot as u32;
            // Without a branch on the answer, which waits for the record: the next slot found
            // overwrites a rejected one.
            len += usize::from(keep(slot as u32));
            if len == QUERY_BATCH {
                visit(&batch);
                len = 0;
            }
        };
        match &query.ranges {
            None => self.query_slots_within(query.q, query.within, &mut push),
            Some((ranges, rows)) => {
                for range in &ranges[..*rows] {
                    let range = range.start as usize..range.end as usize;
                    self.points
                        .scan(range, query.q, query.within.radius_sq, &mut push);
                }
            }
        }
        if len > 0 {
            visit(&batch[..len]);
        }
    }

    /// [`Self::query_slot_batches`] with each point named by its index in the input, as
    /// [`Self::query`] names it.
    #[inline]
    pub fn query_batches(&self, q: Vec3, mut visit: impl FnMut(&[u32])) {
        self.query_slot_batches(q, |slots| {
            let mut indices = [0u32; QUERY_BATCH];
            for (index, &slot) in indices.iter_mut().zip(slots) {
                *index = self.index_of(slot as usize);
            }
            visit(&indices[..slots.len()]);
        });
    }

    /// [`Self::query`] that names each point by its slot (see [`Self::index_of`]), in the same
    /// order.
    #[inline]
    pub fn query_slots(&self, q: Vec3, visit: impl FnMut(usize, f32)) {
        self.query_slots_within(q, self.within, visit);
    }

    #[inline]
    fn query_slots_within(&self, q: Vec3, within: Within, mut visit: impl FnMut(usize, f32)) {
        let Some((lo, hi)) = self.cell_bounds(q, within.reach) else {
            return;
        };
        if (0..3).all(|axis| hi[axis] - lo[axis] < self.runs.len()) {
            let first = self.key(lo);
            match self.runs {
                CellRuns::Pairs => self.scan_rows::<2, 4>(first, q, within, &mut visit),
                CellRuns::Triplets => self.scan_rows::<3, 9>(first, q, within, &mut visit),
            }
        } else {
            // A sphere touching one cell more along an axis (its centre within rounding of a
            // cell face): disjoint runs cover each row.
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in (lo[0]..=hi[0]).step_by(self.runs.len() as usize) {
                        let range = self.lookup(self.key([x, y, z]));
                        self.points.scan(range, q, within.radius_sq, &mut visit);
                    }
                }
            }
        }
    }

    /// The `RUN` x `RUN` rows (`ROWS` of them) of runs from the run keyed `first`, the sphere
    /// inside their cells. All lookups first: their cache misses, and those of the ranges'
    /// first points, overlap instead of each waiting for the previous range's scan.
    #[inline]
    fn scan_rows<const RUN: u64, const ROWS: usize>(
        &self,
        first: u64,
        q: Vec3,
        within: Within,
        visit: &mut impl FnMut(usize, f32),
    ) {
        let (y, z) = (self.stride_y, self.stride_z);
        let ranges: [_; ROWS] = std::array::from_fn(|row| {
            let row = row as u64;
            self.lookup(first + row % RUN * y + row / RUN * z)
        });
        for range in ranges {
            self.points.scan(range, q, within.radius_sq, visit);
        }
    }

    /// The range of the run `key`, empty if no point lies in it.
    #[inline]
    fn lookup(&self, key: u64) -> std::ops::Range<usize> {
        let mask = self.table.len() - 1;
        let mut slot = self.slot_of(key);
        loop {
            let s = &self.table[slot];
            let found = s.key.load(Relaxed);
            if found == key {
                let range = s.range.load(Relaxed);
                return Slot::unpack_range(range);
            }
            if found == EMPTY {
                return 0..0;
            }
            slot = (slot + 1) & mask;
        }
    }

    #[inline]
    fn slot_of(&self, key: u64) -> usize {
        fibonacci_slot(key, self.shift)
    }

    /// The cells, as offsets from `low`, that every point within the radius of `q` lies in:
    /// those of `q -+ reach` per axis, by the points' own (monotone) cell function. The
    /// distance test accepts a point up to a few ulps beyond the radius, and `reach` is a
    /// little longer still, so a point on a cell face of the sphere's box is never missed.
    /// `None` when no point's cell is in them.
    #[inline]
    fn cell_bounds(&self, q: Vec3, reach: f32) -> Option<([i64; 3], [i64; 3])> {
        if self.table.is_empty() {
            return None;
        }
        let (mut lo, mut hi) = ([0; 3], [0; 3]);
        for axis in 0..3 {
            let span = self.span[axis];
            let below = cell(q[axis] - reach, self.inv_cell) - self.low[axis];
            let above = cell(q[axis] + reach, self.inv_cell) - self.low[axis];
            // Beyond the span limit the last cell holds all further points.
            if above < 0 || (below > span && span < SPAN_LIMIT) {
                return None;
            }
            lo[axis] = below.clamp(0, span);
            hi[axis] = above.min(span);
        }
        Some((lo, hi))
    }

    /// The key of the cell at offsets `cell` from `low`, each in 0 ..= span + 2.
    #[inline]
    fn key(&self, cell: [i64; 3]) -> u64 {
        let padded = |axis: usize| (cell[axis] + 2) as u64;
        padded(0) + padded(1) * self.stride_y + padded(2) * self.stride_z
    }

    /// The lowest cell and the span per axis (cells are monotone in the coordinate, so they
    /// are the cells of the bounding box's corners), and the key strides: coordinates padded
    /// by two on each side, so the run keys of any cell and a query's neighbour rows stay
    /// inside the key space without wrapping into another row. Returns the key bits in use.
    fn fit_key_space(&mut self, (min, max): (Vec3, Vec3)) -> u32 {
        for axis in 0..3 {
            self.low[axis] = cell(min[axis], self.inv_cell);
            self.span[axis] =
                (cell(max[axis], self.inv_cell) - self.low[axis]).clamp(0, SPAN_LIMIT);
        }
        self.low_f = Vec3A::from_array(self.low.map(|low| low as f32));
        self.span_f = Vec3A::from_array(self.span.map(|span| span as f32));
        let width = |axis: usize| self.span[axis] as u64 + 5;
        self.stride_y = width(0);
        self.stride_z = width(0) * width(1);
        let top_key = width(2) * self.stride_z - 1;
        u64::BITS - top_key.leading_zeros()
    }

    /// Sorts the points by cell key, stably (so by cell, then index), copies them into cell
    /// order and finds the distinct cells.
    fn arrange<T: Item>(
        &mut self,
        points: &[Vec3],
        [records, scratch]: &mut [Vec<Record<T>>; 2],
        bits: u32,
    ) {
        let n = points.len();
        records.resize(n, Record::default());
        let grid = &*self;
        records
            .par_chunks_mut(CHUNK)
            .zip(points.par_chunks(CHUNK))
            .enumerate()
            .for_each(|(chunk, (records, points))| {
                for (i, (record, &p)) in records.iter_mut().zip(points).enumerate() {
                    *record = Record {
                        item: T::new(grid.key_of(p), (chunk * CHUNK + i) as u32),
                        position: p.to_array(),
                    };
                }
            });
        radix_sort(records, scratch, &mut self.histograms, bits);
        let records = &*records;
        self.place_sorted(
            n,
            |i| records[i].item.key(),
            |i| (records[i].position, records[i].item.index()),
        );
    }

    /// Copies the `n` points, sorted by cell, into cell order and finds the distinct cells:
    /// `key(i)` is the cell key of the i-th point of that order, `point(i)` its position and
    /// its index in the input.
    fn place_sorted(
        &mut self,
        n: usize,
        key: impl Fn(usize) -> u64 + Sync,
        point: impl Fn(usize) -> ([f32; 3], u32) + Sync,
    ) {
        // One pass splits the sorted points into the query's arrays and counts the cells that
        // end in each chunk.
        let is_end = |i: usize| i + 1 == n || key(i) != key(i + 1);
        let chunks = n.div_ceil(CHUNK);
        self.points.reset(n);
        let ends_per_chunk = &mut self.histograms;
        ends_per_chunk.clear();
        ends_per_chunk.resize(chunks, 0);
        self.points
            .groups
            .par_chunks_mut(CHUNK / GROUP)
            .zip(ends_per_chunk.par_iter_mut())
            .enumerate()
            .for_each(|(chunk, (groups, ends))| {
                let start = chunk * CHUNK;
                for i in 0..CHUNK.min(n - start) {
                    let (position, index) = point(start + i);
                    groups[i / GROUP].set(i % GROUP, position, index);
                    *ends += u32::from(is_end(start + i));
                }
            });
        // The distinct cells in order, each with the end of its range; every chunk writes
        // those that end in it to its own slice.
        let total: usize = ends_per_chunk.iter().map(|&ends| ends as usize).sum();
        self.cells.clear();
        self.cells.resize(total, (0, 0));
        let mut rest = self.cells.as_mut_slice();
        let mut targets = Vec::with_capacity(chunks);
        for &ends in ends_per_chunk.iter() {
            let (target, tail) = std::mem::take(&mut rest).split_at_mut(ends as usize);
            targets.push(target);
            rest = tail;
        }
        targets
            .into_par_iter()
            .enumerate()
            .for_each(|(chunk, target)| {
                let start = chunk * CHUNK;
                let ends = (start..(start + CHUNK).min(n)).filter(|&i| is_end(i));
                for (cell, i) in target.iter_mut().zip(ends) {
                    *cell = (key(i), i as u32 + 1);
                }
            });
    }

    /// The key of the cell of a point: [`cell`]'s offsets from `low`, clamped to `span`, on
    /// all three axes at once in SIMD lanes (in integers, clamps and the floor's correction
    /// cost a point as much as its two sort passes). Exact: the floor of a coordinate clamped
    /// to +-2^30 is a whole f32, so are `low` and `span`, and a difference rounded beyond 2^24
    /// is clamped to `span` (at most 2^21) either way, so the offsets convert through i32 (f32
    /// to u64 has no SSE2 instruction: that cast doubled the pass). A NaN coordinate lands in a
    /// valid cell, and no distance test accepts it.
    #[inline]
    fn key_of(&self, p: Vec3) -> u64 {
        let limit = Vec3A::splat(CELL_LIMIT);
        let floor = (Vec3A::from(p) * self.inv_cell)
            .clamp(-limit, limit)
            .floor();
        let offset = (floor - self.low_f).clamp(Vec3A::ZERO, self.span_f);
        let padded = |v: f32| (v as i32 + 2) as u64;
        padded(offset.x) + padded(offset.y) * self.stride_y + padded(offset.z) * self.stride_z
    }

    /// Inserts every run that holds a point once, in key order: the run keyed t spans the
    /// cells with keys t ..= t + run - 1, consecutive in `cells` (sorted order makes their
    /// union one contiguous range; padding keeps other rows' cells out of it).
    fn fill_table(&mut self) {
        if self.cells.is_empty() {
            self.table.clear();
            return;
        }
        let cells = &self.cells;
        let run = self.runs.len() as u64;
        // A cell adds the runs its predecessor's did not: a gap below `run` shares keys.
        let new_runs = |i: usize| match i {
            0 => run as usize,
            _ => (cells[i].0 - cells[i - 1].0).min(run) as usize,
        };
        let count: usize = (0..cells.len()).into_par_iter().map(new_runs).sum();
        // Load at most two thirds: a miss, the commonest lookup on surfaces, ends after a few
        // probes in one or two cache lines.
        let capacity = (count + count / 2).next_power_of_two().max(16);
        self.shift = u64::BITS - capacity.trailing_zeros();
        if self.table.len() == capacity {
            self.table.par_iter().for_each(|slot| {
                slot.key.store(EMPTY, Relaxed);
            });
        } else {
            self.table.clear();
            self.table.resize_with(capacity, Slot::empty);
        }
        let (table, shift) = (&self.table, self.shift);
        let mask = capacity - 1;
        cells
            .par_chunks(CHUNK)
            .enumerate()
            .for_each(|(chunk, part)| {
                let start = chunk * CHUNK;
                // Runs below `next` are the earlier cells'. Cells [first, last) have keys in
                // t ..= t + run - 1 for the current run t; no earlier chunk's cell is among
                // them, as t is past its last key.
                let mut next = match start {
                    0 => 0,
                    _ => cells[start - 1].0 + 1,
                };
                let (mut first, mut last) = (start, start);
                for &(cell, _) in part {
                    // Keys are padded by 2, so above `run` - 1.
                    for t in cell + 1 - run..=cell {
                        if t < next {
                            continue;
                        }
                        next = t + 1;
                        while cells[first].0 < t {
                            first += 1;
                        }
                        while last < cells.len() && cells[last].0 < t + run {
                            last += 1;
                        }
                        let begin = if first == 0 { 0 } else { cells[first - 1].1 };
                        let end = cells[last - 1].1;
                        let mut slot = fibonacci_slot(t, shift);
                        while table[slot]
                            .key
                            .compare_exchange(EMPTY, t, Relaxed, Relaxed)
                            .is_err()
                        {
                            slot = (slot + 1) & mask;
                        }
                        table[slot]
                            .range
                            .store(Slot::pack_range(begin, end), Relaxed);
                    }
                }
            });
    }
}

/// The items of a query batch that `keep` accepts, in order; `keep` runs on the whole batch
/// before the first is returned, so its loads overlap.
pub fn kept(batch: &[u32], mut keep: impl FnMut(u32) -> bool) -> impl Iterator<Item = u32> + '_ {
    let mut mask = 0u64;
    for (bit, &item) in batch.iter().enumerate() {
        mask |= u64::from(keep(item)) << bit;
    }
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let bit = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            batch[bit]
        })
    })
}

/// A point as the sort moves it: its key and index, and its coordinates, so the sorted points
/// are read in order afterwards. Fetching each point through its index instead, in random order,
/// missed the cache once per point: the build's costliest pass, and the one a shared cache
/// slowed most.
#[derive(Clone, Copy, Default)]
struct Record<T> {
    item: T,
    position: [f32; 3],
}

/// A cell key and a point index packed into one integer (key above, index in the low 32 bits).
trait Item: Copy + Default + Ord + Send + Sync {
    fn new(key: u64, index: u32) -> Self;
    fn key(self) -> u64;
    fn index(self) -> u32;
}

impl Item for u64 {
    fn new(key: u64, index: u32) -> Self {
        key << 32 | u64::from(index)
    }
    fn key(self) -> u64 {
        self >> 32
    }
    fn index(self) -> u32 {
        self as u32
    }
}

impl Item for u128 {
    fn new(key: u64, index: u32) -> Self {
        u128::from(key) << 32 | u128::from(index)
    }
    fn key(self) -> u64 {
        (self >> 32) as u64
    }
    fn index(self) -> u32 {
        self as u32
    }
}

/// Sorts `items` stably by key: a least significant digit radix sort over the `bits` key bits
/// in use, skipping digits all keys share; `scratch` and `histograms` are its buffers.
///
/// Each pass runs on all threads: the items are cut into contiguous parts, each part counts
/// its digits, and each part's items of a bucket go after the earlier parts' items of that
/// bucket. So the order is that of a one-thread stable sort, whatever the number of parts, and
/// every part writes only to its own slices of `scratch`.
fn radix_sort<T: Item>(
    items: &mut Vec<Record<T>>,
    scratch: &mut Vec<Record<T>>,
    histograms: &mut Vec<u32>,
    bits: u32,
) {
    let n = items.len();
    let passes = bits.max(1).div_ceil(DIGIT_BITS) as usize;
    let digit_bits = bits.max(1).div_ceil(passes as u32);
    let buckets = 1usize << digit_bits;
    let digit = move |record: Record<T>, pass: usize| {
        ((record.item.key() >> (pass as u32 * digit_bits)) & (buckets as u64 - 1)) as usize
    };
    let part_len = n
        .div_ceil(rayon::current_num_threads())
        .max(SORT_PART_MIN)
        .max(1);
    let parts = n.div_ceil(part_len);
    // Per part, the counts of every pass's digits, in one read. Once a pass has moved items
    // between parts only their sums over parts stay right, and a later pass counts again.
    let pass_len = passes * buckets;
    histograms.clear();
    histograms.resize(parts * pass_len, 0);
    histograms
        .par_chunks_mut(pass_len)
        .zip(items.par_chunks(part_len))
        .for_each(|(histogram, part)| {
            for &item in part {
                for (pass, counts) in histogram.chunks_exact_mut(buckets).enumerate() {
                    counts[digit(item, pass)] += 1;
                }
            }
        });
    let count = |histograms: &[u32], part: usize, pass: usize, bucket: usize| {
        histograms[part * pass_len + pass * buckets + bucket] as usize
    };
    scratch.resize(n, Record::default());
    let mut moved = false;
    for pass in 0..passes {
        let total = |bucket| -> usize {
            (0..parts)
                .map(|part| count(histograms, part, pass, bucket))
                .sum()
        };
        if (0..buckets).any(|bucket| total(bucket) == n) {
            continue;
        }
        if moved && parts > 1 {
            histograms
                .par_chunks_mut(pass_len)
                .zip(items.par_chunks(part_len))
                .for_each(|(histogram, part)| {
                    let counts = &mut histogram[pass * buckets..(pass + 1) * buckets];
                    counts.fill(0);
                    for &item in part {
                        counts[digit(item, pass)] += 1;
                    }
                });
        }
        // Each part's slices of `scratch` in output order: bucket by bucket, part by part
        // within a bucket.
        let mut targets: Vec<Vec<std::slice::IterMut<Record<T>>>> =
            (0..parts).map(|_| Vec::with_capacity(buckets)).collect();
        let mut rest = scratch.as_mut_slice();
        for bucket in 0..buckets {
            for (part, part_targets) in targets.iter_mut().enumerate() {
                let len = count(histograms, part, pass, bucket);
                let (target, tail) = std::mem::take(&mut rest).split_at_mut(len);
                part_targets.push(target.iter_mut());
                rest = tail;
            }
        }
        targets
            .into_par_iter()
            .zip(items.par_chunks(part_len))
            .for_each(|(mut targets, part)| {
                for &item in part {
                    // Never exhausted: the slice is as long as the part's count of the bucket.
                    if let Some(target) = targets[digit(item, pass)].next() {
                        *target = item;
                    }
                }
            });
        std::mem::swap(items, scratch);
        moved = true;
    }
}

/// The points' bounding box, (min, max).
fn bounds(points: &[Vec3]) -> (Vec3, Vec3) {
    points
        .par_iter()
        .fold(
            || (Vec3::INFINITY, Vec3::NEG_INFINITY),
            |(min, max), &p| (min.min(p), max.max(p)),
        )
        .reduce(
            || (Vec3::INFINITY, Vec3::NEG_INFINITY),
            |(a, b), (c, d)| (a.min(c), b.max(d)),
        )
}

/// Fibonacci hashing: the top bits of the key times 2^64 / phi, which spreads runs of
/// consecutive keys (the runs of a row) evenly over a table of 2^(64 - shift) slots.
#[inline]
fn fibonacci_slot(key: u64, shift: u32) -> usize {
    (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> shift) as usize
}

/// The world-grid cell of a coordinate (000 eq. 2.87), floored so negative coordinates are
/// right, clamped so far-away points cannot overflow; monotone in `v`, so a point within one
/// cell side of another lies in a neighbouring cell or the same.
#[inline]
fn cell(v: f32, inv_cell: f32) -> i64 {
    let v = (v * inv_cell).clamp(-CELL_LIMIT, CELL_LIMIT);
    // Floor by truncation and correction: without SSE4.1, f32::floor is a library call.
    let truncated = v as i32;
    i64::from(truncated - i32::from(truncated as f32 > v))
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

    /// Both layouts against brute force.
    fn check(points: &[Vec3], queries: &[Vec3], r: f32) {
        let mut grid = HashGrid::default();
        for runs in CellRuns::ALL {
            grid.rebuild_as(points, r, runs);
            for &q in queries {
                let mut found = Vec::new();
                grid.query(q, |i, d2| {
                    assert!((d2 - (points[i] - q).length_squared()).abs() <= 1e-6 * d2.max(1e-30));
                    found.push(i);
                });
                found.sort_unstable();
                assert_eq!(
                    found,
                    brute_force(points, q, r),
                    "query {q} radius {r}, {runs:?}"
                );
            }
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

    /// Queries of radii from a tenth to ten times the grid's (per-pixel merge radii over a
    /// grid of one cell size) find what brute force finds, in both layouts.
    #[test]
    fn queries_of_other_radii_match_brute_force() {
        let mut rng = Rng::for_sample(4, 0, 0, Stream::Eye);
        let mut grid = HashGrid::default();
        for kind in 0..3 {
            let points = random_points(&mut rng, 3000, kind);
            for runs in CellRuns::ALL {
                grid.rebuild_as(&points, 0.05, runs);
                for _ in 0..100 {
                    let q = points[(rng.next_u32() as usize) % points.len()]
                        + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.1;
                    let r = 0.05 * 10f32.powf(2.0 * rng.next_f32() - 1.0);
                    let mut found = Vec::new();
                    grid.query_slot_batches_within(q, Within::radius(r), |batch| {
                        found.extend(batch.iter().map(|&slot| grid.index_of(slot as usize)));
                    });
                    let mut found: Vec<usize> = found.into_iter().map(|i| i as usize).collect();
                    found.sort_unstable();
                    assert_eq!(found, brute_force(&points, q, r), "{q} r {r}, {runs:?}");
                }
            }
        }
    }

    #[test]
    fn many_chunks_match_brute_force() {
        // Far more distinct cells than one parallel chunk of the table fill holds, in rows
        // that cross chunk boundaries.
        let mut rng = Rng::for_sample(7, 0, 0, Stream::Eye);
        let points = random_points(&mut rng, 100_000, 0);
        let mut queries = random_points(&mut rng, 300, 0);
        queries.extend(points.iter().step_by(500));
        let mut grid = HashGrid::default();
        grid.rebuild(&points, 0.02);
        assert!(grid.cells.len() > 8 * CHUNK);
        check(&points, &queries, 0.02);
    }

    #[test]
    fn dense_sets_take_triplets() {
        let mut rng = Rng::for_sample(12, 0, 0, Stream::Eye);
        let points = random_points(&mut rng, 50_000, 1);
        let mut grid = HashGrid::default();
        // On the three planes about one point per occupied pair cell, then about 800.
        grid.rebuild(&points, 0.005);
        assert_eq!(grid.runs(), CellRuns::Pairs);
        grid.rebuild(&points, 0.25);
        assert_eq!(grid.runs(), CellRuns::Triplets);
        check(&points, &points[..200], 0.25);
        grid.rebuild(&points, 0.005);
        assert_eq!(grid.runs(), CellRuns::Pairs);
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

    /// A point set of one of several shapes, with exact duplicates and points on cell faces.
    fn awkward_points(rng: &mut Rng, n: usize, r: f32) -> Vec<Vec3> {
        let origin = match rng.next_u32() % 4 {
            0 => Vec3::ZERO,
            1 => Vec3::new(-3.5, 2.0, -0.25),
            // Far from the origin, where coordinates are coarse.
            2 => Vec3::new(1.0e5, -2.0e5, 3.0e4),
            _ => Vec3::splat(-7.0e3),
        };
        let extent = r * [0.5, 3.0, 20.0, 200.0][(rng.next_u32() % 4) as usize];
        let mut points: Vec<Vec3> = Vec::with_capacity(n);
        while points.len() < n {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let p = match rng.next_u32() % 4 {
                0 => origin + (u * 2.0 - Vec3::ONE) * extent,
                // On cell faces, edges and corners.
                1 => {
                    let k = ((u * 2.0 - Vec3::ONE) * extent / r).round();
                    origin + k * r
                }
                // An exact copy of an earlier point.
                2 if !points.is_empty() => points[rng.next_u32() as usize % points.len()],
                // Flat, as vertices on a wall.
                _ => origin + Vec3::new(u.x * 2.0 - 1.0, u.y * 2.0 - 1.0, 0.0) * extent,
            };
            points.push(p);
        }
        points
    }

    #[test]
    fn random_sets_exactly_once() {
        let mut rng = Rng::for_sample(11, 0, 0, Stream::Eye);
        // One grid rebuilt for every case: stale buffers would show as wrong results.
        let mut grid = HashGrid::default();
        for case in 0..300 {
            let r = [1e-6f32, 1e-3, 0.05, 1.0, 1e3, 1e6][case % 6];
            let n = [0, 1, 2, 17, 300, 1500][(rng.next_u32() % 6) as usize];
            let points = awkward_points(&mut rng, n, r);
            let mut queries = awkward_points(&mut rng, 40, r);
            queries.extend(points.iter().take(40));
            let runs = CellRuns::ALL[case / 6 % 2];
            grid.rebuild_as(&points, r, runs);
            assert_eq!(grid.len(), n);
            for &q in &queries {
                let mut found = Vec::new();
                grid.query(q, |i, d2| {
                    assert_eq!(d2, (points[i] - q).length_squared());
                    found.push(i);
                });
                found.sort_unstable();
                assert_eq!(
                    found,
                    brute_force(&points, q, r),
                    "case {case}, query {q}, r {r}, {runs:?}"
                );
            }
        }
    }

    #[test]
    fn batches_match_query() {
        let mut rng = Rng::for_sample(9, 0, 0, Stream::Eye);
        let points = random_points(&mut rng, 20_000, 1);
        let grid = HashGrid::build(&points, 0.1);
        let mut longest = 0;
        for &q in points.iter().take(200) {
            let mut expected = Vec::new();
            grid.query(q, |i, _| expected.push(i as u32));
            let (mut batched, mut odd) = (Vec::new(), Vec::new());
            grid.query_batches(q, |batch| {
                assert!(!batch.is_empty() && batch.len() <= QUERY_BATCH);
                batched.extend_from_slice(batch);
                odd.extend(kept(batch, |i| i % 2 == 1));
            });
            longest = longest.max(expected.len());
            assert_eq!(batched, expected);
            expected.retain(|i| i % 2 == 1);
            assert_eq!(odd, expected);
        }
        assert!(
            longest > 2 * QUERY_BATCH,
            "some queries span several batches"
        );
    }

    /// Begun and located queries, at the grid's radius and others, in both layouts, visit the
    /// slots `query_slots_within` finds that `keep` accepts, in its order, and hand out ranges
    /// for prefetching that hold every one of them.
    #[test]
    fn begun_queries_match_query() {
        let mut rng = Rng::for_sample(10, 0, 0, Stream::Eye);
        let points = random_points(&mut rng, 20_000, 1);
        let mut grid = HashGrid::default();
        let mut longest = 0;
        for runs in CellRuns::ALL {
            grid.rebuild_as(&points, 0.1, runs);
            let mut probed = 0;
            for (k, &q) in points.iter().take(300).enumerate() {
                let within = Within::radius(0.1 * [1.0, 0.3, 2.5][k % 3]);
                let mut all = Vec::new();
                grid.query_slots_within(q, within, |slot, _| all.push(slot));
                let keep = |slot: u32| !grid.index_of(slot as usize).is_multiple_of(3);
                let expected: Vec<u32> =
                    all.iter().map(|&s| s as u32).filter(|&s| keep(s)).collect();
                let (mut found, mut touched) = (Vec::new(), Vec::new());
                let begun = grid.begin_query(q, within);
                let query = grid.locate(&begun, |range| touched.push(range));
                grid.query_kept_slot_batches_located(&query, keep, |batch| {
                    assert!(!batch.is_empty() && batch.len() <= QUERY_BATCH);
                    found.extend_from_slice(batch);
                });
                longest = longest.max(expected.len());
                assert_eq!(found, expected, "query {q}, {runs:?}");
                if let Rows::Probed(runs) = begun.rows {
                    probed += 1;
                    assert_eq!(touched.len(), runs.rows());
                    assert!(all.iter().all(|s| touched.iter().any(|r| r.contains(s))));
                }
            }
            // Both kinds of rows: the larger radius, and queries from the points on the planes
            // x = 0 and y = -1 (cell faces), read irregular ones.
            assert!(
                (100..300).contains(&probed),
                "{runs:?}: {probed} regular queries"
            );
        }
        assert!(
            longest > 2 * QUERY_BATCH,
            "some queries span several batches"
        );
    }

    #[test]
    fn simd_keys_match_integer_cells() {
        // `key_of` in float lanes against the cells of `cell` offset and clamped in integers.
        let mut rng = Rng::for_sample(8, 0, 0, Stream::Eye);
        let mut points = vec![
            Vec3::new(3.0e38, -3.0e38, 0.0),
            Vec3::new(-1.0e30, 5.0, 1.0e20),
            Vec3::new(1.0e9, 1.0e9, -1.0e9),
            Vec3::new(1.0e9 + 128.0, -0.0, -1.0e9),
        ];
        for r in [1e-3f32, 0.05, 1.0] {
            points.extend(awkward_points(&mut rng, 2000, r));
        }
        for r in [1e-3f32, 0.05, 1.0, 1e10] {
            let mut grid = HashGrid::default();
            grid.rebuild(&points, r);
            for &p in &points {
                let padded = |axis: usize| {
                    ((cell(p[axis], grid.inv_cell) - grid.low[axis]).clamp(0, grid.span[axis]) + 2)
                        as u64
                };
                let expected = padded(0) + padded(1) * grid.stride_y + padded(2) * grid.stride_z;
                assert_eq!(grid.key_of(p), expected, "{p} at r {r}");
            }
        }
    }

    #[test]
    fn huge_coordinates_and_radii() {
        // Beyond the cell clamp and the span limit cells merge: slower, still exact.
        let points = vec![
            Vec3::new(3.0e38, -3.0e38, 0.0),
            Vec3::new(3.0e38, -3.0e38, 0.0),
            Vec3::new(-1.0e30, 5.0, 1.0e20),
            Vec3::new(1.0e9, 1.0e9, -1.0e9),
            Vec3::new(1.0e9 + 128.0, 1.0e9, -1.0e9),
            Vec3::ZERO,
            Vec3::new(0.5, 0.0, 0.0),
        ];
        for r in [1e-3f32, 1.0, 100.0, 1e10, 1e18] {
            check(&points, &points, r);
            check(&points, &[Vec3::splat(1.0e9), Vec3::new(0.25, 0.0, 0.0)], r);
        }
    }

    #[test]
    fn order_independent_of_threads() {
        let mut rng = Rng::for_sample(5, 0, 0, Stream::Eye);
        // Four threads sort in four parts of 37,501 items, the last one shorter.
        let points = random_points(&mut rng, 150_001, 1);
        let queries = random_points(&mut rng, 500, 1);
        let results = |grid: &HashGrid| {
            let mut out = Vec::new();
            for &q in &queries {
                grid.query(q, |i, _| out.push(i));
            }
            out
        };
        let pool = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool")
        };
        let one = pool(1).install(|| HashGrid::build(&points, 0.05));
        let many = pool(4).install(|| HashGrid::build(&points, 0.05));
        let found = results(&one);
        assert!(found.len() > 10 * queries.len());
        assert_eq!(found, results(&many));
        // Within a row the points come by cell, then by index.
        let mut grid = HashGrid::default();
        for runs in CellRuns::ALL {
            grid.rebuild_as(&points, 0.05, runs);
            let side = runs.cell_side(0.05);
            let key = |i: usize| {
                let p = points[i] / side;
                (p.x.floor() as i64, i)
            };
            let q = points[0];
            let mut row = Vec::new();
            grid.query(q, |i, _| {
                let p = points[i] / side;
                let row_of_q = ((q.y / side).floor(), (q.z / side).floor());
                if (p.y.floor(), p.z.floor()) == row_of_q {
                    row.push(i);
                }
            });
            assert!(row.len() > 1);
            assert!(row.windows(2).all(|w| key(w[0]) < key(w[1])), "{runs:?}");
        }
    }

    /// A scan visits exactly the slots of its range that lie inside, in order, wherever the
    /// range starts and ends within a group of four and however many blocks of 64 it spans.
    #[test]
    fn scans_every_range_of_slots() {
        let n = 141;
        let mut points = GroupedPoints::default();
        points.reset(n);
        // Even slots at distance 0.5 from the query, odd ones at 2.
        let at = |slot: usize| Vec3::new(if slot.is_multiple_of(2) { 0.5 } else { 2.0 }, 0.0, 0.0);
        for slot in 0..n {
            points.set(slot, at(slot), 100 + slot as u32);
        }
        for start in 0..=n {
            for end in start..=n {
                let mut seen = Vec::new();
                points.scan(start..end, Vec3::ZERO, 1.0, &mut |slot, d2| {
                    assert_eq!(d2, at(slot).length_squared());
                    seen.push(slot);
                });
                let expected: Vec<usize> = (start..end).filter(|s| s.is_multiple_of(2)).collect();
                assert_eq!(seen, expected, "range {start}..{end}");
            }
        }
        assert_eq!(points.len(), n);
        assert_eq!(points.index_of(140), 240);
    }

    /// The in-place build gives the radix sort's grid, slot for slot: sparse and crowded sets,
    /// keys of at most and of more than 32 bits (points far apart for the radius).
    #[test]
    fn in_place_build_is_the_rebuild() {
        let mut rng = Rng::for_sample(9, 0, 0, Stream::Eye);
        let mut grid = HashGrid::default();
        let mut wide = Vec::new();
        for (kind, r) in [(0, 0.01), (1, 0.002), (1, 0.3), (2, 1e-4), (0, 1e-5)] {
            let points = random_points(&mut rng, 50_000, kind);
            grid.rebuild(&points, r);
            let mut built = HashGrid::build(&points, r);
            assert!(built.len() == points.len() && built.runs() == grid.runs());
            let slots: Vec<u32> = built.indices().collect();
            assert!(slots.iter().copied().eq(grid.indices().collect::<Vec<_>>()));
            wide.push(built.fit_key_space(bounds(&points)) > 32);
            for &q in points.iter().step_by(97) {
                let (mut a, mut b) = (Vec::new(), Vec::new());
                grid.query(q, |i, _| a.push(i));
                built.query(q, |i, _| b.push(i));
                assert_eq!(a, b, "kind {kind} radius {r}");
            }
        }
        assert!(wide.contains(&true) && wide.contains(&false), "{wide:?}");
        assert!(HashGrid::build(&[], 0.1).is_empty());
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
