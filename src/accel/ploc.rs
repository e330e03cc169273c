//! obvhs 0.4's PLOC builder (`PlocBuilder::build`, its single-threaded path: the
//! crate is built without its `parallel` feature), vendored from the obvhs 0.4.0
//! crate (our dependency; dual-licensed MIT OR Apache-2.0, whose terms allow a
//! modified copy with this notice) and changed in one place: its merge loop is
//! bounded by a work budget.
//!
//! PLOC merges, in each pass, the nodes that are each other's best neighbour
//! (smallest union area) within a window of the Morton order. On ordinary meshes a
//! good fraction of the nodes pair up in every pass and the passes shrink
//! geometrically. On a fan of long thin triangles sharing one vertex the costs
//! form chains instead of pairs: a pass merges only a few nodes, and the build
//! turns quadratic (100K triangles: 25K passes over ~100K nodes, over a minute,
//! and a tree 25K levels deep). obvhs cannot be stopped from outside, so the loop
//! lives here with a work budget; the result is bit-identical to obvhs's whenever
//! the budget suffices (checked against obvhs in the tests).

use glam::DVec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH};
use obvhs::ploc::morton::{morton_encode_u64_unorm, morton_encode_u128_unorm};
use obvhs::ploc::{PlocSearchDistance, SortPrecision};
use rdst::{RadixKey, RadixSort};

/// Builds the PLOC BVH2 of `aabbs` (one primitive each, indices `0..n`) as
/// obvhs's `PlocBuilder::build` does, or `None` once the passes have visited more
/// than `budget` nodes in total (the sum of the node counts of the passes).
pub(crate) fn build(
    search: PlocSearchDistance,
    aabbs: &[Aabb],
    sort: SortPrecision,
    search_depth_threshold: usize,
    budget: u64,
) -> Option<Bvh2> {
    let t = search_depth_threshold;
    match search {
        PlocSearchDistance::Minimum => build_ploc::<1>(aabbs, sort, t, budget),
        PlocSearchDistance::VeryLow => build_ploc::<2>(aabbs, sort, t, budget),
        PlocSearchDistance::Low => build_ploc::<6>(aabbs, sort, t, budget),
        PlocSearchDistance::Medium => build_ploc::<14>(aabbs, sort, t, budget),
        PlocSearchDistance::High => build_ploc::<24>(aabbs, sort, t, budget),
        PlocSearchDistance::VeryHigh => build_ploc::<32>(aabbs, sort, t, budget),
    }
}

fn build_ploc<const SEARCH_DISTANCE: usize>(
    aabbs: &[Aabb],
    sort: SortPrecision,
    search_depth_threshold: usize,
    budget: u64,
) -> Option<Bvh2> {
    let prim_count = aabbs.len();
    let mut bvh = Bvh2::zeroed(prim_count);
    bvh.reset_for_reuse(prim_count, Some((0..prim_count as u32).collect()));
    if prim_count == 0 {
        return Some(bvh);
    }
    let mut total = Aabb::empty();
    let mut current: Vec<Bvh2Node> = bvh
        .primitive_indices
        .iter()
        .zip(aabbs)
        .map(|(&prim, aabb)| {
            total.extend(aabb.min);
            total.extend(aabb.max);
            Bvh2Node::new(*aabb, 1, prim)
        })
        .collect();

    // build_ploc_from_leaves::<SEARCH_DISTANCE, false>
    let nodes_count = 2 * prim_count - 1;
    bvh.nodes.resize(nodes_count, Bvh2Node::default());
    let mut insert_index = nodes_count;
    let scale = 1.0 / total.diagonal().as_dvec3();
    let offset = -total.min.as_dvec3() * scale;
    let mut next = vec![Bvh2Node::default(); prim_count];
    sort_nodes(sort, &current, &mut next, scale, offset);
    std::mem::swap(&mut current, &mut next);

    let mut merge = vec![0i8; prim_count];
    let mut cache = SearchCache::<SEARCH_DISTANCE>::default();
    let mut depth: usize = 0;
    let mut next_idx = 0;
    let mut count = prim_count;
    let mut work = 0u64;
    while count > 1 {
        work += count as u64;
        if work > budget {
            return None;
        }
        let merge = &mut merge[..count];
        if SEARCH_DISTANCE == 1 || depth < search_depth_threshold {
            let mut last_cost = f32::INFINITY;
            for i in 0..count - 1 {
                let cost = current[i].aabb().union(current[i + 1].aabb()).half_area();
                merge[i] = if last_cost < cost { -1 } else { 1 };
                last_cost = cost;
            }
            merge[count - 1] = -1;
        } else {
            for (index, best) in merge.iter_mut().enumerate() {
                *best = cache.find_best_node(index, &current[..count]);
            }
        }
        let mut index = 0;
        while index < count {
            let index_offset = merge[index] as i64;
            let best_index = (index as i64 + index_offset) as usize;
            // Merged only if both agree on each other.
            if best_index as i64 + merge[best_index] as i64 != index as i64 {
                next[next_idx] = current[index];
                next_idx += 1;
                index += 1;
                continue;
            }
            // Each pair once, at its second member.
            if best_index > index {
                index += 1;
                continue;
            }
            let left = current[index];
            let right = current[best_index];
            insert_index -= 2;
            bvh.nodes[insert_index] = left;
            bvh.nodes[insert_index + 1] = right;
            next[next_idx] = Bvh2Node::new(left.aabb().union(right.aabb()), 0, insert_index as u32);
            next_idx += 1;
            if SEARCH_DISTANCE == 1 && index_offset == 1 {
                index += 2;
            } else {
                index += 1;
            }
        }
        std::mem::swap(&mut next, &mut current);
        count = next_idx;
        next_idx = 0;
        depth += 1;
    }
    debug_assert_eq!(insert_index, 1);
    bvh.nodes[0] = current[0];
    bvh.max_depth = DEFAULT_MAX_STACK_DEPTH.max(depth + 1);
    bvh.children_are_ordered_after_parents = true;
    Some(bvh)
}

