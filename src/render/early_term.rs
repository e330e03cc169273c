//! Early ray termination across segments in functional mode [DS17 §3, §5.4]:
//! the pre-test (before a ray copy traverses a segment, its shared hit record
//! is read and the copy dropped if the recorded hit is closer than its entry
//! into the segment) and the post-test (after traversal, exits farther than the
//! recorded hit are not enqueued). Shadow rays stop on any recorded hit.
//!
//! Both tests cull exactly as the traversal culls a box (`geom::cull`'s margin
//! over the hit t, so a tie on a shared edge still reaches the triangle with
//! the smaller id): a copy is dropped only where the reference traversal,
//! knowing that hit, would skip the same box. Closest hits, occlusion and the
//! image are those of `none`.
//!
//! What a test saves is what the copies it stopped would have done: they are
//! carried on as *ghosts* (host-side, no DRAM, no hit updates) through the
//! segments they would have reached, their work counted apart. The counts
//! without early termination are the frame's plus the ghosts' (tested equal to
//! a frame rendered with `none`).

use serde::Serialize;

use super::traverse::SegmentView;
use crate::contract::{HitRec, RayRec, Ref};
use crate::geom::{Aabb, cull, inverse_dir, ray_box};

/// What early termination read, stopped and saved (one wavefront or a frame).
/// Lines are 64 B DRAM lines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct EarlyTermCounts {
    /// Hit records read by the tests (one 64 B line each, in the hit-record
    /// stream's lines read too).
    pub records_read: u64,
    /// Ray copies the pre-test dropped before their segment.
    pub rays_dropped: u64,
    /// Exits into child segments the post-test did not enqueue.
    pub enqueues_avoided: u64,
    /// Box tests the pre-test ran (one per record read: the ray against the
    /// entry node's bounds, for its entry distance); in the traversal's box
    /// tests too.
    pub pre_box_tests: u64,
    /// Box and triangle tests the stopped copies and their descendants would
    /// have run (gross: `pre_box_tests` is the cost against it).
    pub box_tests_avoided: u64,
    pub tri_tests_avoided: u64,
    /// Enqueues (ray copies written to a queue) the stopped copies would have made.
    pub ghost_enqueues: u64,
    /// Ray-stream lines (read and written) the stopped copies would have moved.
    pub ray_lines_removed: u64,
    /// Scene-stream lines of segments only stopped copies would have reached.
    pub scene_lines_removed: u64,
    /// Segment loads those are.
    pub segments_removed: u64,
    /// Hit-record lines without early termination and not with it: the
    /// stopped copies' updates (a read, a write if closer), and writes a
    /// shadow ray's record took there only (it holds the closest of all its
    /// copies' first hits there, here the first recorded).
    pub hit_lines_removed: u64,
    /// Hit-record writes here and not without early termination (shadow rays,
    /// as above); the records read are added lines too.
    pub hit_lines_added: u64,
}

impl std::ops::AddAssign for EarlyTermCounts {
    fn add_assign(&mut self, o: Self) {
        self.records_read += o.records_read;
        self.rays_dropped += o.rays_dropped;
        self.enqueues_avoided += o.enqueues_avoided;
        self.pre_box_tests += o.pre_box_tests;
        self.box_tests_avoided += o.box_tests_avoided;
        self.tri_tests_avoided += o.tri_tests_avoided;
        self.ghost_enqueues += o.ghost_enqueues;
        self.ray_lines_removed += o.ray_lines_removed;
        self.scene_lines_removed += o.scene_lines_removed;
        self.segments_removed += o.segments_removed;
        self.hit_lines_removed += o.hit_lines_removed;
        self.hit_lines_added += o.hit_lines_added;
    }
}

/// The decisions of the two tests. [`Rules::EXACT`] is the model's; a test
/// plants a wrong one to show `--verify` catches it.
#[derive(Clone, Copy)]
pub(crate) struct Rules {
    /// Drop a ray entering its segment at `te` whose record holds `rec`?
    pub pre: fn(te: f32, rec: &HitRec, shadow: bool) -> bool,
    /// Skip an exit at `te`, the record holding `rec`?
    pub post: fn(te: f32, rec: &HitRec, shadow: bool) -> bool,
}

impl Rules {
    pub const EXACT: Rules = Rules {
        pre: beyond_record,
        post: beyond_record,
    };
}

/// A shadow ray with any recorded hit is occluded; a bounce ray's work at `te`
/// is useless when the box there is culled by the recorded hit, exactly as the
/// traversal culls (strictly beyond `cull(rec.t)`: equal keeps it, for ties).
pub(crate) fn beyond_record(te: f32, rec: &HitRec, shadow: bool) -> bool {
    rec.is_hit() && (shadow || te > cull(rec.t))
}

