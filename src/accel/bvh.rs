//! Pure-Rust backend: a binned-SAH binary BVH over triangles and analytic spheres, collapsed
//! into a 4-wide BVH. A wide node keeps its children's boxes as structure-of-arrays vectors,
//! so one SIMD slab test (glam's `Vec4`) checks all four, and nodes lie in depth-first order.
//! A leaf holds up to four triangles with their vertices copied in as structure-of-arrays
//! vectors, so one contiguous read and one SIMD triangle test serve the whole leaf (spheres,
//! rare, sit beside it in a side table). Children are visited nearest first and a popped
//! subtree farther than the closest hit so far is skipped.
//!
//! A leaf marks its cut-out triangles (`alpha.rs`), and only a hit on one of them pays for the
//! alpha test.
//!
//! Triangles use the watertight test of Woop, Benthin and Wald (2013), as pbrt-v4 does, so rays
//! through shared edges and vertices never slip between two triangles.

use super::{group_of, Accel, AccelError, Cutouts, Geometry, Hit, Primitive, Ray, Sphere, PACKET};
use glam::{Vec3, Vec4};

/// Axis-aligned box.
#[derive(Clone, Copy, Debug)]
struct Aabb {
    min: Vec3,
    max: Vec3,
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    fn grow(&mut self, other: &Aabb) {
        self.min = self.min.min(other.min);
        self.max = self.max.max(other.max);
    }

    fn grow_point(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    fn surface_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }

    fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// A node of the binary build tree: an inner node's children are `left` and `right`; a leaf
/// holds `count` primitives from `first` in the final primitive order.
#[derive(Clone, Copy, Debug)]
struct BuildNode {
    bounds: Aabb,
    left: u32,
    right: u32,
    first: u32,
    count: u32,
}

/// Children per wide node.
const WIDTH: usize = 4;

/// A wide node, 128 bytes (two cache lines).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct WideNode {
    /// The children's boxes: min x, max x, min y, max y, min z, max z, one lane per child.
    /// Unused lanes hold an empty box (min +inf, max -inf), which no ray enters.
    bounds: [Vec4; 6],
    /// Per lane, a child reference (see [`LEAF`]).
    children: [u32; WIDTH],
}

/// A child reference with this bit set is the index of a [`Leaf`] in its low bits, otherwise
/// that of a wide node. [`HAS_SPHERES`] marks leaves with spheres.
const LEAF: u32 = 1 << 31;
const HAS_SPHERES: u32 = 1 << 30;
const INDEX_MASK: u32 = HAS_SPHERES - 1;
const MAX_PRIMITIVES: usize = 1 << 28;

/// Up to four triangles, structure-of-arrays: `vertices[j][axis]` holds coordinate `axis` of
/// vertex `j` of the triangle in each lane. Unused lanes hold NaN, which no test accepts.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    vertices: [[Vec4; 3]; 3],
    /// The triangle index of each lane.
    triangles: [u32; LEAF_SIZE],
    /// How many lanes are used.
    count: u32,
    /// Bit `lane` set where that lane's triangle is cut out.
    cutouts: u32,
}

const LEAF_SIZE: usize = 4;
const BINS: usize = 16;
/// Below this depth of the binary tree, splits halve by count: with leaves of up to 4
/// primitives and at most 2^28 of them the tree is then at most 48 + 26 levels deep, and each
/// wide level pushes at most 3 entries, which bounds the traversal stack.
const SAH_DEPTH: usize = 48;
const STACK: usize = 3 * (SAH_DEPTH + 26) + 1;
/// Robust slab test (Ize 2013): the far distance is widened by a few ulps so boxes of flat
/// triangles are not missed to rounding.
const SLAB_WIDEN: f32 = 1.0 + 4.0 * f32::EPSILON;