/// Union areas of the window, each computed once: `front` stores the costs of a
/// node to its successors, `back` reads them when a successor's turn comes.
#[derive(Clone, Copy)]
struct SearchCache<const SEARCH_DISTANCE: usize>([[f32; SEARCH_DISTANCE]; SEARCH_DISTANCE]);

impl<const SEARCH_DISTANCE: usize> Default for SearchCache<SEARCH_DISTANCE> {
    fn default() -> Self {
        SearchCache([[0.0; SEARCH_DISTANCE]; SEARCH_DISTANCE])
    }
}

impl<const SEARCH_DISTANCE: usize> SearchCache<SEARCH_DISTANCE> {
    fn back(&self, index: usize, other: usize) -> f32 {
        self.0[other % SEARCH_DISTANCE][index % SEARCH_DISTANCE]
    }

    fn front(&mut self, index: usize, other: usize) -> &mut f32 {
        &mut self.0[index % SEARCH_DISTANCE][other % SEARCH_DISTANCE]
    }

    /// Offset of the best neighbour of `index` (ties to the later one).
    fn find_best_node(&mut self, index: usize, nodes: &[Bvh2Node]) -> i8 {
        let mut best_node = index;
        let mut best_cost = f32::INFINITY;
        let begin = index - SEARCH_DISTANCE.min(index);
        let end = (index + SEARCH_DISTANCE + 1).min(nodes.len());
        for other in begin..index {
            let area = self.back(index, other);
            if area <= best_cost {
                best_node = other;
                best_cost = area;
            }
        }
        let ours = nodes[index].aabb();
        for (other, node) in nodes.iter().enumerate().take(end).skip(index + 1) {
            let cost = ours.union(node.aabb()).half_area();
            *self.front(index, other) = cost;
            if cost <= best_cost {
                best_node = other;
                best_cost = cost;
            }
        }
        (best_node as i64 - index as i64) as i8
    }
}

/// obvhs's sort keys, same layout (the radix sort sees only the key, but alike is safest).
#[derive(Clone, Copy)]
#[repr(C)]
struct Morton128 {
    code: u128,
    index: u64,
    padding: u64,
}

impl RadixKey for Morton128 {
    const LEVELS: usize = 16;
    fn get_level(&self, level: usize) -> u8 {
        self.code.get_level(level)
    }
}

/// obvhs's sort keys, same layout (the radix sort sees only the key, but alike is safest).
#[derive(Clone, Copy)]
#[repr(C)]
struct Morton64 {
    code: u64,
    index: u64,
}

impl RadixKey for Morton64 {
    const LEVELS: usize = 8;
    fn get_level(&self, level: usize) -> u8 {
        self.code.get_level(level)
    }
}

