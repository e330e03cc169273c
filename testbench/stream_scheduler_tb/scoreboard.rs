//! The stream scheduler bench's scoreboard (the checks the module doc of
//! `stream_scheduler_tb` lists), over what the stand-ins recorded.

use std::collections::BTreeMap;

use crate::contract::{LINE_BYTES, RayRec};
use crate::units::memory::MemLineReq;
use crate::units::scene_buffer::SlotMap;
use crate::units::stream_scheduler::StreamScheduler;

use super::super::harness::Sink;
use super::super::hit_record_updater_tb::LineMem;
use super::{Bench, FakeTm, Key, SchedTbCfg, SegTree};

/// What went through the fake TMs: every (segment, ray) enqueued (the root rays
/// and the TMs' duplicates) and forwarded, and per segment the first ray
/// forwarded and the last end marker sent.
#[derive(Default)]
pub(super) struct Traffic {
    pub(super) want: BTreeMap<Key, u32>,
    pub(super) got: BTreeMap<Key, u32>,
    pub(super) last_marker: BTreeMap<u32, u64>,
    pub(super) first_fwd: BTreeMap<u32, u64>,
    /// Bucket ends seen, and rays forwarded.
    pub(super) lasts: u64,
    pub(super) fwd_rays: u64,
}

/// Collects what the fake TMs took and sent (a bucket's rays share one
/// segment, its header names the segment's base).
pub(super) fn forwarded(
    bench: &Bench,
    b: &SchedTbCfg,
    tree: &SegTree,
    rays: &[RayRec],
    errors: &mut Vec<String>,
) -> Traffic {
    let mut t = Traffic::default();
    for (i, r) in rays.iter().enumerate() {
        if b.drop_expected && i == 0 {
            continue;
        }
        *t.want.entry((0, r.encode().to_vec())).or_default() += 1;
    }
    for (k, &u) in bench.tms.iter().enumerate() {
        let tm = bench.sim.unit_ref::<FakeTm>(u);
        let mut bucket_seg: Option<u32> = None;
        for (c, f) in &tm.got {
            t.fwd_rays += 1;
            let s = f.hdr.seg;
            *t.got.entry((s, f.ray.encode().to_vec())).or_default() += 1;
            t.first_fwd.entry(s).or_insert(*c);
            if let Some(bs) = bucket_seg
                && bs != s
            {
                errors.push(format!(
                    "TM {k}: a bucket of segment {bs} holds a ray of segment {s}"
                ));
            }
            bucket_seg = if f.last { None } else { Some(s) };
            if f.last {
                t.lasts += 1;
            }
            if f.hdr.base != tree.entries[s as usize].base {
                errors.push(format!(
                    "TM {k}: bucket header of segment {s} has base {:#x}, the table {:#x}",
                    f.hdr.base, tree.entries[s as usize].base
                ));
            }
        }
        for (c, w) in &tm.sent {
            if w.done {
                let e = t.last_marker.entry(w.seg).or_insert(0);
                *e = (*e).max(*c);
            } else {
                *t.want.entry((w.seg, w.ray.encode().to_vec())).or_default() += 1;
            }
        }
    }
    t
}

/// Every enqueued (segment, ray) forwarded exactly once, and nothing else.
pub(super) fn check_rays(t: &Traffic, errors: &mut Vec<String>) {
    let mut lost = 0u64;
    let mut extra = 0u64;
    for (k, n) in &t.want {
        let g = t.got.get(k).copied().unwrap_or(0);
        if g != *n {
            if g < *n {
                lost += 1;
            } else {
                extra += 1;
            }
            if lost + extra <= 10 {
                errors.push(format!(
                    "segment {} ray {}: enqueued {n} times, forwarded {g}",
                    k.0,
                    u32::from_le_bytes(k.1[24..28].try_into().expect("4 bytes"))
                ));
            }
        }
    }
    for (k, g) in &t.got {
        if !t.want.contains_key(k) {
            extra += 1;
            if lost + extra <= 10 {
                errors.push(format!(
                    "segment {}: forwarded a ray never enqueued ({g}x)",
                    k.0
                ));
            }
        }
    }
    if lost + extra > 0 {
        errors.push(format!(
            "{lost} enqueued rays lost, {extra} extra forwarded"
        ));
    }
}

