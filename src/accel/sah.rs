//! The fallback builder for inputs on which PLOC stalls (see [`super::ploc`]):
//! top-down binned SAH (Wald 2007) over the box centres, one primitive per leaf,
//! in obvhs's `Bvh2` layout so the rest of the build is shared.
//!
//! Bounded whatever the input: every split leaves primitives on both sides, and
//! below [`SAH_LEVELS`] levels (and in nodes of fewer than 16 primitives) the
//! splits are object medians, so the tree is at
//! most `SAH_LEVELS + ceil(log2 n)` levels deep and the build costs
//! O(n (SAH_LEVELS + log n)). Deterministic: f32/f64 arithmetic in a fixed order,
//! ties broken by axis, plane and primitive index. Plain arrays rather than
//! glam's vectors: the debug-built tests run this on 100K triangles.

use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH};

/// Bins per axis.
const BINS: usize = 16;

/// Levels split by the SAH; deeper nodes are split at the object median.
pub const SAH_LEVELS: u32 = 48;

/// Nodes of fewer primitives are split at the median too: binning costs more
/// than it gains there.
const SAH_MIN_PRIMS: usize = 16;

/// A box as two corners.
#[derive(Clone, Copy)]
struct B {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl B {
    const EMPTY: B = B {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };

    fn grow(&mut self, o: &B) {
        for k in 0..3 {
            self.lo[k] = self.lo[k].min(o.lo[k]);
            self.hi[k] = self.hi[k].max(o.hi[k]);
        }
    }

    fn add(&mut self, p: &[f32; 3]) {
        self.grow(&B { lo: *p, hi: *p });
    }

    /// Half area in f64: counts times areas must not overflow.
    fn half_area(&self) -> f64 {
        let d = |k: usize| self.hi[k] as f64 - self.lo[k] as f64;
        (d(0) + d(1)) * d(2) + d(0) * d(1)
    }
}

/// Returns the BVH2 and its depth (levels of nodes, the root is level 1).
pub(crate) fn build(aabbs: &[Aabb]) -> (Bvh2, u32) {
    let n = aabbs.len();
    assert!(n > 0, "callers reject empty scenes");
    let boxes: Vec<B> = aabbs
        .iter()
        .map(|b| B {
            lo: b.min.to_array(),
            hi: b.max.to_array(),
        })
        .collect();
    let centres: Vec<[f32; 3]> = boxes
        .iter()
        .map(|b| std::array::from_fn(|k| (b.lo[k] + b.hi[k]) * 0.5))
        .collect();
    let mut prims: Vec<u32> = (0..n as u32).collect();
    // Children pairs start at odd indices (obvhs's sibling arithmetic needs it).
    let mut nodes = vec![Bvh2Node::default(); 1];
    nodes.reserve(2 * n - 1);
    let mut max_depth = 1u32;
    // (node, first prim, end, level)
    let mut todo: Vec<(usize, usize, usize, u32)> = vec![(0, 0, n, 1)];
    while let Some((node, start, end, level)) = todo.pop() {
        max_depth = max_depth.max(level);
        let range = &mut prims[start..end];
        let mut bounds = B::EMPTY;
        let mut cb = B::EMPTY;
        for &p in range.iter() {
            bounds.grow(&boxes[p as usize]);
            cb.add(&centres[p as usize]);
        }
        let aabb = Aabb::new(bounds.lo.into(), bounds.hi.into());
        if range.len() == 1 {
            nodes[node] = Bvh2Node::new(aabb, 1, start as u32);
            continue;
        }
        let mid = if level <= SAH_LEVELS && range.len() >= SAH_MIN_PRIMS {
            sah_split(range, &boxes, &centres, &cb)
        } else {
            None
        }
        .unwrap_or_else(|| median_split(range, &centres, &cb));
        let first = nodes.len();
        nodes.push(Bvh2Node::default());
        nodes.push(Bvh2Node::default());
        nodes[node] = Bvh2Node::new(aabb, 0, first as u32);
        // Right below left on the stack: left subtrees are finished first.
        todo.push((first + 1, start + mid, end, level + 1));
        todo.push((first, start, start + mid, level + 1));
    }
    let bvh = Bvh2 {
        nodes,
        primitive_indices: prims,
        max_depth: DEFAULT_MAX_STACK_DEPTH.max(max_depth as usize + 1),
        children_are_ordered_after_parents: true,
        ..Bvh2::zeroed(0)
    };
    (bvh, max_depth)
}

/// Bin of centre coordinate `c` on an axis starting at `lo` with `scale` =
/// BINS / extent. Saturating casts: NaN (0 * inf) gives bin 0, inf the last.
fn bin(c: f32, lo: f32, scale: f32) -> usize {
    (((c - lo) * scale) as usize).min(BINS - 1)
}

/// The axis along which the centres spread widest (ties to the lower axis).
fn widest(cb: &B) -> usize {
    let ext = [
        cb.hi[0] - cb.lo[0],
        cb.hi[1] - cb.lo[1],
        cb.hi[2] - cb.lo[2],
    ];
    if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    }
}

