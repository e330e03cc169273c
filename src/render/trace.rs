//! Tracing a wavefront on the host: dual streaming in functional mode, or the
//! plain reference traversal; putting rays into the root queue; checking and
//! dumping what was traced.

use super::early_term::{self, EarlyTermCounts, Rules};
use super::queues::{RayQueues, queue_lines_read, queue_lines_written};
use super::traverse::{self, SegmentView, TraversalCounts, reference_trace, traverse_segment};
use super::{Mode, Prepared, RenderCfg, RenderError, WaveStats, prepare};
use crate::config::EarlyTermination;
use crate::contract::{HitRec, MemoryMap, RayRec, SHADOW_BIT, SegEntry, SparseMem, lines_touched};
use crate::scene::Scene;
use glam::Vec3;
use std::collections::HashMap;

/// Reads and updates a hit record with atomic-min semantics on (t, id).
pub(super) fn update_hit(
    mem: &mut SparseMem,
    map: &MemoryMap,
    idx: u64,
    h: HitRec,
    st: &mut WaveStats,
) -> bool {
    let a = map.hit_addr(idx);
    let cur = HitRec::read(mem, a);
    st.hit_lines_read += 1;
    let closer = h.closer_than(&cur);
    if closer {
        h.write(mem, a);
        st.hit_lines_written += 1;
    }
    closer
}

/// Puts a new ray into the root segment's queue and resets its hit record.
pub(super) fn emit(
    p: &mut Prepared,
    q: &mut RayQueues,
    st: &mut WaveStats,
    ray: &RayRec,
    keep: bool,
    list: &mut Vec<RayRec>,
) -> Result<(), RenderError> {
    q.push(&mut p.mem, &p.map, 0, ray)?;
    HitRec::NONE.write(&mut p.mem, p.map.hit_addr(ray.hit_index()));
    st.hit_lines_written += 1;
    st.rays += 1;
    st.enqueues += 1;
    if ray.is_shadow() {
        st.shadow_rays += 1;
    } else {
        st.bounce_rays += 1;
    }
    if keep {
        list.push(*ray);
    }
    Ok(())
}