pub struct Bvh {
    nodes: Vec<WideNode>,
    /// What the traversal starts at (a leaf when there are at most 4 primitives); `None`
    /// when the scene is empty.
    root: Option<u32>,
    leaves: Vec<Leaf>,
    /// For a leaf marked [`HAS_SPHERES`], its range `[first, end)` of `sphere_order`, by
    /// leaf index (empty for the others).
    leaf_spheres: Vec<[u32; 2]>,
    sphere_order: Vec<u32>,
    spheres: Vec<Sphere>,
    cutouts: Cutouts,
    /// [`Geometry::group_starts`], to name a hit's group.
    group_starts: Vec<u32>,
}

/// The closest hit so far: a lane of a leaf or a sphere.
#[derive(Clone, Copy)]
enum HitRef {
    Triangle { leaf: u32, lane: usize },
    Sphere(u32),
}

struct BuildPrim {
    bounds: Aabb,
    center: Vec3,
    primitive: Primitive,
}

impl Bvh {
    pub fn build(geometry: &Geometry) -> Result<Self, AccelError> {
        let count = geometry.triangles.len() + geometry.spheres.len();
        if count > MAX_PRIMITIVES {
            return Err(AccelError::InvalidGeometry(format!(
                "{count} primitives, more than the {MAX_PRIMITIVES} the BVH addresses"
            )));
        }
        geometry.check_groups()?;
        let mut prims: Vec<BuildPrim> = Vec::with_capacity(count);
        for (i, tri) in geometry.triangles.iter().enumerate() {
            if tri.iter().any(|&v| v as usize >= geometry.positions.len()) {
                return Err(AccelError::InvalidGeometry(format!(
                    "triangle {i} indexes a vertex beyond the {} given",
                    geometry.positions.len()
                )));
            }
            let mut b = Aabb::EMPTY;
            geometry
                .triangle_vertices(i as u32)
                .iter()
                .for_each(|&p| b.grow_point(p));
            prims.push(BuildPrim {
                bounds: b,
                center: b.center(),
                primitive: Primitive::Triangle(i as u32),
            });
        }
        for (i, s) in geometry.spheres.iter().enumerate() {
            if !(s.radius > 0.0 && s.radius.is_finite() && s.center.is_finite()) {
                return Err(AccelError::InvalidGeometry(format!(
                    "sphere {i} has radius {}",
                    s.radius
                )));
            }
            let r = Vec3::splat(s.radius);
            let b = Aabb {
                min: s.center - r,
                max: s.center + r,
            };
            prims.push(BuildPrim {
                bounds: b,
                center: s.center,
                primitive: Primitive::Sphere(i as u32),
            });
        }
        let mut binary = Vec::with_capacity(2 * prims.len() / LEAF_SIZE + 1);
        let mut bvh = Bvh {
            nodes: Vec::new(),
            root: None,
            leaves: Vec::new(),
            leaf_spheres: Vec::new(),
            sphere_order: Vec::new(),
            spheres: geometry.spheres.clone(),
            cutouts: geometry.cutouts.clone(),
            group_starts: geometry.group_starts.clone(),
        };
        if !prims.is_empty() {
            build_recursive(&mut prims, 0, 0, &mut binary);
            bvh.root = Some(bvh.collapse(&binary, 0, &prims, geometry));
        }
        Ok(bvh)
    }

    /// Collapses the binary subtree at `index` into wide nodes (depth first) and leaves;
    /// returns its child reference. A wide node takes the binary node's two children and keeps
    /// opening the inner one with the largest surface area (the most likely to be entered)
    /// until it has four.
    fn collapse(
        &mut self,
        binary: &[BuildNode],
        index: u32,
        prims: &[BuildPrim],
        geometry: &Geometry,
    ) -> u32 {
        let node = &binary[index as usize];
        if node.count > 0 {
            let range = node.first as usize..(node.first + node.count) as usize;
            return self.add_leaf(&prims[range], geometry);
        }
        let mut kids = vec![node.left, node.right];
        while kids.len() < WIDTH {
            let open = kids
                .iter()
                .enumerate()
                .filter(|(_, &k)| binary[k as usize].count == 0)
                .max_by(|(_, &a), (_, &b)| {
                    let area = |k: u32| binary[k as usize].bounds.surface_area();
                    area(a).total_cmp(&area(b))
                })
                .map(|(i, _)| i);
            let Some(i) = open else { break };
            let k = &binary[kids[i] as usize];
            kids[i] = k.left;
            kids.push(k.right);
        }
        let slot = self.nodes.len();
        self.nodes.push(WideNode {
            bounds: [
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
            ],
            children: [0; WIDTH],
        });
        for (lane, &k) in kids.iter().enumerate() {
            let b = binary[k as usize].bounds;
            let child = self.collapse(binary, k, prims, geometry);
            let w = &mut self.nodes[slot];
            for axis in 0..3 {
                w.bounds[2 * axis][lane] = b.min[axis];
                w.bounds[2 * axis + 1][lane] = b.max[axis];
            }
            w.children[lane] = child;
        }
        slot as u32
    }

