//! Traversal kernels: the segment-local traversal that dual streaming runs (on a
//! segment as loaded into the scene buffer) and the plain reference traversal of
//! the whole BVH that judges every other mode.
//!
//! Both use the same box and triangle functions and the same culling rule, so the
//! closest hit by (t, triangle id) is found exactly, ties included.

use glam::Vec3;

use crate::accel::{Bvh, Child};
use crate::contract::{
    HitRec, NODE_BYTES, NodeRec, RayRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES, SparseMem, TRI_BYTES,
    TriRec,
};
use crate::geom::aabb::ray_box_screened;
use crate::geom::{Aabb, Triangle, cull, inverse_dir, ray_box, ray_triangle};

/// Work done by a traversal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TraversalCounts {
    /// Stack entries popped (culled ones included): the TP's `pop` state.
    pub pops: u64,
    pub nodes: u64,
    pub box_tests: u64,
    pub tri_tests: u64,
    pub exits: u64,
    /// Triangle tests that hit (the triangle pipeline's divide stage runs).
    pub tri_hits: u64,
    /// 64 B lines a TP loads through its L1: one per node, one or two per triangle.
    pub l1_lines: u64,
    pub max_stack: u64,
}

impl std::ops::AddAssign for TraversalCounts {
    fn add_assign(&mut self, o: Self) {
        self.nodes += o.nodes;
        self.box_tests += o.box_tests;
        self.tri_tests += o.tri_tests;
        self.exits += o.exits;
        self.pops += o.pops;
        self.tri_hits += o.tri_hits;
        self.l1_lines += o.l1_lines;
        self.max_stack = self.max_stack.max(o.max_stack);
    }
}

/// A segment as held in the scene buffer: its records, decoded.
pub struct SegmentView {
    pub id: u32,
    pub nodes: Vec<NodeRec>,
    pub tris: Vec<TriRec>,
    /// Every node's boxes are finite (half of `ray_box`'s input screen, done once
    /// here rather than per test; see `ray_box_screened`).
    pub boxes_finite: bool,
}

impl SegmentView {
    /// Reads a whole segment from the DRAM image (the scene stream).
    pub fn load(mem: &SparseMem, base: u64, id: u32, nodes: u32, tris: u32) -> SegmentView {
        let nb = nodes as usize * NODE_BYTES as usize;
        let mut bytes = vec![0u8; nb + tris as usize * TRI_BYTES as usize];
        mem.read(base + SEGMENT_HEADER_BYTES as u64, &mut bytes);
        let (nbytes, tbytes) = bytes.split_at(nb);
        let nodes: Vec<NodeRec> = nbytes
            .chunks_exact(NODE_BYTES as usize)
            .map(NodeRec::decode)
            .collect();
        let boxes_finite = nodes
            .iter()
            .all(|n| (0..2).all(|k| n.bmin[k].is_finite() && n.bmax[k].is_finite()));
        SegmentView {
            id,
            nodes,
            tris: tbytes
                .chunks_exact(TRI_BYTES as usize)
                .map(TriRec::decode)
                .collect(),
            boxes_finite,
        }
    }
}

/// Traverses one ray through one segment from its entry reference: returns the best
/// hit found here (local early termination: nothing farther is visited or enqueued) and calls
/// `exit(segment, entry, t)` for every exit into a child segment that is not
/// culled, in discovery order, `t` the distance at which the ray enters it. A shadow ray stops at its first hit. The stack holds
/// (reference, segment or `SEG_SAME`, entry distance); an entry with a segment is an
/// exit.
pub fn traverse_segment(
    seg: &SegmentView,
    ray: &RayRec,
    stack: &mut Vec<(u32, u32, f32)>,
    counts: &mut TraversalCounts,
    exit: impl FnMut(u32, u32, f32),
) -> HitRec {
    // The box test's input screen, once for the whole traversal when it passes
    // (a loop of its own: a branch per test kept most of the cost).
    let inv = inverse_dir(ray.dir);
    if seg.boxes_finite && ray.origin.is_finite() && !inv.is_nan() {
        traverse_in::<true>(seg, ray, inv, stack, counts, exit)
    } else {
        traverse_in::<false>(seg, ray, inv, stack, counts, exit)
    }
}

