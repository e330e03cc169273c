//! BVH and treelet invariants, and the scene stream written by the data contract.

use std::collections::HashSet;

use dualstream::accel::{
    AccelCfg, AccelError, Bvh, BvhBuilder, BvhCfg, Child, SceneImage, Segmentation,
};
use dualstream::contract::{
    MemoryMap, MemoryMapCfg, NODE_BYTES, NodeRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES,
    SEGMENT_MAGIC, SegEntry, SparseMem, TRI_BYTES, TriRec,
};
use dualstream::geom::{Aabb, Triangle, ray_triangle};
use dualstream::render::traverse::reference_trace;
use dualstream::util::rng::Rng;
use glam::Vec3;

use dualstream::geom::shapes::random_spheres as spheres;

fn check(tris: &[Triangle], budget: u32, leaf: u32) {
    let bvh = Bvh::build(
        tris,
        &BvhCfg {
            max_prims_per_leaf: leaf,
            ..BvhCfg::default()
        },
    )
    .unwrap();
    check_bvh(tris, &bvh, budget, leaf);
}

/// The invariants of a built BVH, its segments and their DRAM image.
fn check_bvh(tris: &[Triangle], bvh: &Bvh, budget: u32, leaf: u32) {
    // Every triangle in exactly one leaf; boxes contain their children.
    let mut seen: Vec<u32> = bvh.tri_order.clone();
    seen.sort();
    assert_eq!(seen, (0..tris.len() as u32).collect::<Vec<_>>());
    for n in &bvh.nodes {
        for s in 0..2 {
            let cb = n.child_bounds[s];
            assert_eq!(n.bounds.union(&cb), n.bounds);
            if let Child::Leaf { first, count } = n.children[s] {
                assert!(count <= leaf);
                for &id in &bvh.tri_order[first as usize..(first + count) as usize] {
                    assert_eq!(
                        cb.union(&tris[id as usize].aabb()),
                        cb,
                        "leaf box holds its triangle"
                    );
                }
            }
        }
    }
    let seg = Segmentation::build(bvh, budget).unwrap();
    let mut node_seen = vec![0u32; bvh.nodes.len()];
    let mut tri_seen = 0u32;
    for (i, s) in seg.segments.iter().enumerate() {
        assert_eq!(s.id as usize, i);
        assert!(
            s.bytes <= budget,
            "segment {} has {} B > {budget}",
            s.id,
            s.bytes
        );
        assert_eq!(
            s.bytes,
            SEGMENT_HEADER_BYTES + NODE_BYTES * s.nodes.len() as u32 + TRI_BYTES * s.tri_count
        );
        for &n in &s.nodes {
            node_seen[n as usize] += 1;
        }
        tri_seen += s.tri_count;
        // Parent before children, children know their parent.
        for &c in &s.children {
            assert!(c > s.id);
            assert_eq!(seg.segments[c as usize].parent, Some(s.id));
        }
        if i == 0 {
            assert_eq!(s.parent, None);
        } else {
            assert!(s.parent.unwrap() < s.id);
        }
    }
    assert!(
        node_seen.iter().all(|&k| k == 1),
        "every node in exactly one segment"
    );
    assert_eq!(tri_seen as usize, tris.len());
    // Depth-first pre-order: a segment's subtree is a contiguous id range.
    let n = seg.segments.len();
    let mut end = vec![0usize; n];
    for i in (0..n).rev() {
        end[i] = seg.segments[i]
            .children
            .iter()
            .map(|&c| end[c as usize])
            .max()
            .unwrap_or(i)
            .max(i);
    }
    for s in &seg.segments {
        let mut expect = s.id as usize + 1;
        for &c in &s.children {
            assert_eq!(c as usize, expect, "children of {} in DFS order", s.id);
            expect = end[c as usize] + 1;
        }
    }

    // The DRAM image.
    let cfg = MemoryMapCfg::default();
    let bytes: Vec<u32> = seg.segments.iter().map(|s| s.bytes).collect();
    let map = MemoryMap::new(
        &cfg,
        &bytes,
        SceneImage::children_total(&seg),
        tris.len() as u64,
        1,
        16,
    )
    .unwrap();
    let mut mem = SparseMem::new(map.capacity);
    let mats = vec![0u32; tris.len()];
    let img = SceneImage::write(&mut mem, &map, tris, &mats, bvh, &seg);
    let mut tri_ids = HashSet::new();
    for s in &seg.segments {
        let base = img.seg_base[s.id as usize];
        assert_eq!(base % cfg.row_bytes, 0, "row-aligned");
        assert_eq!(mem.read_u32(base), SEGMENT_MAGIC);
        let e = SegEntry::read(&mem, map.seg_entry_addr(s.id));
        assert_eq!(
            (e.base, e.bytes, e.nodes, e.tris),
            (base, s.bytes, s.nodes.len() as u32, s.tri_count)
        );
        let kids: Vec<u32> = (0..e.child_count)
            .map(|k| mem.read_u32(map.child_list + (e.first_child + k) as u64 * 4))
            .collect();
        assert_eq!(kids, s.children);
        for k in 0..e.nodes {
            let r = NodeRec::read(&mem, base + 64 + k as u64 * 64);
            for side in 0..2 {
                let target = if r.seg[side] == SEG_SAME {
                    s.id
                } else {
                    r.seg[side]
                };
                if r.seg[side] != SEG_SAME {
                    assert!(
                        s.children.contains(&target),
                        "exits lead only to child segments"
                    );
                }
                let te = SegEntry::read(&mem, map.seg_entry_addr(target));
                match Ref::decode(r.child[side]) {
                    Ref::Node(i) => assert!(i < te.nodes),
                    Ref::Leaf { first, count } => assert!(first + count <= te.tris),
                    Ref::None => panic!("BVH2 inner nodes have two children"),
                }
            }
        }
        for k in 0..e.tris {
            let t = TriRec::read(&mem, base + 64 + e.nodes as u64 * 64 + k as u64 * 48);
            let src = &tris[t.tri_id as usize];
            assert_eq!(t.v, [src.v0, src.v1, src.v2]);
            assert!(tri_ids.insert(t.tri_id), "each triangle stored once");
            let at = base + 64 + e.nodes as u64 * 64 + k as u64 * 48;
            assert_eq!(
                map.scene + mem.read_u32(map.tri_index + t.tri_id as u64 * 4) as u64 * 16,
                at,
                "triangle index"
            );
        }
    }
    assert_eq!(tri_ids.len(), tris.len());
}