    fn add_leaf(&mut self, prims: &[BuildPrim], geometry: &Geometry) -> u32 {
        let mut leaf = Leaf {
            vertices: [[Vec4::NAN; 3]; 3],
            triangles: [0; LEAF_SIZE],
            count: 0,
            cutouts: 0,
        };
        let first_sphere = self.sphere_order.len() as u32;
        for p in prims {
            match p.primitive {
                Primitive::Triangle(i) => {
                    let lane = leaf.count as usize;
                    for (j, v) in geometry.triangle_vertices(i).iter().enumerate() {
                        for axis in 0..3 {
                            leaf.vertices[j][axis][lane] = v[axis];
                        }
                    }
                    leaf.triangles[lane] = i;
                    if geometry.cutouts.get(i).is_some() {
                        leaf.cutouts |= 1 << lane;
                    }
                    leaf.count += 1;
                }
                Primitive::Sphere(i) => self.sphere_order.push(i),
            }
        }
        let index = self.leaves.len() as u32;
        self.leaves.push(leaf);
        let end = self.sphere_order.len() as u32;
        self.leaf_spheres.push([first_sphere, end]);
        if end > first_sphere {
            LEAF | HAS_SPHERES | index
        } else {
            LEAF | index
        }
    }

    fn traverse(&self, ray: &Ray, any_hit: bool) -> Option<Hit> {
        let mut current = self.root?;
        let inv_dir = ray.dir.recip();
        // Per axis, which bounds lane is the near plane of a box along this ray.
        let near = [
            (inv_dir.x < 0.0) as usize,
            2 + (inv_dir.y < 0.0) as usize,
            4 + (inv_dir.z < 0.0) as usize,
        ];
        let far = [near[0] ^ 1, near[1] ^ 1, near[2] ^ 1];
        let origin = [
            Vec4::splat(ray.origin.x),
            Vec4::splat(ray.origin.y),
            Vec4::splat(ray.origin.z),
        ];
        let inv = [
            Vec4::splat(inv_dir.x),
            Vec4::splat(inv_dir.y),
            Vec4::splat(inv_dir.z),
        ];
        let tmin = Vec4::splat(ray.tmin);
        let tri_setup = WatertightRay::new(ray);
        let mut tmax = ray.tmax;
        // The closest hit so far: (t, u, v, what).
        let mut best: Option<(f32, f32, f32, HitRef)> = None;
        let mut stack = [(0u32, 0f32); STACK];
        let mut sp = 0usize;
        loop {
            if current & LEAF == 0 {
                let node = &self.nodes[current as usize];
                let axis = |k: usize, plane: usize| (node.bounds[plane] - origin[k]) * inv[k];
                // glam's SSE max/min return their second operand when the first is NaN (an
                // axis-parallel ray in a box's face plane): that axis then does not cull.
                let t_near = axis(0, near[0]).max(axis(1, near[1]).max(axis(2, near[2]).max(tmin)));
                let t_far = axis(0, far[0])
                    .min(axis(1, far[1]).min(axis(2, far[2]).min(Vec4::splat(tmax))));
                let mut mask = t_near.cmple(t_far * SLAB_WIDEN).bitmask();
                match mask.count_ones() {
                    0 => {}
                    1 => {
                        current = node.children[mask.trailing_zeros() as usize];
                        continue;
                    }
                    _ => {
                        // Push the hit children farthest first, then descend into the nearest.
                        let distances = t_near.to_array();
                        let mut hits = [(0u32, 0f32); WIDTH];
                        let mut n = 0;
                        while mask != 0 {
                            let lane = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            let entry = (node.children[lane], distances[lane]);
                            let mut k = n;
                            while k > 0 && hits[k - 1].1 < entry.1 {
                                hits[k] = hits[k - 1];
                                k -= 1;
                            }
                            hits[k] = entry;
                            n += 1;
                        }
                        stack[sp..sp + n - 1].copy_from_slice(&hits[..n - 1]);
                        sp += n - 1;
                        current = hits[n - 1].0;
                        continue;
                    }
                }
            } else {
                let index = current & INDEX_MASK;
                let leaf = &self.leaves[index as usize];
                if let Some((t, u, v, lane)) =
                    tri_setup.intersect4(leaf, ray.tmin, tmax, &self.cutouts, ray)
                {
                    best = Some((t, u, v, HitRef::Triangle { leaf: index, lane }));
                    if any_hit {
                        return best.map(|hit| self.hit(ray, hit));
                    }
                    tmax = t;
                }
                if current & HAS_SPHERES != 0 {
                    let [first, end] = self.leaf_spheres[index as usize];
                    for &i in &self.sphere_order[first as usize..end as usize] {
                        if let Some(t) = self.spheres[i as usize].first_hit(ray, tmax) {
                            best = Some((t, 0.0, 0.0, HitRef::Sphere(i)));
                            if any_hit {
                                return best.map(|hit| self.hit(ray, hit));
                            }
                            tmax = t;
                        }
                    }
                }
            }
            // Pop the next subtree that may still hold a hit nearer than the closest so far.
            loop {
                if sp == 0 {
                    return best.map(|hit| self.hit(ray, hit));
                }
                sp -= 1;
                let (next, t_near) = stack[sp];
                if t_near <= tmax {
                    current = next;
                    break;
                }
            }
        }
    }

