//! The BVH2 of a scene, built with obvhs and flattened into our own node array.
//!
//! obvhs builds the tree (PLOC with reinsertion; the PLOC passes run in our
//! copy, [`super::ploc`], which stops a build that does not converge and falls
//! back to binned SAH, [`super::sah`]); we copy its topology into a
//! depth-first array and recompute every box exactly from our triangles with f32
//! min/max, so the boxes are tight and identical on every machine whatever obvhs
//! did internally. One triangle per leaf by default (`max_prims_per_leaf`).

use std::time::{Duration, Instant};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::ploc;
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
    /// obvhs build preset: fastest_build, very_fast_build, fast_build,
    /// medium_build (default), slow_build, ...: build time against tree quality.
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
    pub fn validate(&self) -> Result<(), super::AccelError> {
        if !(1..=128).contains(&self.max_prims_per_leaf) {
            return Err(super::AccelError::Invalid(format!(
                "bvh.max_prims_per_leaf = {} is outside 1..=128 (a leaf reference holds up to 128 triangles)",
                self.max_prims_per_leaf
            )));
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
    pub builder: BvhBuilder,
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

/// Which builder made a BVH.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BvhBuilder {
    /// obvhs's PLOC with reinsertion (every ordinary scene).
    Ploc,
    /// The bounded fallback ([`super::sah`]), and why PLOC was not used.
    BinnedSah { reason: String },
}

/// PLOC's passes may visit this many nodes per triangle in total before the
/// build falls back to binned SAH. Ordinary meshes need 3.1 to 3.8 (the
/// builtins, the Cornell box, Dragon, Dragon Box, both Sponzas, Conference,
/// Bunny, Armadillo, Buddha, Lucy), flat grids, stacked planes and long strips
/// up to 4.5; a fan of 100K thin triangles needs thousands.
pub const PLOC_WORK_PER_TRIANGLE: u64 = 16;

/// A PLOC tree deeper than this many levels per level of a balanced tree
/// (`ceil(log2 n)`, and at least 64 levels) is rebuilt by the fallback.
/// The meshes of [`PLOC_WORK_PER_TRIANGLE`] reach 0.7 to 2.3 (Conference: 44
/// levels for 277K triangles).
pub const DEPTH_PER_BALANCED_LEVEL: u32 = 4;

/// The deepest PLOC tree kept for `n` triangles.
pub fn depth_limit(n: usize) -> u32 {
    let balanced = usize::BITS - (n.max(2) - 1).leading_zeros();
    (DEPTH_PER_BALANCED_LEVEL * balanced).max(64)
}

/// The fallback tree with obvhs's leaf collapsing, as the PLOC path has it.
fn sah_fallback(
    aabbs: &[obvhs::aabb::Aabb],
    cfg: &BvhCfg,
    params: &obvhs::BvhBuildParams,
) -> obvhs::bvh2::Bvh2 {
    let (mut ob, _) = super::sah::build(aabbs);
    obvhs::bvh2::leaf_collapser::collapse(
        &mut ob,
        cfg.max_prims_per_leaf,
        params.collapse_traversal_cost,
    );
    ob
}

impl Bvh {
    /// Builds the BVH of `tris` (which must be non-empty and valid).
    pub fn build(tris: &[Triangle], cfg: &BvhCfg) -> Result<Bvh, super::AccelError> {
        cfg.validate()?;
        if tris.is_empty() {
            return Err(super::AccelError::NoTriangles);
        }
        let start = Instant::now();
        let aabbs: Vec<obvhs::aabb::Aabb> = tris
            .iter()
            .map(|t| {
                obvhs::triangle::Triangle {
                    v0: t.v0.into(),
                    v1: t.v1.into(),
                    v2: t.v2.into(),
                }
                .aabb()
            })
            .collect();
        let params = match cfg.preset {
            BuildPreset::FastestBuild => obvhs::BvhBuildParams::fastest_build(),
            BuildPreset::VeryFastBuild => obvhs::BvhBuildParams::very_fast_build(),
            BuildPreset::FastBuild => obvhs::BvhBuildParams::fast_build(),
            BuildPreset::MediumBuild => obvhs::BvhBuildParams::medium_build(),
            BuildPreset::SlowBuild => obvhs::BvhBuildParams::slow_build(),
        };
        let n = tris.len();
        let budget = PLOC_WORK_PER_TRIANGLE * n as u64;
        let fallback = |reason: String| {
            let ob = sah_fallback(&aabbs, cfg, &params);
            (flatten(&ob, tris), BvhBuilder::BinnedSah { reason })
        };
        let (mut bvh, builder) = match ploc::build(
            params.ploc_search_distance,
            &aabbs,
            params.sort_precision,
            params.search_depth_threshold,
            budget,
        ) {
            Some(mut ob) => {
                // The rest of obvhs's build_bvh2_from_tris, without pre-splitting:
                // spatial splits would reference one triangle from several leaves,
                // and the treelet invariant (every triangle in exactly one treelet)
                // forbids that.
                let mut reinsertion = obvhs::bvh2::reinsertion::ReinsertionOptimizer::default();
                reinsertion.run(&mut ob, params.reinsertion_batch_ratio, None);
                obvhs::bvh2::leaf_collapser::collapse(
                    &mut ob,
                    cfg.max_prims_per_leaf,
                    params.collapse_traversal_cost,
                );
                reinsertion.run(
                    &mut ob,
                    params.reinsertion_batch_ratio
                        * params.post_collapse_reinsertion_batch_ratio_multiplier,
                    None,
                );
                let bvh = flatten(&ob, tris);
                if bvh.depth > depth_limit(n) {
                    fallback(format!(
                        "the PLOC tree is {} levels deep, over the limit of {} for {n} triangles",
                        bvh.depth,
                        depth_limit(n)
                    ))
                } else {
                    (bvh, BvhBuilder::Ploc)
                }
            }
            None => fallback(format!(
                "PLOC stopped converging (over {PLOC_WORK_PER_TRIANGLE} node visits per triangle)"
            )),
        };
        bvh.builder = builder;
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

/// Copies obvhs's topology into a depth-first node array and recomputes every box
/// exactly from `tris`.
fn flatten(ob: &obvhs::bvh2::Bvh2, tris: &[Triangle]) -> Bvh {
    let mut bvh = Bvh {
        nodes: Vec::new(),
        tri_order: Vec::new(),
        root: Child::Inner(0),
        bounds: Aabb::empty(),
        depth: 0,
        build_time: Duration::ZERO,
        builder: BvhBuilder::Ploc,
    };
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
        return bvh;
    }
    // Depth-first copy with an explicit stack (deep trees must not overflow).
    // Each entry: obvhs node index, slot in the parent to patch (node, side), depth.
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
    bvh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::shapes::uv_sphere;

    use crate::geom::shapes::random_spheres as spheres;

    /// What `Bvh::build` made before PLOC ran in our copy: obvhs's whole builder.
    fn obvhs_bvh(tris: &[Triangle], cfg: &BvhCfg) -> Bvh {
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
        params.pre_split = false;
        let ob =
            obvhs::bvh2::builder::build_bvh2_from_tris(&otris, params, &mut Duration::default());
        flatten(&ob, tris)
    }

    fn same(a: &Bvh, b: &Bvh) -> bool {
        a.root == b.root
            && a.tri_order == b.tri_order
            && a.depth == b.depth
            && a.nodes.len() == b.nodes.len()
            && a.nodes.iter().zip(&b.nodes).all(|(x, y)| x == y)
    }

    /// Ordinary inputs get exactly the tree obvhs builds, in every preset.
    #[test]
    fn ordinary_scenes_get_obvhs_tree() {
        let presets = [
            BuildPreset::FastestBuild,
            BuildPreset::VeryFastBuild,
            BuildPreset::FastBuild,
            BuildPreset::MediumBuild,
            BuildPreset::SlowBuild,
        ];
        let scenes = [
            spheres(12, 3),
            // A room: big walls around small boxes and a ball.
            [
                crate::geom::shapes::box_mesh(Vec3::splat(-5.0), Vec3::splat(5.0)),
                crate::geom::shapes::box_mesh(
                    Vec3::new(-3.0, -5.0, -2.0),
                    Vec3::new(-1.0, -1.0, 0.0),
                ),
                crate::geom::shapes::box_mesh(Vec3::new(1.0, -5.0, 0.5), Vec3::new(2.5, -3.5, 2.0)),
                uv_sphere(Vec3::new(0.0, 2.0, 0.0), 1.5, 16, 32),
            ]
            .concat(),
            spheres(1, 9)[..3].to_vec(),
        ];
        for tris in &scenes {
            for preset in presets {
                for leaf in [1, 4] {
                    let cfg = BvhCfg {
                        preset,
                        max_prims_per_leaf: leaf,
                    };
                    let got = Bvh::build(tris, &cfg).unwrap();
                    assert_eq!(got.builder, BvhBuilder::Ploc);
                    assert!(
                        same(&got, &obvhs_bvh(tris, &cfg)),
                        "{} triangles, {preset:?}, {leaf} per leaf",
                        tris.len()
                    );
                }
            }
        }
    }

    #[test]
    fn depth_limit_follows_the_balanced_depth() {
        assert_eq!(depth_limit(1), 64);
        assert_eq!(depth_limit(1 << 16), 64);
        assert_eq!(depth_limit((1 << 16) + 1), 68);
        assert_eq!(depth_limit(871_306), 80);
    }
}
