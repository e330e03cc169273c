//! Writes the scene stream into the DRAM image: the segment table, the child list
//! and every segment (header, node records, triangle records), as the data
//! contract specifies.

use glam::Vec3;

use super::bvh::{Bvh, Child};
use super::treelet::Segmentation;
use crate::contract::{
    MemoryMap, NODE_BYTES, NodeRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES, SEGMENT_MAGIC, SegEntry,
    SparseMem, TRI_BYTES, TriRec,
};
use crate::geom::Triangle;

/// Where the scene lives in DRAM.
#[derive(Clone, Debug)]
pub struct SceneImage {
    /// Base address of each segment.
    pub seg_base: Vec<u64>,
    pub seg_bytes: Vec<u32>,
    /// Entry of the root segment (where every new ray starts).
    pub root_entry: Ref,
    pub children_total: u64,
}

/// Location of each BVH piece: (segment, local reference).
struct Loc {
    node: Vec<(u32, u32)>,
    leaf: std::collections::HashMap<u32, (u32, Ref)>,
}

impl Loc {
    fn of(&self, c: Child) -> (u32, Ref) {
        match c {
            Child::Inner(i) => {
                let (s, l) = self.node[i as usize];
                (s, Ref::Node(l))
            }
            Child::Leaf { first, .. } => self.leaf[&first],
        }
    }
}

impl SceneImage {
    pub fn children_total(seg: &Segmentation) -> u64 {
        seg.segments.iter().map(|s| s.children.len() as u64).sum()
    }

    /// Writes everything into `mem` at the addresses of `map`.
    pub fn write(
        mem: &mut SparseMem,
        map: &MemoryMap,
        tris: &[Triangle],
        tri_material: &[u32],
        bvh: &Bvh,
        seg: &Segmentation,
    ) -> SceneImage {
        let mut loc = Loc {
            node: vec![(u32::MAX, 0); bvh.nodes.len()],
            leaf: Default::default(),
        };
        for s in &seg.segments {
            let mut tri = 0u32;
            for (k, &n) in s.nodes.iter().enumerate() {
                loc.node[n as usize] = (s.id, k as u32);
            }
            for &l in &s.leaves {
                if let Child::Leaf { first, count } = l {
                    loc.leaf
                        .insert(first, (s.id, Ref::Leaf { first: tri, count }));
                    tri += count;
                }
            }
        }
        let mut seg_base = Vec::with_capacity(seg.segments.len());
        let mut addr = map.scene;
        let mut child_index = 0u32;
        for s in &seg.segments {
            seg_base.push(addr);
            // Header.
            mem.write_u32(addr, SEGMENT_MAGIC);
            mem.write_u32(addr + 4, s.id);
            mem.write_u32(addr + 8, s.nodes.len() as u32);
            mem.write_u32(addr + 12, s.tri_count);
            mem.write_u32(addr + 16, s.bytes);
            let nodes_at = addr + SEGMENT_HEADER_BYTES as u64;
            for (k, &n) in s.nodes.iter().enumerate() {
                let node = &bvh.nodes[n as usize];
                let mut rec = NodeRec {
                    bmin: [Vec3::ZERO; 2],
                    bmax: [Vec3::ZERO; 2],
                    child: [0; 2],
                    seg: [SEG_SAME; 2],
                };
                for side in 0..2 {
                    let (cs, r) = loc.of(node.children[side]);
                    rec.bmin[side] = node.child_bounds[side].min;
                    rec.bmax[side] = node.child_bounds[side].max;
                    rec.child[side] = r.encode();
                    rec.seg[side] = if cs == s.id { SEG_SAME } else { cs };
                }
                rec.write(mem, nodes_at + k as u64 * NODE_BYTES as u64);
            }
            let mut tri_at = nodes_at + s.nodes.len() as u64 * NODE_BYTES as u64;
            for &l in &s.leaves {
                if let Child::Leaf { first, count } = l {
                    for &id in &bvh.tri_order[first as usize..(first + count) as usize] {
                        let t = &tris[id as usize];
                        TriRec {
                            v: [t.v0, t.v1, t.v2],
                            tri_id: id,
                            material: tri_material[id as usize],
                        }
                        .write(mem, tri_at);
                        mem.write_u32(
                            map.tri_index + id as u64 * 4,
                            ((tri_at - map.scene) / 16) as u32,
                        );
                        tri_at += TRI_BYTES as u64;
                    }
                }
            }
            debug_assert_eq!(
                tri_at - addr,
                s.bytes as u64,
                "segment size matches its records"
            );
            let e = SegEntry {
                base: addr,
                bytes: s.bytes,
                nodes: s.nodes.len() as u32,
                tris: s.tri_count,
                parent: s.parent.unwrap_or(SEG_SAME),
                first_child: child_index,
                child_count: s.children.len() as u32,
            };
            e.write(mem, map.seg_entry_addr(s.id));
            for &c in &s.children {
                mem.write_u32(map.child_list + child_index as u64 * 4, c);
                child_index += 1;
            }
            addr += (s.bytes as u64).div_ceil(map.row_bytes) * map.row_bytes;
        }
        let (_, root_entry) = loc.of(bvh.root);
        SceneImage {
            seg_base,
            seg_bytes: seg.segments.iter().map(|s| s.bytes).collect(),
            root_entry,
            children_total: child_index as u64,
        }
    }
}