    /// The [`Hit`] of `(t, u, v, what)`, its normal computed once per query.
    fn hit(&self, ray: &Ray, (t, u, v, what): (f32, f32, f32, HitRef)) -> Hit {
        match what {
            HitRef::Triangle { leaf, lane } => {
                let leaf = &self.leaves[leaf as usize];
                let [a, b, c] = leaf
                    .vertices
                    .map(|p| Vec3::new(p[0][lane], p[1][lane], p[2][lane]));
                let triangle = leaf.triangles[lane];
                Hit {
                    t,
                    primitive: Primitive::Triangle(triangle),
                    group: group_of(&self.group_starts, triangle),
                    u,
                    v,
                    ng: (b - a).cross(c - a),
                }
            }
            HitRef::Sphere(i) => self.spheres[i as usize].hit(i, ray, t),
        }
    }
}

/// Builds the binary subtree over `prims`, which start at index `base` of the final primitive
/// order, at depth `depth`; returns its node index.
fn build_recursive(
    prims: &mut [BuildPrim],
    base: u32,
    depth: usize,
    nodes: &mut Vec<BuildNode>,
) -> u32 {
    let mut bounds = Aabb::EMPTY;
    let mut centers = Aabb::EMPTY;
    for p in prims.iter() {
        bounds.grow(&p.bounds);
        centers.grow_point(p.center);
    }
    let index = nodes.len() as u32;
    nodes.push(BuildNode {
        bounds,
        left: 0,
        right: 0,
        first: base,
        count: prims.len() as u32,
    });
    // Testing a leaf of four triangles costs one SIMD test, no more than one triangle.
    if prims.len() <= LEAF_SIZE {
        return index;
    }
    let extent = centers.max - centers.min;
    let mut split = None;
    if depth < SAH_DEPTH {
        // Binned SAH (Wald 2007) on all three axes: cost of splitting after each bin boundary,
        // counting primitives in leaf blocks of four, which cost one SIMD test each.
        let blocks = |n: usize| n.div_ceil(LEAF_SIZE) as f32;
        let mut bins = [[(Aabb::EMPTY, 0usize); BINS]; 3];
        let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), BINS as f32 / extent, Vec3::ZERO);
        let bin_of = |c: Vec3, axis: usize| {
            (((c[axis] - centers.min[axis]) * scale[axis]) as usize).min(BINS - 1)
        };
        for p in prims.iter() {
            for (axis, bins) in bins.iter_mut().enumerate() {
                let b = &mut bins[bin_of(p.center, axis)];
                b.0.grow(&p.bounds);
                b.1 += 1;
            }
        }
        let mut best = (f32::INFINITY, 0, 0);
        for (axis, bins) in bins.iter().enumerate() {
            if extent[axis] <= 0.0 {
                continue;
            }
            let mut right_area = [0.0f32; BINS];
            let mut right_count = [0usize; BINS];
            let (mut acc, mut count) = (Aabb::EMPTY, 0);
            for i in (1..BINS).rev() {
                acc.grow(&bins[i].0);
                count += bins[i].1;
                right_area[i] = acc.surface_area();
                right_count[i] = count;
            }
            let (mut acc, mut count) = (Aabb::EMPTY, 0);
            for i in 0..BINS - 1 {
                acc.grow(&bins[i].0);
                count += bins[i].1;
                if count == 0 || right_count[i + 1] == 0 {
                    continue;
                }
                let cost = acc.surface_area() * blocks(count)
                    + right_area[i + 1] * blocks(right_count[i + 1]);
                if cost < best.0 {
                    best = (cost, axis, i + 1);
                }
            }
        }
        if best.0.is_finite() {
            let (_, axis, bin) = best;
            split = Some(partition(prims, |p| bin_of(p.center, axis) < bin));
        }
    }
    let mid = match split {
        Some(mid) if mid > 0 && mid < prims.len() => mid,
        // All centres coincide, SAH found no split, or the tree is deep: halve by count
        // along the widest axis of the centres.
        _ => {
            let axis = extent.max_position();
            let mid = prims.len() / 2;
            prims.select_nth_unstable_by(mid, |a, b| a.center[axis].total_cmp(&b.center[axis]));
            mid
        }
    };
    let (left, right) = prims.split_at_mut(mid);
    let left = build_recursive(left, base, depth + 1, nodes);
    let right = build_recursive(right, base + mid as u32, depth + 1, nodes);
    let node = &mut nodes[index as usize];
    (node.left, node.right, node.count) = (left, right, 0);
    index
}

