//! Pure-Rust backend: a binned-SAH bounding volume hierarchy over triangles and analytic
//! spheres, flattened depth-first into 32-byte nodes and traversed near child first.
//!
//! Triangles use the watertight test of Woop, Benthin and Wald (2013), as pbrt-v4 does, so rays
//! through shared edges and vertices never slip between two triangles.

use super::{sphere_roots, Accel, AccelError, Geometry, Hit, Primitive, Ray, Sphere, PACKET};
use glam::Vec3;

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

/// A flattened node: an inner node's first child follows it, `offset` is the second child;
/// a leaf holds `count` primitives starting at `offset` in `Bvh::order`.
#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3,
    offset: u32,
    max: Vec3,
    /// 0 for inner nodes, otherwise the primitive count; the split axis is kept in `axis`.
    count: u16,
    axis: u16,
}

const LEAF_SIZE: usize = 4;
const BINS: usize = 16;
/// Relative cost of a node traversal step against one primitive test in the SAH.
const TRAVERSAL_COST: f32 = 1.0;

pub struct Bvh {
    nodes: Vec<Node>,
    /// Primitive references in leaf order.
    order: Vec<Primitive>,
    /// Triangle vertices in primitive order, copied so a leaf test reads contiguous memory.
    triangles: Vec<[Vec3; 3]>,
    spheres: Vec<Sphere>,
}

struct BuildPrim {
    bounds: Aabb,
    center: Vec3,
    primitive: Primitive,
}