/// Dual streaming, functional: segments in depth-first order, each loaded once if
/// its queue has rays; every ray of the queue traverses the segment locally and is
/// duplicated into the queue of each child segment it exits into.
/// With early termination `et`, the pre-test reads a ray's hit record before it
/// traverses and may drop it, the post-test reads it before the ray's exits are
/// enqueued and may skip them (`rules` decide; see `early_term`); the copies they
/// stop go on as ghosts whose work is counted apart (`st.early`).
/// `hook` is called before each segment that holds rays (with its id) and once at
/// the end (with `u32::MAX`).
pub(super) fn trace_functional(
    p: &mut Prepared,
    q: &mut RayQueues,
    st: &mut WaveStats,
    et: EarlyTermination,
    rules: &Rules,
    progress: &mut dyn FnMut(u64, u64),
    hook: &mut SegHook,
) -> Result<(), RenderError> {
    let mut done = 0u64;
    let mut rays = Vec::new();
    let mut stack = Vec::new();
    let mut exits: Vec<(u32, u32, f32)> = Vec::new();
    let n = p.seg.segments.len();
    // Early termination: the copies stopped, per segment, and the copies each
    // queue took (for the ray-stream lines with and without).
    let mut ghosts: Vec<Vec<RayRec>> = Vec::new();
    let (mut real_in, mut ghost_in) = (Vec::new(), Vec::new());
    if et != EarlyTermination::None {
        ghosts = vec![Vec::new(); n];
        real_in = vec![0u64; n];
        ghost_in = vec![0u64; n];
    }
    let mut ghost_work = TraversalCounts::default();
    // The hit records as they would stand without early termination (a shadow
    // ray's differs: it stops on any hit, not the closest).
    let mut none_recs: HashMap<u64, HitRec> = HashMap::new();
    for s in 0..n as u32 {
        let real = !q.is_empty(s);
        let ghost = ghosts.get(s as usize).is_some_and(|g| !g.is_empty());
        if !real && !ghost {
            // No rays: the segment and (since rays come only from parents) its whole
            // subtree are skipped.
            continue;
        }
        let e = SegEntry::read(&p.mem, p.map.seg_entry_addr(s));
        let view = SegmentView::load(&p.mem, e.base, s, e.nodes, e.tris);
        let seg_lines = lines_touched(e.base, e.bytes as u64);
        if real {
            hook(s, p, q, st)?;
            st.segments_loaded += 1;
            st.scene_lines += seg_lines;
        } else {
            st.early.segments_removed += 1;
            st.early.scene_lines_removed += seg_lines;
        }
        while {
            rays.clear();
            q.pop_bucket(&p.mem, &p.map, s, &mut rays)
        } {
            for ray in &rays {
                let idx = ray.hit_index();
                if et.pre() {
                    let rec = read_record(p, idx, st);
                    st.early.pre_box_tests += 1;
                    st.traversal.box_tests += 1;
                    if early_term::pre_test(rules, &view, ray, &rec) {
                        st.early.rays_dropped += 1;
                        ghosts[s as usize].push(*ray);
                        continue;
                    }
                }
                exits.clear();
                let best = traverse_segment(
                    &view,
                    ray,
                    &mut stack,
                    &mut st.traversal,
                    |seg, entry, t| exits.push((seg, entry, t)),
                );
                if best.is_hit() {
                    let wrote = update_hit(&mut p.mem, &p.map, idx, best, st);
                    if et != EarlyTermination::None {
                        none_update(&mut none_recs, idx, best, Some(wrote), &mut st.early);
                    }
                }
                // The record after this ray's own update: the closest hit of all
                // its copies so far.
                let rec = (et.post() && !exits.is_empty()).then(|| read_record(p, idx, st));
                for &(cs, entry, t) in &exits {
                    let copy = RayRec { entry, ..*ray };
                    if rec.is_some_and(|r| (rules.post)(t, &r, ray.is_shadow())) {
                        st.early.enqueues_avoided += 1;
                        ghosts[cs as usize].push(copy);
                        ghost_in[cs as usize] += 1;
                        continue;
                    }
                    q.push(&mut p.mem, &p.map, cs, &copy)?;
                    st.enqueues += 1;
                    if let Some(r) = real_in.get_mut(cs as usize) {
                        *r += 1;
                    }
                }
            }
            done += rays.len() as u64;
            progress(done, st.enqueues);
        }
        // The stopped copies here do what they would have done without early
        // termination: traverse, and go on into the children they exit into.
        // (The pre-test may have stopped copies here itself.)
        if ghosts.get(s as usize).is_some_and(|g| !g.is_empty()) {
            let here = std::mem::take(&mut ghosts[s as usize]);
            for ray in &here {
                let best =
                    traverse_segment(&view, ray, &mut stack, &mut ghost_work, |cs, entry, _| {
                        ghosts[cs as usize].push(RayRec { entry, ..*ray });
                        ghost_in[cs as usize] += 1;
                    });
                if best.is_hit() {
                    none_update(&mut none_recs, ray.hit_index(), best, None, &mut st.early);
                }
            }
        }
        for k in 0..e.child_count {
            let c = p
                .mem
                .read_u32(p.map.child_list + (e.first_child + k) as u64 * 4);
            q.close(&mut p.mem, &p.map, c);
        }
    }
    if et != EarlyTermination::None {
        st.early.box_tests_avoided += ghost_work.box_tests;
        st.early.tri_tests_avoided += ghost_work.tri_tests;
        let rpb = q.rays_per_bucket();
        let lines = |n: u64| queue_lines_written(n, rpb) + queue_lines_read(n, rpb);
        for s in 0..n {
            let (r, g) = (real_in[s], ghost_in[s]);
            st.early.ghost_enqueues += g;
            st.early.ray_lines_removed += lines(r + g) - lines(r);
        }
    }
    hook(u32::MAX, p, q, st)
}

/// Hit record `idx` without early termination (`recs`) takes the update `h`:
/// counts the hit-record lines that run would move and this one does not
/// (`wrote`: whether this run's update wrote; `None` for a stopped copy's,
/// which this run does not make) and the reverse.
fn none_update(
    recs: &mut HashMap<u64, HitRec>,
    idx: u64,
    h: HitRec,
    wrote: Option<bool>,
    e: &mut EarlyTermCounts,
) {
    let cur = recs.entry(idx).or_insert(HitRec::NONE);
    let writes = h.closer_than(cur);
    if writes {
        *cur = h;
    }
    match wrote {
        None => e.hit_lines_removed += 1 + writes as u64,
        Some(w) if writes && !w => e.hit_lines_removed += 1,
        Some(w) if w && !writes => e.hit_lines_added += 1,
        Some(_) => {}
    }
}

/// An early-termination test's read of a ray's hit record (one line).
fn read_record(p: &Prepared, idx: u64, st: &mut WaveStats) -> HitRec {
    st.early.records_read += 1;
    st.hit_lines_read += 1;
    HitRec::read(&p.mem, p.map.hit_addr(idx))
}

pub(super) type SegHook<'a> =
    dyn FnMut(u32, &mut Prepared, &RayQueues, &WaveStats) -> Result<(), RenderError> + 'a;

/// The reference: every ray of the root queue traced through the whole BVH.
pub(super) fn trace_reference(
    p: &mut Prepared,
    q: &mut RayQueues,
    scene: &Scene,
    st: &mut WaveStats,
) {
    let mut rays = Vec::new();
    while q.pop_bucket(&p.mem, &p.map, 0, &mut rays) {}
    for ray in &rays {
        let best = traverse::reference_trace_counted(
            &p.bvh,
            &scene.triangles,
            ray.origin,
            ray.dir,
            ray.is_shadow(),
            &mut st.traversal,
        );
        if best.is_hit() {
            update_hit(&mut p.mem, &p.map, ray.hit_index(), best, st);
        }
    }
}