/// Order, from the slot mappings: a segment admitted once, after its parent
/// was admitted and retired; siblings in increasing id; exactly the segments
/// that received rays, each before its first ray is forwarded. Returns the
/// cycle each segment was admitted.
pub(super) fn check_admissions(
    bench: &Bench,
    tree: &SegTree,
    t: &Traffic,
    errors: &mut Vec<String>,
) -> BTreeMap<u32, u64> {
    let parent = &tree.parent;
    let maps = &bench.sim.unit_ref::<Sink<SlotMap>>(bench.map_sink).got;
    let by_base: BTreeMap<u64, u32> = tree
        .entries
        .iter()
        .enumerate()
        .map(|(s, e)| (e.base, s as u32))
        .collect();
    let mut admitted: BTreeMap<u32, u64> = BTreeMap::new();
    let mut order = Vec::new();
    for (c, m) in maps {
        let Some(&s) = by_base.get(&m.base) else {
            errors.push(format!("slot map of an unknown base {:#x}", m.base));
            continue;
        };
        if admitted.insert(s, *c).is_some() {
            errors.push(format!("segment {s} admitted twice"));
        }
        order.push(s);
        if let Some(par) = parent[s as usize] {
            match (admitted.get(&par), t.last_marker.get(&par)) {
                (None, _) => errors.push(format!(
                    "segment {s} admitted at {c} before its parent {par}"
                )),
                (Some(_), Some(&lm)) if lm >= *c => errors.push(format!(
                    "segment {s} admitted at {c}, its parent {par}'s last end marker was sent at {lm}"
                )),
                _ => {}
            }
        }
    }
    // Siblings in increasing id.
    let mut last_child: BTreeMap<u32, u32> = BTreeMap::new();
    for &s in &order {
        if let Some(par) = parent[s as usize] {
            if let Some(&prev) = last_child.get(&par)
                && prev > s
            {
                errors.push(format!(
                    "segment {s} admitted after its higher sibling {prev}: not depth-first order"
                ));
            }
            last_child.insert(par, s);
        }
    }
    let with_rays: Vec<u32> = {
        let mut v: Vec<u32> = t.want.keys().map(|k| k.0).collect();
        v.dedup();
        v
    };
    let adm: Vec<u32> = admitted.keys().copied().collect();
    if adm != with_rays {
        errors.push(format!(
            "admitted {} segments, {} received rays",
            adm.len(),
            with_rays.len()
        ));
    }
    for (s, &c) in &t.first_fwd {
        if admitted.get(s).is_none_or(|&a| a > c) {
            errors.push(format!(
                "segment {s}: a ray forwarded at {c} before its admission"
            ));
        }
    }
    admitted
}

/// Segment streams: every line of every admitted segment once. Returns the
/// lines streamed.
pub(super) fn check_streams(
    bench: &Bench,
    tree: &SegTree,
    admitted: &BTreeMap<u32, u64>,
    errors: &mut Vec<String>,
) -> u64 {
    let scene: Vec<_> = bench
        .scene_sinks
        .iter()
        .flat_map(|&u| bench.sim.unit_ref::<Sink<MemLineReq>>(u).got.iter())
        .collect();
    let mut lines: BTreeMap<u64, u32> = BTreeMap::new();
    for (_, r) in &scene {
        *lines.entry(r.addr).or_default() += 1;
    }
    let mut want_lines = 0u64;
    for &s in admitted.keys() {
        let e = &tree.entries[s as usize];
        let mut a = e.base / LINE_BYTES * LINE_BYTES;
        while a < e.base + e.bytes as u64 {
            want_lines += 1;
            if lines.get(&a).copied().unwrap_or(0) != 1 {
                errors.push(format!(
                    "segment {s}: line {a:#x} streamed {} times",
                    lines.get(&a).copied().unwrap_or(0)
                ));
            }
            a += LINE_BYTES;
        }
    }
    if scene.len() as u64 != want_lines {
        errors.push(format!(
            "{} scene lines streamed, the admitted segments have {want_lines}",
            scene.len()
        ));
    }
    scene.len() as u64
}

/// Every bucket freed (written = read = forwarded, none live), every admitted
/// segment retired, and every memory request answered.
pub(super) fn check_buckets(
    bench: &Bench,
    t: &Traffic,
    admitted: &BTreeMap<u32, u64>,
    errors: &mut Vec<String>,
) {
    let sch = bench.sim.unit_ref::<StreamScheduler>(bench.dut);
    let s = sch.stats();
    if sch.live_buckets() != 0 {
        errors.push(format!("{} buckets never freed", sch.live_buckets()));
    }
    if s.buckets_written != s.buckets_read || s.buckets_read != s.buckets_forwarded {
        errors.push(format!(
            "buckets written {} read {} forwarded {}",
            s.buckets_written, s.buckets_read, s.buckets_forwarded
        ));
    }
    if t.lasts != s.buckets_forwarded {
        errors.push(format!(
            "{} bucket ends seen by the TMs, {} forwarded",
            t.lasts, s.buckets_forwarded
        ));
    }
    if s.retired != admitted.len() as u64 {
        errors.push(format!(
            "{} segments retired of {} admitted",
            s.retired,
            admitted.len()
        ));
    }
    if sch.dest_blocked() {
        errors.push("the destination table blocked".into());
    }
    let m = bench.sim.unit_ref::<LineMem>(bench.memu);
    if m.accepted.len() != m.answered.len() {
        errors.push("a memory request was not answered".into());
    }
}