fn partition(prims: &mut [BuildPrim], left: impl Fn(&BuildPrim) -> bool) -> usize {
    let mut i = 0;
    for j in 0..prims.len() {
        if left(&prims[j]) {
            prims.swap(i, j);
            i += 1;
        }
    }
    i
}

/// Per-ray precomputation of the watertight triangle test.
struct WatertightRay {
    /// The axes (kx, ky, kz): kz the dominant axis of the direction.
    k: [usize; 3],
    /// The origin's coordinates along (kx, ky, kz).
    origin: [Vec4; 3],
    shear: [Vec4; 3],
}

impl WatertightRay {
    fn new(ray: &Ray) -> Self {
        let d = ray.dir;
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let o = ray.origin;
        WatertightRay {
            k: [kx, ky, kz],
            origin: [o[kx], o[ky], o[kz]].map(Vec4::splat),
            shear: [-d[kx] / d[kz], -d[ky] / d[kz], 1.0 / d[kz]].map(Vec4::splat),
        }
    }

    /// The nearest hit `(t, u, v, lane)` among the leaf's triangles with `t` in `[tmin, tmax]`
    /// that `cutouts` lets count for `ray`, asked for the leaf's cut-out lanes alone.
    #[inline]
    fn intersect4(
        &self,
        leaf: &Leaf,
        tmin: f32,
        tmax: f32,
        cutouts: &Cutouts,
        ray: &Ray,
    ) -> Option<(f32, f32, f32, usize)> {
        let [kx, ky, kz] = self.k;
        let [sx, sy, sz] = self.shear;
        let rel = |p: &[Vec4; 3]| {
            let (x, y, z) = (
                p[kx] - self.origin[0],
                p[ky] - self.origin[1],
                p[kz] - self.origin[2],
            );
            (x + sx * z, y + sy * z, sz * z)
        };
        let (a, b, c) = (
            rel(&leaf.vertices[0]),
            rel(&leaf.vertices[1]),
            rel(&leaf.vertices[2]),
        );
        let mut u = c.0 * b.1 - c.1 * b.0;
        let mut v = a.0 * c.1 - a.1 * c.0;
        let mut w = b.0 * a.1 - b.1 * a.0;
        let lanes = (1u32 << leaf.count) - 1;
        let zero = Vec4::ZERO;
        let mut on_edge = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & lanes;
        while on_edge != 0 {
            // Exact fallback on edges, as the paper prescribes.
            let l = on_edge.trailing_zeros() as usize;
            on_edge &= on_edge - 1;
            let (ax, ay, bx, by, cx, cy) = (
                a.0[l] as f64,
                a.1[l] as f64,
                b.0[l] as f64,
                b.1[l] as f64,
                c.0[l] as f64,
                c.1[l] as f64,
            );
            u[l] = (cx * by - cy * bx) as f32;
            v[l] = (ax * cy - ay * cx) as f32;
            w[l] = (bx * ay - by * ax) as f32;
        }
        let outside = (u.cmplt(zero) | v.cmplt(zero) | w.cmplt(zero))
            & (u.cmpgt(zero) | v.cmpgt(zero) | w.cmpgt(zero));
        let det = u + v + w;
        let t_scaled = u * a.2 + v * b.2 + w * c.2;
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        let mut hits =
            (!outside & det.cmpne(zero) & t.cmpge(Vec4::splat(tmin)) & t.cmple(Vec4::splat(tmax)))
                .bitmask()
                & lanes;
        if hits & leaf.cutouts != 0 {
            hits = cut_out_lanes(hits, leaf, [v, w, inv_det], cutouts, ray);
        }
        if hits == 0 {
            return None;
        }
        let mut best = hits.trailing_zeros() as usize;
        hits &= hits - 1;
        while hits != 0 {
            let l = hits.trailing_zeros() as usize;
            hits &= hits - 1;
            if t[l] < t[best] {
                best = l;
            }
        }
        // u weighs vertex 0 here; the Hit contract's (u, v) weigh vertices 1 and 2.
        Some((
            t[best],
            v[best] * inv_det[best],
            w[best] * inv_det[best],
            best,
        ))
    }
}

