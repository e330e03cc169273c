//! BVH and treelet invariants, and the scene stream written by the data contract.

use std::collections::HashSet;

use dualstream::accel::{AccelCfg, Bvh, BvhCfg, Child, SceneImage, Segmentation};
use dualstream::contract::{
    MemoryMap, MemoryMapCfg, NODE_BYTES, NodeRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES,
    SEGMENT_MAGIC, SegEntry, SparseMem, TRI_BYTES, TriRec,
};
use dualstream::geom::shapes::uv_sphere;
use dualstream::geom::{Aabb, Triangle};
use dualstream::util::rng::Rng;
use glam::Vec3;

fn spheres(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = Rng::new(seed);
    let mut t = Vec::new();
    for _ in 0..n {
        let c = Vec3::new(
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
        );
        t.extend(uv_sphere(c, rng.range_f32(0.2, 1.5), 12, 24));
    }
    t
}

fn check(tris: &[Triangle], budget: u32, leaf: u32) {
    let bvh = Bvh::build(
        tris,
        &BvhCfg {
            max_prims_per_leaf: leaf,
            ..BvhCfg::default()
        },
    )
    .unwrap();
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
    let seg = Segmentation::build(&bvh, budget).unwrap();
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
    let img = SceneImage::write(&mut mem, &map, tris, &mats, &bvh, &seg);
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
    assert!(e.contains("cannot hold"), "{e}");
    let e = AccelCfg {
        segment_bytes: 10_000,
        ..AccelCfg::default()
    }
    .validate(8192)
    .unwrap_err();
    assert!(e.contains("multiple of the DRAM row"), "{e}");
    assert!(Bvh::build(&[], &BvhCfg::default()).is_err());
    let e = BvhCfg {
        max_prims_per_leaf: 0,
        ..BvhCfg::default()
    }
    .validate()
    .unwrap_err();
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
