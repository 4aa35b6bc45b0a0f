//! The reference's bounding-volume hierarchy: a binned-SAH build on the CPU, flattened into the
//! two arrays `glsl/reference/trace.glsl` traverses.
//!
//! Build: top-down, 16 centroid bins per axis, surface-area cost with a traversal cost of one
//! triangle test. It runs from an explicit work list (no recursion, so a million triangles cannot
//! overflow the thread's stack) and stops at [`MAX_DEPTH`], so the shader's fixed traversal
//! stack of [`STACK_SIZE`] entries can never overflow either. Degenerate input is handled where
//! it arises: an axis whose centroids do not spread is not binned, flat boxes have a positive
//! (or zero) area and still compare, and a node whose centroids all coincide is split at its
//! median when it is too big for a leaf.
//!
//! Layout: 32-byte nodes (`min, left_or_first, max, count`); an interior node has `count == 0`
//! and its children at `left_or_first` and `left_or_first + 1`; a leaf holds triangles
//! `left_or_first .. + count` of the reordered triangle array (48 bytes each: three vertices,
//! and the triangle's original index in the first padding word). Node boxes are padded by
//! [`BOX_PAD`] × the scene's largest coordinate, more than the slab test's rounding, so the
//! traversal never culls a triangle that the triangle test would hit: BVH and brute force give
//! the same answer (tested below).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::cpu::ray_cast::{intersect, Ray, Triangle};
use crate::error::{Error, Result};
use crate::scene::Aabb;

/// Deepest node level the build creates (the root is level 0). A million triangles of the
/// `grid` scene need 23.
pub const MAX_DEPTH: u32 = 40;
/// Entries of the shader's traversal stack: at most one per level below the root, for two
/// traversals at once (the single layer's primary ray and a centre ray).
pub const STACK_SIZE: usize = 2 * MAX_DEPTH as usize;
/// Node-box padding, relative to the scene's largest absolute coordinate.
pub const BOX_PAD: f32 = 1.0 / 262_144.0;
/// Leaves hold at most this many triangles unless the depth limit forces a larger one.
pub const MAX_LEAF: usize = 8;
const BINS: usize = 16;
/// Cost of visiting a node, in triangle tests.
const TRAVERSAL_COST: f32 = 1.0;

/// One node, as `struct Node` in `trace.glsl` (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    /// Box minimum corner (padded).
    pub min: [f32; 3],
    /// Interior: index of the left child (the right one follows it). Leaf: first triangle.
    pub left_or_first: u32,
    /// Box maximum corner (padded).
    pub max: [f32; 3],
    /// Leaf: number of triangles (≥ 1). Interior: 0.
    pub count: u32,
}

/// One triangle, as `struct Tri` in `trace.glsl` (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhTriangle {
    /// First vertex.
    pub a: [f32; 3],
    /// The triangle's index in the scene's index list (for debugging and tests).
    pub index: u32,
    /// Second vertex.
    pub b: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// Third vertex.
    pub c: [f32; 3],
    /// Padding.
    pub pad1: u32,
}

/// A built hierarchy.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// Nodes, root first. Never empty; with no triangles the root is a placeholder that is never
    /// traversed (the shader and [`Bvh::occluded`] check the triangle count first).
    pub nodes: Vec<BvhNode>,
    /// Triangles in leaf order.
    pub triangles: Vec<BvhTriangle>,
    /// Deepest level reached.
    pub depth: u32,
}

/// Surface area of a box (0 for an empty one).
fn area(b: &Aabb) -> f32 {
    if b.is_empty() {
        return 0.0;
    }
    let e = b.max - b.min;
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}

/// The largest absolute coordinate (at least the smallest normal `f32`, so a scale exists).
pub fn scene_scale(positions: &[Vec3]) -> f32 {
    positions
        .iter()
        .fold(f32::MIN_POSITIVE, |m, p| m.max(p.abs().max_element()))
}

/// What the builder knows about one triangle.
struct Prim {
    bounds: Aabb,
    centroid: Vec3,
}

