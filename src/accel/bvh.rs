//! The BVH2 of a scene, built with obvhs and flattened into our own node array.
//!
//! obvhs builds the tree (PLOC with reinsertion); we copy its topology into a
//! depth-first array and recompute every box exactly from our triangles with f32
//! min/max, so the boxes are tight and identical on every machine whatever obvhs
//! did internally. One triangle per leaf by default (`max_prims_per_leaf`).

use std::time::{Duration, Instant};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::geom::{Aabb, Triangle};

/// obvhs build presets, named as obvhs names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum BuildPreset {
    FastestBuild,
    VeryFastBuild,
    FastBuild,
    #[default]
    MediumBuild,
    SlowBuild,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BvhCfg {
    pub preset: BuildPreset,
    /// Triangles per leaf (1 as in the paper's TRaX BVHs).
    pub max_prims_per_leaf: u32,
}

impl Default for BvhCfg {
    fn default() -> Self {
        BvhCfg {
            preset: BuildPreset::MediumBuild,
            max_prims_per_leaf: 1,
        }
    }
}

impl BvhCfg {
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=128).contains(&self.max_prims_per_leaf) {
            return Err(format!(
                "bvh.max_prims_per_leaf = {} is outside 1..=128 (a leaf reference holds up to 128 triangles)",
                self.max_prims_per_leaf
            ));
        }
        Ok(())
    }
}

/// A child of an inner node: another inner node or a leaf (a run of triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Child {
    Inner(u32),
    /// `first` indexes `Bvh::tri_order`; the triangles are `tri_order[first..first+count]`.
    Leaf {
        first: u32,
        count: u32,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub bounds: Aabb,
    pub children: [Child; 2],
    pub child_bounds: [Aabb; 2],
}

/// The flattened BVH: inner nodes in depth-first order (node 0 is the root, a
/// parent before its children), leaves as runs of `tri_order`.
#[derive(Clone, Debug)]
pub struct Bvh {
    pub nodes: Vec<Node>,
    /// Scene triangle ids in leaf order.
    pub tri_order: Vec<u32>,
    /// The root: an inner node, or a single leaf for a tiny scene.
    pub root: Child,
    pub bounds: Aabb,
    pub depth: u32,
    pub build_time: Duration,
}

fn leaf_bounds(tris: &[Triangle], ids: &[u32]) -> Aabb {
    let mut b = Aabb::empty();
    for &i in ids {
        let t = &tris[i as usize];
        for v in [t.v0, t.v1, t.v2] {
            b.grow(v);
        }
    }
    b
}

impl Bvh {
    /// Builds the BVH of `tris` (which must be non-empty and valid).
    pub fn build(tris: &[Triangle], cfg: &BvhCfg) -> Result<Bvh, String> {
        cfg.validate()?;
        if tris.is_empty() {
            return Err("cannot build a BVH of zero triangles; the scene has no geometry".into());
        }
        let start = Instant::now();
        let otris: Vec<obvhs::triangle::Triangle> = tris
            .iter()
            .map(|t| obvhs::triangle::Triangle {
                v0: t.v0.into(),
                v1: t.v1.into(),
                v2: t.v2.into(),
            })
            .collect();
        let mut params = match cfg.preset {
            BuildPreset::FastestBuild => obvhs::BvhBuildParams::fastest_build(),
            BuildPreset::VeryFastBuild => obvhs::BvhBuildParams::very_fast_build(),
            BuildPreset::FastBuild => obvhs::BvhBuildParams::fast_build(),
            BuildPreset::MediumBuild => obvhs::BvhBuildParams::medium_build(),
            BuildPreset::SlowBuild => obvhs::BvhBuildParams::slow_build(),
        };
        params.max_prims_per_leaf = cfg.max_prims_per_leaf;
        // Spatial splits would reference one triangle from several leaves; the
        // treelet invariant (every triangle in exactly one treelet) forbids that.
        params.pre_split = false;
        let ob =
            obvhs::bvh2::builder::build_bvh2_from_tris(&otris, params, &mut Duration::default());

        let mut bvh = Bvh {
            nodes: Vec::new(),
            tri_order: Vec::new(),
            root: Child::Inner(0),
            bounds: Aabb::empty(),
            depth: 0,
            build_time: Duration::ZERO,
        };
        // Depth-first copy with an explicit stack (deep trees must not overflow).
        // Each entry: obvhs node index, slot to patch (parent, side), depth.
        let leaf_of = |bvh: &mut Bvh, on: &obvhs::bvh2::node::Bvh2Node| -> (Child, Aabb) {
            let first = bvh.tri_order.len() as u32;
            let ids: Vec<u32> = (on.first_index..on.first_index + on.prim_count)
                .map(|k| ob.primitive_indices[k as usize])
                .collect();
            let b = leaf_bounds(tris, &ids);
            bvh.tri_order.extend_from_slice(&ids);
            (
                Child::Leaf {
                    first,
                    count: on.prim_count,
                },
                b,
            )
        };
        let root = &ob.nodes[0];
        if root.is_leaf() {
            let (c, b) = leaf_of(&mut bvh, root);
            bvh.root = c;
            bvh.bounds = b;
            bvh.depth = 1;
            bvh.build_time = start.elapsed();
            return Ok(bvh);
        }
        // (obvhs node, slot in the parent to patch: (node, side), depth)
        type Pending = (usize, Option<(u32, usize)>, u32);
        let mut stack: Vec<Pending> = vec![(0, None, 1)];
        while let Some((oi, slot, depth)) = stack.pop() {
            let on = &ob.nodes[oi];
            bvh.depth = bvh.depth.max(depth);
            let me = bvh.nodes.len() as u32;
            bvh.nodes.push(Node {
                bounds: Aabb::empty(),
                children: [Child::Inner(u32::MAX); 2],
                child_bounds: [Aabb::empty(); 2],
            });
            if let Some((p, side)) = slot {
                bvh.nodes[p as usize].children[side] = Child::Inner(me);
            }
            // Right first on the stack so the left subtree is laid out first.
            for side in [1usize, 0] {
                let ci = on.first_index as usize + side;
                let cn = &ob.nodes[ci];
                if cn.is_leaf() {
                    let (c, _) = leaf_of(&mut bvh, cn);
                    bvh.nodes[me as usize].children[side] = c;
                } else {
                    stack.push((ci, Some((me, side)), depth + 1));
                }
            }
        }
        // The leaves were appended in an interleaved order; that is fine (tri_order
        // is only an indirection), but boxes must now be computed bottom-up. Nodes
        // are in parent-before-child order, so a reverse sweep sees children first.
        for i in (0..bvh.nodes.len()).rev() {
            let mut nb = Aabb::empty();
            for side in 0..2 {
                let b = match bvh.nodes[i].children[side] {
                    Child::Inner(c) => bvh.nodes[c as usize].bounds,
                    Child::Leaf { first, count } => leaf_bounds(
                        tris,
                        &bvh.tri_order[first as usize..(first + count) as usize],
                    ),
                };
                bvh.nodes[i].child_bounds[side] = b;
                nb = nb.union(&b);
            }
            bvh.nodes[i].bounds = nb;
        }
        bvh.bounds = bvh.nodes[0].bounds;
        bvh.build_time = start.elapsed();
        Ok(bvh)
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes
            .iter()
            .flat_map(|n| n.children)
            .filter(|c| matches!(c, Child::Leaf { .. }))
            .count()
            + matches!(self.root, Child::Leaf { .. }) as usize
    }
}

/// Bounding box of a point set (for tests).
pub fn bounds_of(points: &[Vec3]) -> Aabb {
    Aabb::from_points(points.iter().copied())
}
