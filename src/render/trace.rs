//! Tracing a wavefront on the host: dual streaming in functional mode, or the
//! plain reference traversal; putting rays into the root queue; checking and
//! dumping what was traced.

use super::queues::RayQueues;
use super::traverse::{self, SegmentView, reference_trace, traverse_segment};
use super::{Mode, Prepared, RenderCfg, RenderError, WaveStats, prepare};
use crate::contract::{HitRec, MemoryMap, RayRec, SHADOW_BIT, SegEntry, SparseMem, lines_touched};
use crate::scene::Scene;
use glam::Vec3;

/// Reads and updates a hit record with atomic-min semantics on (t, id).
pub(super) fn update_hit(
    mem: &mut SparseMem,
    map: &MemoryMap,
    idx: u64,
    h: HitRec,
    st: &mut WaveStats,
) {
    let a = map.hit_addr(idx);
    let cur = HitRec::read(mem, a);
    st.hit_lines_read += 1;
    if h.closer_than(&cur) {
        h.write(mem, a);
        st.hit_lines_written += 1;
    }
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
/// `hook` is called before each segment that holds rays (with its id) and once at
/// the end (with `u32::MAX`).
pub(super) fn trace_functional(
    p: &mut Prepared,
    q: &mut RayQueues,
    st: &mut WaveStats,
    progress: &mut dyn FnMut(u64, u64),
    hook: &mut SegHook,
) -> Result<(), RenderError> {
    let mut done = 0u64;
    let mut rays = Vec::new();
    let mut stack = Vec::new();
    let mut exits: Vec<(u32, u32)> = Vec::new();
    for s in 0..p.seg.segments.len() as u32 {
        if q.is_empty(s) {
            // No rays: the segment and (since rays come only from parents) its whole
            // subtree are skipped.
            continue;
        }
        hook(s, p, q, st)?;
        let e = SegEntry::read(&p.mem, p.map.seg_entry_addr(s));
        let view = SegmentView::load(&p.mem, e.base, s, e.nodes, e.tris);
        st.segments_loaded += 1;
        st.scene_lines += lines_touched(e.base, e.bytes as u64);
        while {
            rays.clear();
            q.pop_bucket(&p.mem, &p.map, s, &mut rays)
        } {
            for ray in &rays {
                exits.clear();
                let best =
                    traverse_segment(&view, ray, &mut stack, &mut st.traversal, |seg, entry| {
                        exits.push((seg, entry))
                    });
                for &(cs, entry) in &exits {
                    q.push(&mut p.mem, &p.map, cs, &RayRec { entry, ..*ray })?;
                    st.enqueues += 1;
                }
                if best.is_hit() {
                    update_hit(&mut p.mem, &p.map, ray.hit_index(), best, st);
                }
            }
            done += rays.len() as u64;
            progress(done, st.enqueues);
        }
        for k in 0..e.child_count {
            let c = p
                .mem
                .read_u32(p.map.child_list + (e.first_child + k) as u64 * 4);
            q.close(&mut p.mem, &p.map, c);
        }
    }
    hook(u32::MAX, p, q, st)
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
