//! Treelets: the paper's scene segments.
//!
//! ## Formation
//! A segment is a set of connected pieces of the BVH (one or more subtree roots and
//! nodes below them) whose records fit the byte budget (`segment_bytes`, default
//! 64 KB): a 64 B header, 64 B per inner node, 48 B per triangle. Rays flow only from
//! a segment to the segments holding the roots it cut off (its children), so the
//! segments form a tree.
//!
//! 1. The root segment starts at the BVH root. It grows greedily by surface area:
//!    of the nodes adjacent to the segment (children of included inner nodes), the
//!    one with the largest box surface area (the most likely to be hit by a random
//!    ray) is included if its record fits; otherwise it is cut and becomes a root of
//!    a child segment. This fills the segment with the part of the tree that most
//!    rays reach (wide near the top), as Aila & Karras' treelets do.
//! 2. The cut roots of a segment, largest area first, seed its child segments; each
//!    grows the same way. When a child segment has taken its whole subtree and room
//!    is left, whole subtrees of other roots cut from the same parent are packed in
//!    (first fit), so the small subtrees at the bottom of the BVH do not become
//!    thousands of tiny segments. A ray entering such a segment carries the node it
//!    enters at (the ray record's entry reference).
//! 3. Segments are numbered in depth-first pre-order of the segment tree (children in
//!    creation order), the order in which the stream scheduler visits them.
//!
//! Shallow segments (a small budget) cut rays more often, so they raise ray
//! duplication; deep ones waste scene-buffer space on rarely-hit nodes (paper §7).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::bvh::{Bvh, Child};
use crate::contract::{NODE_BYTES, SEGMENT_HEADER_BYTES, TRI_BYTES};

/// A segment as formed: what it holds, in the order records are laid out.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    pub id: u32,
    pub parent: Option<u32>,
    pub children: Vec<u32>,
    /// Entry points: BVH pieces whose parent is in the parent segment (or the BVH root).
    pub roots: Vec<Child>,
    /// Inner nodes (BVH node indices) in record order.
    pub nodes: Vec<u32>,
    /// Leaves in record order; their triangles are laid out in this order.
    pub leaves: Vec<Child>,
    pub tri_count: u32,
    pub bytes: u32,
}

/// The segmentation of a BVH.
#[derive(Clone, Debug)]
pub struct Segmentation {
    pub segments: Vec<Segment>,
    pub budget: u32,
}

fn cost(c: Child) -> u32 {
    match c {
        Child::Inner(_) => NODE_BYTES,
        Child::Leaf { count, .. } => TRI_BYTES * count,
    }
}

/// Heap entry ordered by surface area, ties by a deterministic key.
struct Cand {
    area: f32,
    key: (u8, u32),
    child: Child,
}
impl PartialEq for Cand {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Cand {}
impl PartialOrd for Cand {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Cand {
    fn cmp(&self, o: &Self) -> Ordering {
        self.area
            .total_cmp(&o.area)
            .then_with(|| o.key.cmp(&self.key))
    }
}

fn key(c: Child) -> (u8, u32) {
    match c {
        Child::Inner(i) => (0, i),
        Child::Leaf { first, .. } => (1, first),
    }
}

struct Builder<'a> {
    bvh: &'a Bvh,
    budget: u32,
    /// Subtree bytes of every inner node.
    sub: Vec<u32>,
    segs: Vec<Segment>,
    /// For each segment, the roots it cut (in cut order).
    cuts: Vec<Vec<Child>>,
}

impl Builder<'_> {
    fn subtree(&self, c: Child) -> u32 {
        match c {
            Child::Inner(i) => self.sub[i as usize],
            leaf => cost(leaf),
        }
    }

    /// Grows a new segment from `roots` (bounds given); returns its index.
    fn grow(&mut self, roots: Vec<(Child, crate::geom::Aabb)>, parent: Option<u32>) -> usize {
        let mut seg = Segment {
            id: 0,
            parent,
            children: Vec::new(),
            roots: roots.iter().map(|r| r.0).collect(),
            nodes: Vec::new(),
            leaves: Vec::new(),
            tri_count: 0,
            bytes: SEGMENT_HEADER_BYTES,
        };
        let mut cut = Vec::new();
        let mut heap: BinaryHeap<Cand> = roots
            .iter()
            .map(|&(c, b)| Cand {
                area: b.surface_area(),
                key: key(c),
                child: c,
            })
            .collect();
        let mut first = true;
        while let Some(Cand { child, .. }) = heap.pop() {
            let c = cost(child);
            // The first root is always taken (the budget admits one node + one leaf).
            if !first && seg.bytes + c > self.budget {
                cut.push(child);
                continue;
            }
            first = false;
            seg.bytes += c;
            match child {
                Child::Inner(i) => {
                    seg.nodes.push(i);
                    let n = &self.bvh.nodes[i as usize];
                    for s in 0..2 {
                        heap.push(Cand {
                            area: n.child_bounds[s].surface_area(),
                            key: key(n.children[s]),
                            child: n.children[s],
                        });
                    }
                }
                Child::Leaf { count, .. } => {
                    seg.leaves.push(child);
                    seg.tri_count += count;
                }
            }
        }
        let idx = self.segs.len();
        self.segs.push(seg);
        self.cuts.push(cut);
        idx
    }
}