/// `sorted` = `nodes` in Morton order of their box centres, sorted as obvhs
/// sorts them (comparison sort up to 250K nodes, radix sort above: the order of
/// equal codes depends on which).
fn sort_nodes(
    precision: SortPrecision,
    nodes: &[Bvh2Node],
    sorted: &mut [Bvh2Node],
    scale: DVec3,
    offset: DVec3,
) {
    let centre = |n: &Bvh2Node| n.aabb().center().as_dvec3() * scale + offset;
    let order: Vec<usize> = match precision {
        SortPrecision::U128 => {
            let mut m: Vec<Morton128> = nodes
                .iter()
                .enumerate()
                .map(|(i, n)| Morton128 {
                    code: morton_encode_u128_unorm(centre(n)),
                    index: i as u64,
                    padding: 0,
                })
                .collect();
            if nodes.len() <= 250_000 {
                m.sort_unstable_by_key(|m| m.code);
            } else {
                m.as_mut_slice().radix_sort_unstable();
            }
            m.iter().map(|m| m.index as usize).collect()
        }
        SortPrecision::U64 => {
            let mut m: Vec<Morton64> = nodes
                .iter()
                .enumerate()
                .map(|(i, n)| Morton64 {
                    code: morton_encode_u64_unorm(centre(n)),
                    index: i as u64,
                })
                .collect();
            if nodes.len() <= 250_000 {
                m.sort_unstable_by_key(|m| m.code);
            } else {
                m.as_mut_slice().radix_sort_unstable();
            }
            m.iter().map(|m| m.index as usize).collect()
        }
    };
    for (s, i) in sorted.iter_mut().zip(order) {
        *s = nodes[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::shapes::uv_sphere;
    use crate::util::rng::Rng;
    use glam::Vec3A;
    use obvhs::ploc::PlocBuilder;

    fn boxes(tris: &[crate::geom::Triangle]) -> Vec<Aabb> {
        tris.iter()
            .map(|t| Aabb::from_points(&[t.v0.into(), t.v1.into(), t.v2.into()]))
            .collect()
    }

    /// Inputs of several shapes: a mesh, a random soup, coincident boxes, tiny sets.
    fn inputs() -> Vec<Vec<Aabb>> {
        let mut rng = Rng::new(5);
        let mut mesh = Vec::new();
        for _ in 0..6 {
            let c = glam::Vec3::new(
                rng.range_f32(-8.0, 8.0),
                rng.range_f32(-8.0, 8.0),
                rng.range_f32(-8.0, 8.0),
            );
            mesh.extend(uv_sphere(c, rng.range_f32(0.3, 2.0), 10, 20));
        }
        let soup: Vec<Aabb> = (0..3000)
            .map(|_| {
                let p = Vec3A::new(
                    rng.range_f32(-50.0, 50.0),
                    rng.range_f32(-50.0, 50.0),
                    rng.range_f32(-50.0, 50.0),
                );
                let e = Vec3A::new(
                    rng.range_f32(0.0, 9.0),
                    rng.range_f32(0.0, 9.0),
                    rng.range_f32(0.0, 0.1),
                );
                Aabb::new(p, p + e)
            })
            .collect();
        let same = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); 200];
        let tiny: Vec<Aabb> = soup[..3].to_vec();
        vec![
            boxes(&mesh),
            soup,
            same,
            tiny.clone(),
            tiny[..2].to_vec(),
            tiny[..1].to_vec(),
        ]
    }

    fn same_tree(a: &Bvh2, b: &Bvh2) -> bool {
        a.nodes.len() == b.nodes.len()
            && a.nodes.iter().zip(&b.nodes).all(|(x, y)| {
                x.aabb() == y.aabb()
                    && x.prim_count == y.prim_count
                    && x.first_index == y.first_index
            })
            && a.primitive_indices == b.primitive_indices
            && a.max_depth == b.max_depth
            && a.children_are_ordered_after_parents == b.children_are_ordered_after_parents
    }

    /// The copy is obvhs's PLOC, node for node, in every search distance and sort.
    #[test]
    fn the_copy_builds_what_obvhs_builds() {
        let searches = [
            PlocSearchDistance::Minimum,
            PlocSearchDistance::VeryLow,
            PlocSearchDistance::Low,
            PlocSearchDistance::Medium,
            PlocSearchDistance::High,
            PlocSearchDistance::VeryHigh,
        ];
        for aabbs in inputs() {
            let n = aabbs.len();
            for search in searches {
                for sort in [SortPrecision::U64, SortPrecision::U128] {
                    for thresh in [0, 3] {
                        let want = PlocBuilder::with_capacity(n).build(
                            search,
                            &aabbs,
                            (0..n as u32).collect(),
                            sort,
                            thresh,
                        );
                        let got = build(search, &aabbs, sort, thresh, u64::MAX).unwrap();
                        assert!(
                            same_tree(&got, &want),
                            "{n} boxes, {search:?} {sort:?} threshold {thresh}"
                        );
                    }
                }
            }
        }
    }

    /// Thin triangles fanning out of one vertex: PLOC merges a few nodes a pass.
    fn fan(n: usize) -> Vec<Aabb> {
        let p = |i: usize| {
            let (s, c) = crate::geom::shapes::sin_cos(i as f64 / n as f64 * std::f64::consts::TAU);
            Vec3A::new(c as f32, s as f32, 0.0)
        };
        (1..n - 1)
            .map(|i| Aabb::from_points(&[p(0), p(i), p(i + 1)]))
            .collect()
    }

    #[test]
    fn the_budget_stops_a_build_that_does_not_converge() {
        let f = fan(3000);
        let n = f.len() as u64;
        let medium = |budget| {
            build(
                PlocSearchDistance::Medium,
                &f,
                SortPrecision::U64,
                3,
                budget,
            )
        };
        // Unbounded, it finishes, with far more passes than a balanced tree.
        let full = medium(u64::MAX).unwrap();
        assert!(full.max_depth > 500, "{}", full.max_depth);
        assert!(medium(16 * n).is_none());
        // An ordinary input fits well within the budget.
        let mesh = &inputs()[0];
        assert!(
            build(
                PlocSearchDistance::Medium,
                mesh,
                SortPrecision::U64,
                3,
                4 * mesh.len() as u64
            )
            .is_some()
        );
    }
}