/// Compares every hit record of the wavefront with the reference traversal:
/// the closest (t, id) for bounce rays, occluded or not for shadow rays.
pub(super) fn verify(p: &Prepared, scene: &Scene, rays: &[RayRec]) -> Result<u64, RenderError> {
    for ray in rays {
        let got = HitRec::read(&p.mem, p.map.hit_addr(ray.hit_index()));
        let want = reference_trace(
            &p.bvh,
            &scene.triangles,
            ray.origin,
            ray.dir,
            ray.is_shadow(),
        );
        let same = if ray.is_shadow() {
            got.is_hit() == want.is_hit()
        } else {
            got.tri_id == want.tri_id && got.t.to_bits() == want.t.to_bits()
        };
        if !same {
            return Err(RenderError::Mismatch(format!(
                "ray {:#x} (origin {:?}, dir {:?}): traced {:?}, reference {:?}",
                ray.ray_id, ray.origin, ray.dir, got, want
            )));
        }
    }
    Ok(rays.len() as u64)
}

/// Traces a batch of rays (origin, direction, shadow?) as one wavefront and returns
/// their hit records, read back from the DRAM image. Ray i gets pixel id i, so the
/// batch may hold at most one bounce and one shadow ray per index (tests use it to
/// aim rays at shared edges and vertices).
pub fn trace_rays(
    scene: &Scene,
    cfg: &RenderCfg,
    mode: Mode,
    rays: &[(Vec3, Vec3, bool)],
) -> Result<(Vec<HitRec>, WaveStats), RenderError> {
    trace_rays_ruled(scene, cfg, mode, rays, &Rules::EXACT)
}

/// [`trace_rays`] with early termination decided by `rules` (a test plants
/// wrong ones).
pub(crate) fn trace_rays_ruled(
    scene: &Scene,
    cfg: &RenderCfg,
    mode: Mode,
    rays: &[(Vec3, Vec3, bool)],
    rules: &Rules,
) -> Result<(Vec<HitRec>, WaveStats), RenderError> {
    let mut sc = scene.clone();
    // Room for one hit-record pair per ray.
    sc.settings.width = rays.len().max(1) as u32;
    sc.settings.height = 1;
    let mut p = prepare(&sc, cfg)?;
    let mut q = RayQueues::new(&p.map, p.seg.segments.len());
    let mut st = WaveStats::default();
    let root = p.image.root_entry.encode();
    let recs: Vec<RayRec> = rays
        .iter()
        .enumerate()
        .map(|(i, &(o, d, sh))| RayRec {
            origin: o,
            dir: d,
            ray_id: i as u32 | if sh { SHADOW_BIT } else { 0 },
            entry: root,
        })
        .collect();
    let mut unused = Vec::new();
    for r in &recs {
        emit(&mut p, &mut q, &mut st, r, false, &mut unused)?;
    }
    q.close(&mut p.mem, &p.map, 0);
    match mode {
        Mode::Functional => trace_functional(
            &mut p,
            &mut q,
            &mut st,
            cfg.early_termination(),
            rules,
            &mut |_, _| {},
            &mut |_, _, _, _| Ok(()),
        )?,
        Mode::Reference => trace_reference(&mut p, &mut q, &sc, &mut st),
        Mode::Cycle => {
            return Err(RenderError::Invalid(
                "trace_rays runs functional or reference mode; render a frame for cycle mode"
                    .into(),
            ));
        }
    }
    Ok((
        recs.iter()
            .map(|r| HitRec::read(&p.mem, p.map.hit_addr(r.hit_index())))
            .collect(),
        st,
    ))
}

/// Writes a wavefront's rays (32 B ray records) and their hit records (16 B), in the
/// same order, as `wave<k>_rays.bin` and `wave<k>_hits.bin` (data contract layouts).
pub(super) fn dump(
    dir: &std::path::Path,
    wave: usize,
    p: &Prepared,
    rays: &[RayRec],
) -> Result<(), RenderError> {
    let mut rb = Vec::with_capacity(rays.len() * 32);
    let mut hb = Vec::with_capacity(rays.len() * 16);
    for r in rays {
        for f in [
            r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z,
        ] {
            rb.extend_from_slice(&f.to_le_bytes());
        }
        rb.extend_from_slice(&r.ray_id.to_le_bytes());
        rb.extend_from_slice(&r.entry.to_le_bytes());
        let h = HitRec::read(&p.mem, p.map.hit_addr(r.hit_index()));
        hb.extend_from_slice(&h.t.to_le_bytes());
        hb.extend_from_slice(&h.tri_id.to_le_bytes());
        hb.extend_from_slice(&h.u.to_le_bytes());
        hb.extend_from_slice(&h.v.to_le_bytes());
    }
    for (name, bytes) in [
        (format!("wave{wave}_rays.bin"), rb),
        (format!("wave{wave}_hits.bin"), hb),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(|e| {
            let msg = format!("cannot write '{}': {e}", path.display());
            RenderError::File(crate::util::FileError::new(&path, e, msg))
        })?;
    }
    Ok(())
}