/// The bin of centroid coordinate `c` on an axis starting at `lo` with `scale` bins per unit.
fn bin_of(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// The best binned-SAH split of `order` as `(axis, last bin of the left side)`, if any split
/// beats a leaf (or the node is too big to be one).
fn best_split(
    order: &[u32],
    prims: &[Prim],
    bounds: &Aabb,
    centroids: &Aabb,
) -> Option<(usize, f32, f32, usize)> {
    let count = order.len();
    let parent_area = area(bounds).max(f32::MIN_POSITIVE);
    let mut best: Option<(f32, usize, f32, f32, usize)> = None;
    for axis in 0..3 {
        let lo = centroids.min[axis];
        let extent = centroids.max[axis] - lo;
        if extent <= 0.0 || !extent.is_finite() {
            continue;
        }
        let scale = BINS as f32 / extent;
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        for &t in order {
            let p = &prims[t as usize];
            let b = &mut bins[bin_of(p.centroid[axis], lo, scale)];
            b.0 = b.0.union(p.bounds);
            b.1 += 1;
        }
        // Right side areas and counts for a split after bin i.
        let mut right = [(0.0f32, 0usize); BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(bins[i].0);
            n += bins[i].1;
            right[i - 1] = (area(&acc), n);
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for i in 0..BINS - 1 {
            acc = acc.union(bins[i].0);
            n += bins[i].1;
            let (right_area, right_n) = right[i];
            if n == 0 || right_n == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (area(&acc) * n as f32 + right_area * right_n as f32) / parent_area;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, lo, scale, i));
            }
        }
    }
    let (cost, axis, lo, scale, last) = best?;
    (cost < count as f32 || count > MAX_LEAF).then_some((axis, lo, scale, last))
}

/// Splits `order` in place around its best split; returns the size of the left part, or `None`
/// for a leaf.
fn split(order: &mut [u32], prims: &[Prim], bounds: &Aabb, centroids: &Aabb) -> Option<usize> {
    match best_split(order, prims, bounds, centroids) {
        Some((axis, lo, scale, last)) => {
            let mut mid = 0;
            for i in 0..order.len() {
                if bin_of(prims[order[i] as usize].centroid[axis], lo, scale) <= last {
                    order.swap(i, mid);
                    mid += 1;
                }
            }
            // Both sides held a bin's worth of triangles when the split was chosen.
            (mid > 0 && mid < order.len()).then_some(mid)
        }
        // Every centroid in one place: any split is as good as another.
        None if order.len() > MAX_LEAF => Some(order.len() / 2),
        None => None,
    }
}

impl Bvh {
    /// Builds the hierarchy over an indexed triangle list (world space).
    pub fn build(positions: &[Vec3], indices: &[u32]) -> Result<Bvh> {
        let bad = |message: String| Error::input("reference BVH", None, message);
        if indices.len() % 3 != 0 {
            return Err(bad(format!(
                "{} indices is not a whole number of triangles",
                indices.len()
            )));
        }
        let n = indices.len() / 3;
        if n >= (u32::MAX / 2) as usize {
            return Err(bad(format!("{n} triangles do not fit 32-bit node indices")));
        }
        let mut tris: Vec<Triangle> = Vec::with_capacity(n);
        for (t, tri) in indices.chunks_exact(3).enumerate() {
            let mut v = [[0.0; 3]; 3];
            for (k, &i) in tri.iter().enumerate() {
                let p = positions.get(i as usize).ok_or_else(|| {
                    bad(format!(
                        "triangle {t} uses vertex {i}; there are {}",
                        positions.len()
                    ))
                })?;
                v[k] = p.to_array();
            }
            tris.push(v);
        }
        let prims: Vec<Prim> = tris
            .iter()
            .map(|t| {
                let mut bounds = Aabb::EMPTY;
                for v in t {
                    bounds.extend(Vec3::from_array(*v));
                }
                Prim {
                    bounds,
                    centroid: bounds.centre(),
                }
            })
            .collect();
        let pad = Vec3::splat(BOX_PAD * scene_scale(positions));
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = vec![BvhNode::default()];
        let mut depth = 0;
        // (node, first, end, level): one entry per node still to build.
        let mut work = vec![(0usize, 0usize, n, 0u32)];
        while let Some((node, start, end, level)) = work.pop() {
            depth = depth.max(level);
            let (mut bounds, mut centroids) = (Aabb::EMPTY, Aabb::EMPTY);
            for &t in &order[start..end] {
                bounds = bounds.union(prims[t as usize].bounds);
                centroids.extend(prims[t as usize].centroid);
            }
            let (min, max) = if bounds.is_empty() {
                (Vec3::ZERO, Vec3::ZERO)
            } else {
                (bounds.min - pad, bounds.max + pad)
            };
            let mid = if end - start > 1 && level < MAX_DEPTH {
                split(&mut order[start..end], &prims, &bounds, &centroids)
            } else {
                None
            };
            nodes[node] = match mid {
                Some(mid) => {
                    let left = nodes.len();
                    nodes.extend([BvhNode::default(); 2]);
                    work.push((left + 1, start + mid, end, level + 1));
                    work.push((left, start, start + mid, level + 1));
                    BvhNode {
                        min: min.to_array(),
                        left_or_first: left as u32,
                        max: max.to_array(),
                        count: 0,
                    }
                }
                None => BvhNode {
                    min: min.to_array(),
                    left_or_first: start as u32,
                    max: max.to_array(),
                    count: (end - start) as u32,
                },
            };
        }
        let triangles = order
            .iter()
            .map(|&t| {
                let [a, b, c] = tris[t as usize];
                BvhTriangle {
                    a,
                    index: t,
                    b,
                    pad0: 0,
                    c,
                    pad1: 0,
                }
            })
            .collect();
        Ok(Bvh {
            nodes,
            triangles,
            depth,
        })
    }