#[inline(always)]
fn traverse_in<const SCREENED: bool>(
    seg: &SegmentView,
    ray: &RayRec,
    inv: Vec3,
    stack: &mut Vec<(u32, u32, f32)>,
    counts: &mut TraversalCounts,
    mut exit: impl FnMut(u32, u32, f32),
) -> HitRec {
    let (origin, dir, shadow, entry) = (ray.origin, ray.dir, ray.is_shadow(), ray.entry);
    let t_ray = ray.t_max();
    let mut best = HitRec::NONE;
    stack.clear();
    stack.push((entry, SEG_SAME, 0.0));
    while let Some((r, s, te)) = stack.pop() {
        counts.pops += 1;
        let limit = best.t.min(t_ray);
        if te > cull(limit) {
            continue;
        }
        if s != SEG_SAME {
            counts.exits += 1;
            exit(s, r, te);
            continue;
        }
        match Ref::decode(r) {
            Ref::Leaf { first, count } => {
                for k in first..first + count {
                    let tr = &seg.tris[k as usize];
                    counts.tri_tests += 1;
                    // Segments start on a row (a line) boundary, so offsets give the lines.
                    let off = (SEGMENT_HEADER_BYTES + seg.nodes.len() as u32 * NODE_BYTES) as u64
                        + k as u64 * TRI_BYTES as u64;
                    counts.l1_lines += crate::contract::lines_touched(off, TRI_BYTES as u64);
                    let tri = Triangle {
                        v0: tr.v[0],
                        v1: tr.v[1],
                        v2: tr.v[2],
                    };
                    if let Some(h) = ray_triangle(origin, dir, 0.0, best.t.min(t_ray), &tri) {
                        counts.tri_hits += 1;
                        let cand = HitRec {
                            t: h.t,
                            tri_id: tr.tri_id,
                            u: h.u,
                            v: h.v,
                        };
                        if cand.closer_than(&best) {
                            best = cand;
                        }
                        if shadow {
                            return best;
                        }
                    }
                }
            }
            Ref::Node(i) => {
                counts.nodes += 1;
                counts.l1_lines += 1;
                let n = &seg.nodes[i as usize];
                let lim = cull(best.t.min(t_ray));
                counts.box_tests += 2;
                // Two plain calls rather than an array map, whose closure was not
                // inlined in this hot loop (docs/results/2026-11-27-speed-error-the-functional-traversal-s-box-screen-and-the-dragon-box-aga.md).
                let side = |k: usize| Aabb {
                    min: n.bmin[k],
                    max: n.bmax[k],
                };
                let hit = if SCREENED {
                    [
                        ray_box_screened(origin, inv, 0.0, lim, n.bmin[0], n.bmax[0]),
                        ray_box_screened(origin, inv, 0.0, lim, n.bmin[1], n.bmax[1]),
                    ]
                } else {
                    [
                        ray_box(origin, inv, 0.0, lim, &side(0)),
                        ray_box(origin, inv, 0.0, lim, &side(1)),
                    ]
                };
                // Push the far child first so the near one is visited first.
                let order = match (hit[0], hit[1]) {
                    (Some(a), Some(b)) if b < a => [0, 1],
                    _ => [1, 0],
                };
                for side in order {
                    if let Some(t) = hit[side] {
                        stack.push((n.child[side], n.seg[side], t));
                    }
                }
                counts.max_stack = counts.max_stack.max(stack.len() as u64);
            }
            Ref::None => {}
        }
    }
    // The pop that finds the stack empty ends the traversal (a TP runs it too).
    counts.pops += 1;
    best
}

/// The reference: a plain stack traversal of the whole BVH. Closest hit by
/// (t, id) for a bounce ray; for a shadow ray, whether anything lies in t in [0, 1].
pub fn reference_trace(
    bvh: &Bvh,
    tris: &[Triangle],
    origin: Vec3,
    dir: Vec3,
    shadow: bool,
) -> HitRec {
    reference_trace_counted(
        bvh,
        tris,
        origin,
        dir,
        shadow,
        &mut TraversalCounts::default(),
    )
}

/// [`reference_trace`], counting its work.
pub fn reference_trace_counted(
    bvh: &Bvh,
    tris: &[Triangle],
    origin: Vec3,
    dir: Vec3,
    shadow: bool,
    counts: &mut TraversalCounts,
) -> HitRec {
    let inv = inverse_dir(dir);
    let t_ray = if shadow { 1.0 } else { f32::INFINITY };
    let mut best = HitRec::NONE;
    let mut stack: Vec<(Child, f32)> = vec![(bvh.root, 0.0)];
    while let Some((c, te)) = stack.pop() {
        counts.pops += 1;
        if te > cull(best.t.min(t_ray)) {
            continue;
        }
        match c {
            Child::Leaf { first, count } => {
                for &id in &bvh.tri_order[first as usize..(first + count) as usize] {
                    counts.tri_tests += 1;
                    if let Some(h) =
                        ray_triangle(origin, dir, 0.0, best.t.min(t_ray), &tris[id as usize])
                    {
                        counts.tri_hits += 1;
                        let cand = HitRec {
                            t: h.t,
                            tri_id: id,
                            u: h.u,
                            v: h.v,
                        };
                        if cand.closer_than(&best) {
                            best = cand;
                        }
                        if shadow {
                            return best;
                        }
                    }
                }
            }
            Child::Inner(i) => {
                let n = &bvh.nodes[i as usize];
                counts.nodes += 1;
                counts.box_tests += 2;
                let lim = cull(best.t.min(t_ray));
                let h0 = ray_box(origin, inv, 0.0, lim, &n.child_bounds[0]);
                let h1 = ray_box(origin, inv, 0.0, lim, &n.child_bounds[1]);
                let order = match (h0, h1) {
                    (Some(a), Some(b)) if b < a => [0, 1],
                    _ => [1, 0],
                };
                for side in order {
                    if let Some(t) = [h0, h1][side] {
                        stack.push((n.children[side], t));
                    }
                }
            }
        }
    }
    best
}