impl Bvh {
    pub fn build(geometry: &Geometry) -> Result<Self, AccelError> {
        let mut triangles = Vec::with_capacity(geometry.triangles.len());
        for (i, tri) in geometry.triangles.iter().enumerate() {
            if tri.iter().any(|&v| v as usize >= geometry.positions.len()) {
                return Err(AccelError::InvalidGeometry(format!(
                    "triangle {i} indexes a vertex beyond the {} given",
                    geometry.positions.len()
                )));
            }
            triangles.push(geometry.triangle_vertices(i as u32));
        }
        let mut prims: Vec<BuildPrim> =
            Vec::with_capacity(triangles.len() + geometry.spheres.len());
        for (i, t) in triangles.iter().enumerate() {
            let mut b = Aabb::EMPTY;
            t.iter().for_each(|&p| b.grow_point(p));
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
        let mut nodes = Vec::with_capacity(2 * prims.len() / LEAF_SIZE + 1);
        if !prims.is_empty() {
            build_recursive(&mut prims, 0, &mut nodes);
        }
        Ok(Bvh {
            nodes,
            order: prims.iter().map(|p| p.primitive).collect(),
            triangles,
            spheres: geometry.spheres.clone(),
        })
    }

    fn traverse(&self, ray: &Ray, any_hit: bool) -> Option<Hit> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv_dir = ray.dir.recip();
        let dir_negative = [inv_dir.x < 0.0, inv_dir.y < 0.0, inv_dir.z < 0.0];
        let tri_setup = WatertightRay::new(ray);
        let mut tmax = ray.tmax;
        let mut best: Option<Hit> = None;
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut index = 0u32;
        loop {
            let node = &self.nodes[index as usize];
            if slab_test(node, ray.origin, inv_dir, ray.tmin, tmax) {
                if node.count > 0 {
                    let first = node.offset as usize;
                    for &primitive in &self.order[first..first + node.count as usize] {
                        let hit = match primitive {
                            Primitive::Triangle(i) => tri_setup
                                .intersect(&self.triangles[i as usize], ray.tmin, tmax)
                                .map(|(t, u, v, ng)| Hit {
                                    t,
                                    primitive,
                                    u,
                                    v,
                                    ng,
                                }),
                            Primitive::Sphere(i) => {
                                let s = &self.spheres[i as usize];
                                sphere_roots(s, ray)
                                    .and_then(|r| {
                                        r.into_iter().find(|&t| t >= ray.tmin && t <= tmax)
                                    })
                                    .map(|t| Hit {
                                        t,
                                        primitive,
                                        u: 0.0,
                                        v: 0.0,
                                        ng: (ray.at(t) - s.center).normalize(),
                                    })
                            }
                        };
                        if let Some(hit) = hit {
                            if any_hit {
                                return Some(hit);
                            }
                            tmax = hit.t;
                            best = Some(hit);
                        }
                    }
                } else {
                    // Visit the near child first: along a negative direction the second child
                    // (upper half of the split axis) is nearer.
                    let (near, far) = if dir_negative[node.axis as usize] {
                        (node.offset, index + 1)
                    } else {
                        (index + 1, node.offset)
                    };
                    stack[sp] = far;
                    sp += 1;
                    index = near;
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            index = stack[sp];
        }
        best
    }
}

/// Builds the subtree over `prims`, which start at index `base` of the final primitive order.
fn build_recursive(prims: &mut [BuildPrim], base: u32, nodes: &mut Vec<Node>) -> u32 {
    let mut bounds = Aabb::EMPTY;
    let mut centers = Aabb::EMPTY;
    for p in prims.iter() {
        bounds.grow(&p.bounds);
        centers.grow_point(p.center);
    }
    let index = nodes.len() as u32;
    nodes.push(Node {
        min: bounds.min,
        offset: 0,
        max: bounds.max,
        count: 0,
        axis: 0,
    });
    let leaf = |nodes: &mut Vec<Node>, offset: u32, count: usize| {
        nodes[index as usize].offset = offset;
        nodes[index as usize].count = count as u16;
    };
    if prims.len() <= 1 {
        leaf(nodes, base, prims.len());
        return index;
    }
    let extent = centers.max - centers.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mut split = None;
    if extent[axis] > 0.0 {
        // Binned SAH (Wald 2007): cost of splitting after each bin boundary.
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        let scale = BINS as f32 / extent[axis];
        let bin_of = |c: Vec3| (((c[axis] - centers.min[axis]) * scale) as usize).min(BINS - 1);
        for p in prims.iter() {
            let b = &mut bins[bin_of(p.center)];
            b.0.grow(&p.bounds);
            b.1 += 1;
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
        let mut best = (f32::INFINITY, 0);
        for i in 0..BINS - 1 {
            acc.grow(&bins[i].0);
            count += bins[i].1;
            if count == 0 || right_count[i + 1] == 0 {
                continue;
            }
            let cost =
                acc.surface_area() * count as f32 + right_area[i + 1] * right_count[i + 1] as f32;
            if cost < best.0 {
                best = (cost, i + 1);
            }
        }
        let leaf_cost = bounds.surface_area() * prims.len() as f32;
        let split_cost = TRAVERSAL_COST * bounds.surface_area() + best.0;
        if best.0.is_finite() && (split_cost < leaf_cost || prims.len() > LEAF_SIZE) {
            split = Some(partition(prims, |p| bin_of(p.center) < best.1));
        }
    }
    let mid = match split {
        Some(mid) if mid > 0 && mid < prims.len() => mid,
        _ if prims.len() <= LEAF_SIZE => {
            leaf(nodes, base, prims.len());
            return index;
        }
        // All centres coincide (or SAH found no split): halve by count along the axis.
        _ => {
            let mid = prims.len() / 2;
            prims.select_nth_unstable_by(mid, |a, b| a.center[axis].total_cmp(&b.center[axis]));
            mid
        }
    };
    let (left, right) = prims.split_at_mut(mid);
    build_recursive(left, base, nodes);
    let second = build_recursive(right, base + mid as u32, nodes);
    nodes[index as usize].offset = second;
    nodes[index as usize].axis = axis as u16;
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

#[inline]
fn slab_test(node: &Node, origin: Vec3, inv_dir: Vec3, tmin: f32, tmax: f32) -> bool {
    let t0 = (node.min - origin) * inv_dir;
    let t1 = (node.max - origin) * inv_dir;
    // max/min ignore NaN from 0 * inf on an axis-parallel ray through a slab face.
    let near = t0.min(t1).max_element().max(tmin);
    let far = t0.max(t1).min_element().min(tmax);
    // Robust slab test (Ize 2013): widen by 2 ulp-ish so boxes of flat triangles are not missed.
    near <= far * (1.0 + 2.0 * f32::EPSILON * 2.0)
}

/// Per-ray precomputation of the watertight triangle test.
struct WatertightRay {
    origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    shear: Vec3,
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
        let shear = Vec3::new(-d[kx] / d[kz], -d[ky] / d[kz], 1.0 / d[kz]);
        WatertightRay {
            origin: ray.origin,
            kx,
            ky,
            kz,
            shear,
        }
    }

    /// `(t, u, v, unit normal)` of a hit with `t` in `[tmin, tmax]`.
    #[inline]
    fn intersect(&self, tri: &[Vec3; 3], tmin: f32, tmax: f32) -> Option<(f32, f32, f32, Vec3)> {
        let (kx, ky, kz, s) = (self.kx, self.ky, self.kz, self.shear);
        let rel = |p: Vec3| {
            let p = p - self.origin;
            Vec3::new(p[kx] + s.x * p[kz], p[ky] + s.y * p[kz], s.z * p[kz])
        };
        let (a, b, c) = (rel(tri[0]), rel(tri[1]), rel(tri[2]));
        let mut u = c.x * b.y - c.y * b.x;
        let mut v = a.x * c.y - a.y * c.x;
        let mut w = b.x * a.y - b.y * a.x;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // Exact fallback on edges, as the paper prescribes.
            let (ax, ay, bx, by, cx, cy) = (
                a.x as f64, a.y as f64, b.x as f64, b.y as f64, c.x as f64, c.y as f64,
            );
            u = (cx * by - cy * bx) as f32;
            v = (ax * cy - ay * cx) as f32;
            w = (bx * ay - by * ax) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let t_scaled = u * a.z + v * b.z + w * c.z;
        let inv_det = 1.0 / det;
        let t = t_scaled * inv_det;
        if !(t >= tmin && t <= tmax) {
            return None;
        }
        // u weighs vertex 0 here; the Hit contract's (u, v) weigh vertices 1 and 2.
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
        Some((t, v * inv_det, w * inv_det, ng))
    }
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