/// Partitions `range` at the cheapest binned SAH plane across the widest axis
/// of the centres (one axis: a third of the binning, for a fallback); returns
/// the size of the left part (1..len), or None if all centres coincide. `cb`
/// bounds the centres.
fn sah_split(range: &mut [u32], boxes: &[B], centres: &[[f32; 3]], cb: &B) -> Option<usize> {
    let axis = widest(cb);
    let (lo, ext) = (cb.lo[axis], cb.hi[axis] - cb.lo[axis]);
    // Also catches a NaN extent.
    if ext.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let scale = BINS as f32 / ext;
    let mut bin_box = [B::EMPTY; BINS];
    let mut bin_n = [0u64; BINS];
    for &p in range.iter() {
        let k = bin(centres[p as usize][axis], lo, scale);
        bin_box[k].grow(&boxes[p as usize]);
        bin_n[k] += 1;
    }
    // The lowest and highest centres sit in the first and last bins, so every
    // plane (bins 0..=plane to the left) has primitives on both sides.
    let mut right_cost = [0.0f64; BINS];
    let (mut b, mut c) = (B::EMPTY, 0u64);
    for k in (1..BINS).rev() {
        b.grow(&bin_box[k]);
        c += bin_n[k];
        right_cost[k - 1] = c as f64 * b.half_area();
    }
    // (cost, plane), the first cheapest.
    let mut best = (f64::INFINITY, 0);
    let (mut b, mut c) = (B::EMPTY, 0u64);
    for (plane, right) in right_cost.iter().enumerate().take(BINS - 1) {
        b.grow(&bin_box[plane]);
        c += bin_n[plane];
        let cost = c as f64 * b.half_area() + right;
        if cost < best.0 {
            best = (cost, plane);
        }
    }
    let plane = best.1;
    // The sides are sets: no need for a stable partition.
    let mut left = 0;
    for i in 0..range.len() {
        if bin(centres[range[i] as usize][axis], lo, scale) <= plane {
            range.swap(left, i);
            left += 1;
        }
    }
    debug_assert!(left > 0 && left < range.len());
    Some(left)
}

/// Splits `range` in half along the widest axis of its centres (ties by index).
fn median_split(range: &mut [u32], centres: &[[f32; 3]], cb: &B) -> usize {
    let axis = widest(cb);
    let mid = range.len() / 2;
    range.select_nth_unstable_by(mid, |&a, &b| {
        centres[a as usize][axis]
            .total_cmp(&centres[b as usize][axis])
            .then(a.cmp(&b))
    });
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// Leaves hold every primitive once, boxes hold their children, depth is
    /// as reported.
    fn check(aabbs: &[Aabb]) -> u32 {
        let (bvh, depth) = build(aabbs);
        let mut seen = vec![0u32; aabbs.len()];
        let mut deepest = 0;
        let mut todo = vec![(0usize, 1u32)];
        while let Some((i, level)) = todo.pop() {
            deepest = deepest.max(level);
            let n = &bvh.nodes[i];
            if n.is_leaf() {
                for k in n.first_index..n.first_index + n.prim_count {
                    let p = bvh.primitive_indices[k as usize] as usize;
                    seen[p] += 1;
                    assert_eq!(n.aabb().union(&aabbs[p]), *n.aabb());
                }
            } else {
                assert_eq!(n.first_index % 2, 1, "sibling pairs start at odd slots");
                for c in [n.first_index, n.first_index + 1] {
                    let cn = &bvh.nodes[c as usize];
                    assert_eq!(n.aabb().union(cn.aabb()), *n.aabb());
                    todo.push((c as usize, level + 1));
                }
            }
        }
        assert!(seen.iter().all(|&k| k == 1), "every primitive in one leaf");
        assert_eq!(deepest, depth);
        depth
    }

    #[test]
    fn splits_every_input_into_a_bounded_tree() {
        let mut rng = crate::util::rng::Rng::new(2);
        let soup: Vec<Aabb> = (0..2000)
            .map(|_| {
                let p = Vec3A::new(
                    rng.range_f32(-9.0, 9.0),
                    rng.range_f32(-9.0, 9.0),
                    rng.range_f32(-9.0, 9.0),
                );
                Aabb::new(p, p + Vec3A::splat(rng.range_f32(0.0, 3.0)))
            })
            .collect();
        assert!(
            check(&soup) <= 2 * 11 + 4,
            "a soup splits near the balanced depth"
        );
        // Coincident centres: median splits, a balanced tree.
        let same = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); 1000];
        assert_eq!(check(&same), 11);
        // Nested boxes on one centre line, sizes growing geometrically: the SAH
        // peels one off per level, then the median takes over.
        let nested: Vec<Aabb> = (0..3000)
            .map(|i| {
                let s = 1.01f32.powi(i);
                Aabb::new(Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(s, s, s))
            })
            .collect();
        let d = check(&nested);
        assert!(d <= SAH_LEVELS + 12, "{d}");
        assert_eq!(check(&soup[..1]), 1);
        assert_eq!(check(&soup[..2]), 2);
    }
}