    /// `occluded` of the shader on the CPU: any triangle hit in (0, `ray.tmax`).
    pub fn occluded(&self, ray: &Ray) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let safe = |d: f32| {
            if d.abs() < 1e-30 {
                if d < 0.0 {
                    -1e-30
                } else {
                    1e-30
                }
            } else {
                d
            }
        };
        let inv = ray.dir.map(|d| 1.0 / safe(d));
        let o = ray.origin;
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 0;
        let mut index = 0;
        loop {
            let node = &self.nodes[index as usize];
            let (mut near, mut far) = (0.0f32, ray.tmax);
            for k in 0..3 {
                let t0 = (node.min[k] - o[k]) * inv[k];
                let t1 = (node.max[k] - o[k]) * inv[k];
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            if near <= far {
                if node.count == 0 {
                    stack[sp] = node.left_or_first + 1;
                    sp += 1;
                    index = node.left_or_first;
                    continue;
                }
                let first = node.left_or_first as usize;
                for t in &self.triangles[first..first + node.count as usize] {
                    if intersect(ray, &[t.a, t.b, t.c]).hit {
                        return true;
                    }
                }
            }
            if sp == 0 {
                return false;
            }
            sp -= 1;
            index = stack[sp];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::ray_cast::{occluded, triangles};
    use std::mem::{offset_of, size_of};

    #[test]
    fn gpu_struct_layouts() {
        assert_eq!(offset_of!(BvhNode, min), 0);
        assert_eq!(offset_of!(BvhNode, left_or_first), 12);
        assert_eq!(offset_of!(BvhNode, max), 16);
        assert_eq!(offset_of!(BvhNode, count), 28);
        assert_eq!(size_of::<BvhNode>(), 32);
        assert_eq!(offset_of!(BvhTriangle, a), 0);
        assert_eq!(offset_of!(BvhTriangle, index), 12);
        assert_eq!(offset_of!(BvhTriangle, b), 16);
        assert_eq!(offset_of!(BvhTriangle, c), 32);
        assert_eq!(size_of::<BvhTriangle>(), 48);
    }

    fn contains(outer: &BvhNode, min: [f32; 3], max: [f32; 3]) -> bool {
        (0..3).all(|k| outer.min[k] <= min[k] && max[k] <= outer.max[k])
    }

    /// Every triangle in exactly one leaf, every leaf reachable once, boxes nested.
    fn check_structure(bvh: &Bvh, n: usize) {
        assert!(bvh.depth <= MAX_DEPTH);
        let mut seen = vec![0u32; n];
        let mut visits = vec![0u32; bvh.nodes.len()];
        let mut work = vec![0usize];
        while let Some(i) = work.pop() {
            visits[i] += 1;
            let node = bvh.nodes[i];
            if node.count == 0 {
                let l = node.left_or_first as usize;
                for c in [l, l + 1] {
                    let child = bvh.nodes[c];
                    assert!(
                        contains(&node, child.min, child.max),
                        "node {i} ⊉ child {c}"
                    );
                    work.push(c);
                }
            } else {
                let first = node.left_or_first as usize;
                for t in &bvh.triangles[first..first + node.count as usize] {
                    seen[t.index as usize] += 1;
                    for v in [t.a, t.b, t.c] {
                        assert!(contains(&node, v, v), "leaf {i} misses a vertex");
                    }
                }
            }
        }
        assert!(
            seen.iter().all(|&s| s == 1),
            "a triangle is missing or repeated"
        );
        assert!(
            visits.iter().all(|&v| v == 1),
            "a node is unreachable or shared"
        );
    }

    /// A small LCG in [0, 1).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    #[test]
    fn scene_bvh_is_complete_and_traversal_equals_brute_force() {
        let scene = crate::scene::Scene::procedural("plane-boxes").expect("scene");
        let (p, i) = scene.merged();
        let bvh = Bvh::build(&p, &i).expect("build");
        let n = i.len() / 3;
        check_structure(&bvh, n);
        let tris = triangles(&p, &i);
        let mut rng = Lcg(7);
        let mut blocked = 0;
        for k in 0..3000 {
            let mut point = || {
                [
                    rng.next() * 16.0 - 8.0,
                    rng.next() * 4.0,
                    rng.next() * 16.0 - 8.0,
                ]
            };
            let o = point();
            let t = point();
            let d = [t[0] - o[0], t[1] - o[1], t[2] - o[2]];
            // Every third ray is axis-parallel, the slab test's zero-direction case.
            let d = if k % 3 == 0 { [0.0, d[1], 0.0] } else { d };
            let ray = Ray::new(o, d, if k % 2 == 0 { 1.0 } else { 1e3 });
            let brute = occluded(&ray, &tris).blocked;
            assert_eq!(bvh.occluded(&ray), brute, "ray {k}: {ray:?}");
            blocked += u32::from(brute);
        }
        assert!(
            blocked > 300 && blocked < 2700,
            "rays should both hit and miss: {blocked}"
        );
    }

    #[test]
    fn degenerate_inputs_build() {
        // 1000 copies of one triangle: no centroid spread at all.
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let i: Vec<u32> = (0..1000).flat_map(|_| [0, 1, 2]).collect();
        let bvh = Bvh::build(&p, &i).expect("build");
        check_structure(&bvh, 1000);
        assert!(bvh.nodes.iter().all(|n| n.count as usize <= MAX_LEAF));
        // Flat, axis-aligned boxes; and exponentially spaced triangles that drive the depth.
        let mut p = Vec::new();
        let mut i = Vec::new();
        for k in 0..200u32 {
            let x = 2f32.powi(-(k as i32 % 120));
            let base = p.len() as u32;
            p.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x * 1.5, 0.0, 0.0),
                Vec3::new(x, 0.0, x),
            ]);
            i.extend([base, base + 1, base + 2]);
        }
        let bvh = Bvh::build(&p, &i).expect("build");
        check_structure(&bvh, 200);
        // No triangles: one unused leaf.
        let empty = Bvh::build(&[], &[]).expect("build");
        assert_eq!(empty.nodes.len(), 1);
        assert!(empty.triangles.is_empty());
        assert!(!empty.occluded(&Ray::new([0.0; 3], [1.0, 0.0, 0.0], 1.0)));
        // Bad indices are an error, not a panic.
        assert!(Bvh::build(&[Vec3::ZERO], &[0, 1, 2]).is_err());
        assert!(Bvh::build(&[Vec3::ZERO], &[0, 0]).is_err());
    }

    #[test]
    fn a_million_triangles_build_within_the_depth_limit() {
        let scene = crate::scene::Scene::procedural("grid:1000000").expect("scene");
        let (p, i) = scene.merged();
        let start = std::time::Instant::now();
        let bvh = Bvh::build(&p, &i).expect("build");
        let n = i.len() / 3;
        eprintln!(
            "{n} triangles, depth {}, built in {:?}",
            bvh.depth,
            start.elapsed()
        );
        assert!(n >= 1_000_000);
        check_structure(&bvh, n);
        // A few rays through the sheet and its holes, against brute force.
        let tris = triangles(&p, &i);
        let mut blocked = 0;
        for k in 0..8 {
            let x = -5.0 + 1.37 * k as f32;
            let ray = Ray::new([x, 0.01, 0.3 * k as f32], [0.4, 8.0, -0.2], 1.0);
            let brute = occluded(&ray, &tris).blocked;
            assert_eq!(bvh.occluded(&ray), brute, "ray {k}");
            blocked += u32::from(brute);
        }
        assert!(
            blocked > 0 && blocked < 8,
            "rays both hit the sheet and pass its holes"
        );
    }
}