#[test]
fn treelet_invariants_on_spheres() {
    let tris = spheres(40, 1); // ~23K triangles
    check(&tris, 64 << 10, 1);
    check(&tris, 8 << 10, 1);
    check(&tris, 16 << 10, 4);
}

#[test]
fn tiny_scenes() {
    let one = vec![Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y)];
    let bvh = Bvh::build(&one, &BvhCfg::default()).unwrap();
    assert!(matches!(bvh.root, Child::Leaf { count: 1, .. }));
    let seg = Segmentation::build(&bvh, 8192).unwrap();
    assert_eq!(seg.segments.len(), 1);
    check(&spheres(1, 2)[..3], 8192, 1);
}

#[test]
fn bad_sizes_are_named() {
    let tris = spheres(1, 3);
    let bvh = Bvh::build(&tris, &BvhCfg::default()).unwrap();
    let e = Segmentation::build(&bvh, 100).unwrap_err();
    assert!(
        matches!(e, AccelError::SegmentTooSmall { budget: 100, .. }),
        "{e:?}"
    );
    assert!(e.to_string().contains("cannot hold"), "{e}");
    let e = AccelCfg {
        segment_bytes: 10_000,
        ..AccelCfg::default()
    }
    .validate(8192)
    .unwrap_err()
    .to_string();
    assert!(e.contains("multiple of the DRAM row"), "{e}");
    assert!(matches!(
        Bvh::build(&[], &BvhCfg::default()),
        Err(AccelError::NoTriangles)
    ));
    let e = BvhCfg {
        max_prims_per_leaf: 0,
        ..BvhCfg::default()
    }
    .validate()
    .unwrap_err()
    .to_string();
    assert!(e.contains("max_prims_per_leaf"));
}

#[test]
fn build_is_deterministic() {
    let tris = spheres(10, 4);
    let a = Bvh::build(&tris, &BvhCfg::default()).unwrap();
    let b = Bvh::build(&tris, &BvhCfg::default()).unwrap();
    assert_eq!(a.tri_order, b.tri_order);
    assert_eq!(a.nodes, b.nodes);
    let _ = Aabb::empty();
}

/// A polygon of `n` vertices on the unit circle triangulated as a fan from
/// vertex 0, as an OBJ `f` line of all of them loads: thin triangles sharing one
/// vertex, their boxes overlapping.
fn fan(n: usize) -> Vec<Triangle> {
    let p = |i: usize| {
        let (s, c) = dualstream::geom::shapes::sin_cos(i as f64 / n as f64 * std::f64::consts::TAU);
        Vec3::new(c as f32, s as f32, 0.0)
    };
    (1..n - 1)
        .map(|i| Triangle::new(p(0), p(i), p(i + 1)))
        .filter(|t| !t.is_degenerate())
        .collect()
}