/// `hits` without the cut-out lanes whose alpha removes the hit (barycentrics `v * inv_det`,
/// `w * inv_det` from `[v, w, inv_det]`). Out of line: leaves without cut-outs never call it,
/// and keeping it out keeps their test as it was.
#[inline(never)]
fn cut_out_lanes(
    mut hits: u32,
    leaf: &Leaf,
    [v, w, inv_det]: [Vec4; 3],
    cutouts: &Cutouts,
    ray: &Ray,
) -> u32 {
    let mut cut = hits & leaf.cutouts;
    while cut != 0 {
        let l = cut.trailing_zeros() as usize;
        cut &= cut - 1;
        if !cutouts.keeps(leaf.triangles[l], v[l] * inv_det[l], w[l] * inv_det[l], ray) {
            hits &= !(1 << l);
        }
    }
    hits
}

impl Accel for Bvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.traverse(ray, false)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        self.traverse(ray, true).is_some()
    }

    fn intersect8(&self, rays: &[Ray; PACKET], active: u8, hits: &mut [Option<Hit>; PACKET]) {
        for (i, (ray, hit)) in rays.iter().zip(hits.iter_mut()).enumerate() {
            *hit = if active & (1 << i) != 0 {
                self.intersect(ray)
            } else {
                None
            };
        }
    }

    fn occluded8(&self, rays: &[Ray; PACKET], active: u8) -> u8 {
        let mut mask = 0;
        for (i, ray) in rays.iter().enumerate() {
            if active & (1 << i) != 0 && self.occluded(ray) {
                mask |= 1 << i;
            }
        }
        mask
    }

    fn name(&self) -> &'static str {
        "bvh"
    }
}