impl Segmentation {
    /// The most traversal-stack entries a ray can need inside any one segment
    /// (the stack starts afresh in each): a ray pops a node and pushes both
    /// children, so after a node `L` levels below its segment's entry the stack
    /// holds at most `L + 2` entries.
    pub fn stack_bound(&self, bvh: &Bvh) -> u32 {
        let mut seg_of = vec![u32::MAX; bvh.nodes.len()];
        for s in &self.segments {
            for &n in &s.nodes {
                seg_of[n as usize] = s.id;
            }
        }
        let mut most = 1;
        let mut todo: Vec<(u32, u32)> = Vec::new();
        for s in &self.segments {
            for &r in &s.roots {
                if let Child::Inner(i) = r {
                    todo.push((i, 0));
                }
            }
            while let Some((i, level)) = todo.pop() {
                most = most.max(level + 2);
                for c in bvh.nodes[i as usize].children {
                    if let Child::Inner(j) = c
                        && seg_of[j as usize] == s.id
                    {
                        todo.push((j, level + 1));
                    }
                }
            }
        }
        most
    }

    /// Partitions `bvh` into segments of at most `budget` bytes.
    pub fn build(bvh: &Bvh, budget: u32) -> Result<Segmentation, super::AccelError> {
        let max_leaf = bvh
            .nodes
            .iter()
            .flat_map(|n| n.children)
            .chain([bvh.root])
            .map(|c| {
                if let Child::Leaf { count, .. } = c {
                    count
                } else {
                    0
                }
            })
            .max()
            .unwrap_or(1);
        let min = SEGMENT_HEADER_BYTES + NODE_BYTES + TRI_BYTES * max_leaf;
        if budget < min {
            return Err(super::AccelError::SegmentTooSmall { budget, min });
        }
        // Subtree sizes, bottom-up (nodes are parent-before-child).
        let mut sub = vec![0u32; bvh.nodes.len()];
        for i in (0..bvh.nodes.len()).rev() {
            let mut s = NODE_BYTES;
            for c in bvh.nodes[i].children {
                s = s.saturating_add(match c {
                    Child::Inner(j) => sub[j as usize],
                    leaf => cost(leaf),
                });
            }
            sub[i] = s;
        }
        // Bounds of every child reference, for area priority of cut roots.
        let mut child_box = std::collections::HashMap::new();
        for n in &bvh.nodes {
            for s in 0..2 {
                child_box.insert(key(n.children[s]), n.child_bounds[s]);
            }
        }
        child_box.insert(key(bvh.root), bvh.bounds);
        let boxed = |c: Child| (c, child_box[&key(c)]);

        let mut b = Builder {
            bvh,
            budget,
            sub,
            segs: Vec::new(),
            cuts: Vec::new(),
        };
        b.grow(vec![boxed(bvh.root)], None);
        let mut next = 0;
        while next < b.segs.len() {
            let parent = next;
            next += 1;
            let mut cut = std::mem::take(&mut b.cuts[parent]);
            cut.sort_by(|x, y| {
                child_box[&key(*y)]
                    .surface_area()
                    .total_cmp(&child_box[&key(*x)].surface_area())
                    .then(key(*x).cmp(&key(*y)))
            });
            let mut remaining: std::collections::VecDeque<Child> = cut.into();
            while let Some(seed) = remaining.pop_front() {
                let si = b.grow(vec![boxed(seed)], Some(parent as u32));
                b.segs[parent].children.push(si as u32);
                // Whole subtree taken: pack other whole subtrees of the same parent.
                if b.cuts[si].is_empty() {
                    let mut keep = std::collections::VecDeque::new();
                    while let Some(c) = remaining.pop_front() {
                        let need = b.subtree(c);
                        if b.segs[si].bytes + need <= budget {
                            let extra = b.grow(vec![boxed(c)], None);
                            let e = b.segs.pop().expect("just grown");
                            b.cuts.pop();
                            debug_assert_eq!(extra, b.segs.len());
                            let s = &mut b.segs[si];
                            s.roots.extend(e.roots);
                            s.nodes.extend(e.nodes);
                            s.leaves.extend(e.leaves);
                            s.tri_count += e.tri_count;
                            s.bytes += e.bytes - SEGMENT_HEADER_BYTES;
                        } else {
                            keep.push_back(c);
                        }
                    }
                    remaining = keep;
                }
            }
        }
        // Renumber in depth-first pre-order.
        let mut order = Vec::with_capacity(b.segs.len());
        let mut stack = vec![0usize];
        while let Some(s) = stack.pop() {
            order.push(s);
            for &c in b.segs[s].children.iter().rev() {
                stack.push(c as usize);
            }
        }
        let mut new_id = vec![0u32; b.segs.len()];
        for (k, &s) in order.iter().enumerate() {
            new_id[s] = k as u32;
        }
        let mut segments: Vec<Segment> = order
            .iter()
            .map(|&s| {
                let mut g = b.segs[s].clone();
                g.id = new_id[s];
                g.parent = g.parent.map(|p| new_id[p as usize]);
                g.children = g.children.iter().map(|&c| new_id[c as usize]).collect();
                g
            })
            .collect();
        segments.sort_by_key(|s| s.id);
        Ok(Segmentation { segments, budget })
    }
}