/// PLOC stalls on the fan (a minute and a tree 25K levels deep for 100K
/// vertices); the build falls back to binned SAH and stays fast and shallow,
/// shallow enough for the TP's stack (42 entries by default).
#[test]
fn a_fan_of_thin_triangles_builds_fast_and_shallow() {
    let tris = fan(100_000);
    assert!(tris.len() > 99_990);
    // Against a well-behaved soup of as many triangles, built in the same run:
    // a ratio holds on a busy machine where a wall-clock bound does not (about
    // 4x with the fallback in a debug build; PLOC alone takes about a minute).
    let mut rng = Rng::new(3);
    let soup: Vec<Triangle> = (0..tris.len())
        .map(|_| {
            let c = Vec3::new(
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
            );
            let e = |r: &mut Rng| {
                Vec3::new(
                    r.range_f32(0.0, 0.01),
                    r.range_f32(0.0, 0.01),
                    r.range_f32(0.0, 0.01),
                )
            };
            Triangle::new(c, c + e(&mut rng), c + e(&mut rng))
        })
        .collect();
    let t0 = std::time::Instant::now();
    Bvh::build(&soup, &BvhCfg::default()).unwrap();
    let soup_secs = t0.elapsed().as_secs_f64();
    let t0 = std::time::Instant::now();
    let bvh = Bvh::build(&tris, &BvhCfg::default()).unwrap();
    let secs = t0.elapsed().as_secs_f64();
    assert!(
        secs < 10.0 * soup_secs + 0.5,
        "the fan took {secs:.2} s to build, a soup of as many triangles {soup_secs:.2} s"
    );
    assert!(
        matches!(&bvh.builder, BvhBuilder::BinnedSah { reason } if reason.contains("PLOC")),
        "{:?}",
        bvh.builder
    );
    // SAH levels (48), then medians: ceil(log2 n) more at most.
    assert!(bvh.depth <= 48 + 17, "depth {}", bvh.depth);
    check_bvh(&tris, &bvh, 64 << 10, 1);
    // The tree finds the closest hit, as a test of every triangle does.
    let mut rng = Rng::new(8);
    for _ in 0..40 {
        let o = Vec3::new(rng.range_f32(-1.5, 1.5), rng.range_f32(-1.5, 1.5), 2.0);
        let aim = Vec3::new(rng.range_f32(-1.0, 1.0), rng.range_f32(-1.0, 1.0), 0.0);
        let d = aim - o;
        let got = reference_trace(&bvh, &tris, o, d, false);
        let want = tris
            .iter()
            .enumerate()
            .filter_map(|(i, t)| ray_triangle(o, d, 0.0, f32::INFINITY, t).map(|h| (h.t, i as u32)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        match want {
            Some((t, id)) => assert_eq!((got.t, got.tri_id), (t, id), "ray {o} {d}"),
            None => assert!(!got.is_hit(), "ray {o} {d}"),
        }
    }
    let seg = Segmentation::build(&bvh, 64 << 10).unwrap();
    let tp_stack = dualstream::units::tm::TmCfg::default().stack_entries();
    assert!(
        seg.stack_bound(&bvh) <= tp_stack,
        "{}",
        seg.stack_bound(&bvh)
    );
    // The fallback keeps leaf sizes: up to 4 per leaf when asked.
    let four = BvhCfg {
        max_prims_per_leaf: 4,
        ..BvhCfg::default()
    };
    let small = fan(3000);
    let b4 = Bvh::build(&small, &four).unwrap();
    assert!(matches!(b4.builder, BvhBuilder::BinnedSah { .. }));
    check_bvh(&small, &b4, 16 << 10, 4);
}

/// Deepest stack of a traversal of every segment in which every box is hit (the
/// worst case for the stack), pushing children as the TP does (inner nodes,
/// leaves and exits alike), the child leading deepest into the segment on top:
/// the order in which the stack grows most.
fn deepest_first_stack(bvh: &Bvh, seg: &Segmentation) -> u32 {
    let mut most = 0;
    for s in &seg.segments {
        let mine: HashSet<u32> = s.nodes.iter().copied().collect();
        // Levels below each node of the segment, within the segment (children
        // come after parents in the node array, so a reverse sweep sees them first).
        let mut below = std::collections::HashMap::new();
        let mut nodes = s.nodes.clone();
        nodes.sort_unstable();
        for &i in nodes.iter().rev() {
            let h = bvh.nodes[i as usize]
                .children
                .iter()
                .filter_map(|c| match c {
                    Child::Inner(j) if mine.contains(j) => Some(below[j] + 1),
                    _ => None,
                })
                .max()
                .unwrap_or(0);
            below.insert(i, h);
        }
        let depth_of = |c: &Child| match c {
            Child::Inner(j) if mine.contains(j) => below[j] as i64,
            _ => -1,
        };
        for &r in &s.roots {
            let mut stack = vec![r];
            most = most.max(1);
            while let Some(c) = stack.pop() {
                if let Child::Inner(i) = c
                    && mine.contains(&i)
                {
                    let mut kids = bvh.nodes[i as usize].children;
                    kids.sort_by_key(depth_of);
                    stack.extend(kids);
                    most = most.max(stack.len() as u32);
                }
            }
        }
    }
    most
}

/// The stack bound is the deepest stack a traversal of a segment can reach.
#[test]
fn the_stack_bound_is_the_deepest_stack_a_segment_can_need() {
    for (tris, budget) in [
        (spheres(8, 6), 4 << 10),
        (spheres(8, 6), 64 << 10),
        (fan(600), 8 << 10),
    ] {
        let bvh = Bvh::build(&tris, &BvhCfg::default()).unwrap();
        let seg = Segmentation::build(&bvh, budget).unwrap();
        let bound = seg.stack_bound(&bvh);
        assert_eq!(bound, deepest_first_stack(&bvh, &seg));
        assert!(bound >= 3, "the trees are deeper than a node");
    }
}