/// The distance at which `ray` enters its segment: the box test against the
/// bounds of its entry node (both children's boxes; the box its parent segment
/// tested, up to rounding, which only brings it closer). `None` if the ray
/// misses them; `Some(0.0)` for a leaf entry (no bounds in the segment: never
/// dropped by distance).
pub(crate) fn entry_distance(seg: &SegmentView, ray: &RayRec) -> Option<f32> {
    match Ref::decode(ray.entry) {
        Ref::Node(i) => {
            let n = &seg.nodes[i as usize];
            let b = Aabb {
                min: n.bmin[0].min(n.bmin[1]),
                max: n.bmax[0].max(n.bmax[1]),
            };
            ray_box(ray.origin, inverse_dir(ray.dir), 0.0, f32::INFINITY, &b)
        }
        _ => Some(0.0),
    }
}

/// The pre-test's decision for `ray` entering `seg` with record `rec`: a ray
/// that misses its entry node's bounds altogether is dropped only when the
/// record holds a hit (the traversal would find nothing there either way).
pub(crate) fn pre_test(rules: &Rules, seg: &SegmentView, ray: &RayRec, rec: &HitRec) -> bool {
    let te = entry_distance(seg, ray).unwrap_or(f32::INFINITY);
    (rules.pre)(te, rec, ray.is_shadow())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::HIT_NONE_ID;

    fn hit(t: f32) -> HitRec {
        HitRec {
            t,
            tri_id: 7,
            u: 0.0,
            v: 0.0,
        }
    }

    /// Primary rays through the hairball traced by dual streaming under
    /// `rules` with the pre- and post-test: how many closest hits differ from
    /// the reference traversal's (what `--verify` checks), and the rays dropped.
    fn mismatches(rules: &Rules) -> (usize, u64) {
        use crate::render::traverse::reference_trace;
        let s = crate::scene::load("hairball").unwrap();
        let n = 40u32;
        let rays: Vec<_> = (0..n * n)
            .map(|p| {
                let (o, d, _) = crate::units::shade::primary_path(&s.camera, 1, p, n, n);
                (o, d, false)
            })
            .collect();
        let mut c = crate::config::Config::default();
        c.chip.early_termination = crate::config::EarlyTermination::Both;
        let cfg = crate::render::RenderCfg::for_chip(&c, Default::default());
        let (hits, st) = crate::render::trace::trace_rays_ruled(
            &s,
            &cfg,
            crate::render::Mode::Functional,
            &rays,
            rules,
        )
        .unwrap();
        let prep = crate::render::prepare(&s, &cfg).unwrap();
        let wrong = rays
            .iter()
            .zip(&hits)
            .filter(|((o, d, _), h)| {
                let r = reference_trace(&prep.bvh, &s.triangles, *o, *d, false);
                (r.t.to_bits(), r.tri_id) != (h.t.to_bits(), h.tri_id)
            })
            .count();
        (wrong, st.early.rays_dropped)
    }

    /// The check catches a wrong test: dropping a copy whose recorded hit is
    /// as far as its entry or farther (the comparison turned round) loses
    /// closest hits; the model's rule loses none while dropping as many.
    #[test]
    fn a_wrong_drop_rule_is_caught_by_the_reference() {
        let (wrong, dropped) = mismatches(&Rules::EXACT);
        assert_eq!(wrong, 0);
        assert!(dropped > 100, "{dropped} dropped");
        let broken = Rules {
            pre: |te, rec, _| rec.is_hit() && rec.t >= te,
            post: beyond_record,
        };
        let (wrong, dropped) = mismatches(&broken);
        assert!(wrong > 10, "{wrong} wrong closest hits ({dropped} dropped)");
    }

    #[test]
    fn the_record_stops_only_work_strictly_beyond_its_margin() {
        // No record: never.
        assert!(!beyond_record(5.0, &HitRec::NONE, false));
        assert!(!beyond_record(5.0, &HitRec::NONE, true));
        assert_eq!(HitRec::NONE.tri_id, HIT_NONE_ID);
        // A tie, or within the culling margin: kept (a smaller id may win).
        assert!(!beyond_record(2.0, &hit(2.0), false));
        assert!(!beyond_record(cull(2.0), &hit(2.0), false));
        assert!(!beyond_record(1.0, &hit(2.0), false));
        // Beyond the margin: stopped.
        assert!(beyond_record(cull(2.0) * 1.0001, &hit(2.0), false));
        // A shadow ray stops on any hit, nearer or not.
        assert!(beyond_record(0.0, &hit(0.9), true));
    }
}
