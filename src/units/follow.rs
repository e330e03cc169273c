//! Following one ray through the chip (`render --follow-ray`): a probe, not
//! hardware. A unit that carries a [`Follower`] (`None` by default, so the
//! untraced path costs one branch) logs every event of the followed rays it
//! sees: the cycle, its instance path (as in the waveform's scopes,
//! `chip.tm3.tp5`) and what happened. The followed rays are named by
//! wavefront and ray id (`RayRec::ray_id`: pixel, bit 31 shadow); a ray's
//! duplicates share its id, so they are followed too (each event names the
//! segment it happened in).
//!
//! Logging reads no link and writes nothing the simulation reads: following
//! changes no result. Units on several evaluation lanes log into one shared
//! list; [`FollowLog::events`] orders it by (cycle, unit, the unit's own
//! order), which no lane count or evaluation order changes.

use std::fmt;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use glam::Vec3;

use crate::contract::SHADOW_BIT;

/// One thing that happened to a followed ray.
#[derive(Clone, Debug, PartialEq)]
pub enum FollowKind {
    /// Scheduler: written into segment `seg`'s queue, bucket `bucket` (pool
    /// index), ray slot `slot` in it; sent by TM `from` (`None`: the host's
    /// `emit` port).
    Queued {
        seg: u32,
        bucket: u64,
        slot: u32,
        from: Option<u32>,
    },
    /// Scheduler: its bucket of segment `seg` was read back onto the chip.
    BucketRead { seg: u32 },
    /// Scheduler: its bucket of segment `seg` was handed to TM `tm`.
    HandedOut { seg: u32, tm: u32 },
    /// Scheduler: pushed into TM `tm`'s staging buffer (`fill` port).
    Filled { seg: u32, tm: u32 },
    /// Staging buffer: stored in half `half`, slot `slot`.
    Staged { seg: u32, half: u32, slot: u32 },
    /// Staging buffer: handed to TP `tp` of the TM.
    ToTp { seg: u32, tp: u32 },
    /// TP: took the ray to traverse segment `seg` from `entry` (an encoded
    /// `Ref`).
    Taken {
        seg: u32,
        origin: Vec3,
        dir: Vec3,
        entry: u32,
    },
    /// TP: visits inner node `node` of the segment.
    Node { seg: u32, node: u32 },
    /// TP: the box test of child `side` (0, 1) of the node: entry distance if hit.
    BoxTest {
        seg: u32,
        side: u32,
        hit: Option<f32>,
    },
    /// TP: a stack entry at distance `t` culled beyond the best hit.
    Cull { seg: u32, t: f32 },
    /// TP: a leaf's triangles `first..first + count`.
    Leaf { seg: u32, first: u32, count: u32 },
    /// TP: the triangle test of `tri_id`: distance if hit.
    TriTest {
        seg: u32,
        tri_id: u32,
        hit: Option<f32>,
    },
    /// TP: the segment's best hit so far became (`t`, `tri_id`).
    Closer { seg: u32, t: f32, tri_id: u32 },
    /// TP: the duplicate into child segment `child` (entry `entry`) sent.
    Exit { seg: u32, child: u32, entry: u32 },
    /// TP: done with segment `seg`: end marker sent, and the best hit (t,
    /// triangle) sent to the hit record updater if any.
    Finish { seg: u32, best: Option<(f32, u32)> },
    /// Scheduler: took the end marker of the ray in segment `seg`.
    Marker { seg: u32 },
    /// Hit record updater: took the update (t, triangle) from TM `tm`, merged
    /// into a pending one or queued.
    HitQueued {
        tm: u32,
        t: f32,
        tri_id: u32,
        merged: bool,
    },
    /// Hit record updater: read the hit record (read-compare-write).
    HitRead,
    /// Hit record updater: compared the update (t, triangle) with the
    /// record's (`old_t`, `old_tri`); written if closer.
    HitCompared {
        t: f32,
        tri_id: u32,
        old_t: f32,
        old_tri: u32,
        written: bool,
    },
    /// Hit record updater: the record's write was answered.
    HitWritten,
    /// TP: took the shading item of the ray's pixel (the pass after its wavefront).
    ShadeTaken { pixel: u32 },
    /// TP: shaded the pixel: the bounce ray hit, the shadow ray was blocked.
    Shaded { hit: bool, occluded: bool },
    /// TP: the shading emitted ray `ray_id` of the next wavefront.
    ShadeEmit { ray_id: u32 },
    /// TP: the shading item's end marker sent.
    ShadeDone,
}

impl FollowKind {
    /// The event's name in the log.
    pub fn name(&self) -> &'static str {
        use FollowKind::*;
        match self {
            Queued { .. } => "queued",
            BucketRead { .. } => "bucket_read",
            HandedOut { .. } => "handed_out",
            Filled { .. } => "filled",
            Staged { .. } => "staged",
            ToTp { .. } => "to_tp",
            Taken { .. } => "taken",
            Node { .. } => "node",
            BoxTest { .. } => "box_test",
            Cull { .. } => "cull",
            Leaf { .. } => "leaf",
            TriTest { .. } => "tri_test",
            Closer { .. } => "closer",
            Exit { .. } => "exit",
            Finish { .. } => "finish",
            Marker { .. } => "marker",
            HitQueued { .. } => "hit_queued",
            HitRead => "hit_read",
            HitCompared { .. } => "hit_compared",
            HitWritten => "hit_written",
            ShadeTaken { .. } => "shade_taken",
            Shaded { .. } => "shaded",
            ShadeEmit { .. } => "shade_emit",
            ShadeDone => "shade_done",
        }
    }

    /// The segment the event happened in, for traversal and queue events.
    pub fn seg(&self) -> Option<u32> {
        use FollowKind::*;
        match *self {
            Queued { seg, .. }
            | BucketRead { seg }
            | HandedOut { seg, .. }
            | Filled { seg, .. }
            | Staged { seg, .. }
            | ToTp { seg, .. }
            | Taken { seg, .. }
            | Node { seg, .. }
            | BoxTest { seg, .. }
            | Cull { seg, .. }
            | Leaf { seg, .. }
            | TriTest { seg, .. }
            | Closer { seg, .. }
            | Exit { seg, .. }
            | Finish { seg, .. }
            | Marker { seg } => Some(seg),
            _ => None,
        }
    }
}

fn opt_t(h: Option<f32>) -> String {
    h.map_or("miss".into(), |t| format!("t={t}"))
}

impl fmt::Display for FollowKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use FollowKind::*;
        f.write_str(self.name())?;
        match *self {
            Queued {
                seg,
                bucket,
                slot,
                from,
            } => {
                write!(f, " seg={seg} bucket={bucket} slot={slot} from=")?;
                match from {
                    Some(k) => write!(f, "tm{k}"),
                    None => f.write_str("host"),
                }
            }
            BucketRead { seg } | Marker { seg } => write!(f, " seg={seg}"),
            HandedOut { seg, tm } | Filled { seg, tm } => write!(f, " seg={seg} tm={tm}"),
            Staged { seg, half, slot } => write!(f, " seg={seg} half={half} slot={slot}"),
            ToTp { seg, tp } => write!(f, " seg={seg} tp={tp}"),
            Taken {
                seg,
                origin,
                dir,
                entry,
            } => write!(
                f,
                " seg={seg} entry={entry:#x} origin={},{},{} dir={},{},{}",
                origin.x, origin.y, origin.z, dir.x, dir.y, dir.z
            ),
            Node { seg, node } => write!(f, " seg={seg} node={node}"),
            BoxTest { seg, side, hit } => write!(f, " seg={seg} side={side} {}", opt_t(hit)),
            Cull { seg, t } => write!(f, " seg={seg} t={t}"),
            Leaf { seg, first, count } => write!(f, " seg={seg} first={first} count={count}"),
            TriTest { seg, tri_id, hit } => {
                write!(f, " seg={seg} tri={tri_id} {}", opt_t(hit))
            }
            Closer { seg, t, tri_id } => write!(f, " seg={seg} t={t} tri={tri_id}"),
            Exit { seg, child, entry } => write!(f, " seg={seg} child={child} entry={entry:#x}"),
            Finish { seg, best } => match best {
                Some((t, tri)) => write!(f, " seg={seg} t={t} tri={tri}"),
                None => write!(f, " seg={seg} miss"),
            },
            HitQueued {
                tm,
                t,
                tri_id,
                merged,
            } => write!(f, " tm={tm} t={t} tri={tri_id} merged={merged}"),
            HitCompared {
                t,
                tri_id,
                old_t,
                old_tri,
                written,
            } => write!(
                f,
                " t={t} tri={tri_id} old_t={old_t} old_tri={old_tri} written={written}"
            ),
            ShadeTaken { pixel } => write!(f, " pixel={pixel}"),
            Shaded { hit, occluded } => write!(f, " hit={hit} occluded={occluded}"),
            ShadeEmit { ray_id } => write!(f, " ray={ray_id:#x}"),
            HitRead | HitWritten | ShadeDone => Ok(()),
        }
    }
}

/// One logged event: when, where, which ray, what.
#[derive(Clone, Debug, PartialEq)]
pub struct FollowEvent {
    /// Core cycle, from the start of the frame (as the waveform's).
    pub cycle: u64,
    /// The unit instance's path (`chip.tm3.tp5`).
    pub unit: Arc<str>,
    /// The ray: its wavefront and id.
    pub wave: u32,
    pub ray_id: u32,
    pub kind: FollowKind,
    /// The unit's index and its own event count: the order within a cycle.
    order: (u32, u64),
}

impl fmt::Display for FollowEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:>9} {:<24} w{} {:#010x} {}",
            self.cycle, self.unit, self.wave, self.ray_id, self.kind
        )
    }
}

/// What the followers share: the rays followed, the chip run's wavefront, the log.
#[derive(Debug)]
struct Shared {
    /// (wavefront, ray id) of every followed ray.
    targets: Vec<(u32, u32)>,
    /// The wavefront the chip traces in this run (its shading pass, if any,
    /// shades the one before).
    wave: AtomicU32,
    events: Mutex<Vec<FollowEvent>>,
}

/// The chip's handle on a following: arms units ([`FollowLog::follower`]),
/// says which wavefront a run traces, reads the log.
#[derive(Clone, Debug)]
pub struct FollowLog(Arc<Shared>);

impl FollowLog {
    /// Follows the rays `targets` ((wavefront, ray id) pairs).
    pub fn new(targets: Vec<(u32, u32)>) -> FollowLog {
        FollowLog(Arc::new(Shared {
            targets,
            wave: AtomicU32::new(0),
            events: Mutex::new(Vec::new()),
        }))
    }

    /// The probe for unit `index` (its simulator id) at `path`.
    pub fn follower(&self, index: u32, path: &str) -> Follower {
        Follower {
            shared: self.0.clone(),
            unit: path.into(),
            index,
            seq: 0,
        }
    }

    /// The chip run that starts traces wavefront `wave`.
    pub fn set_wave(&self, wave: u32) {
        self.0.wave.store(wave, Ordering::Relaxed);
    }

    /// Whether any followed ray was written into a queue (so it exists).
    pub fn any_queued(&self) -> bool {
        let ev = self.0.events.lock().expect("not poisoned");
        ev.iter()
            .any(|e| matches!(e.kind, FollowKind::Queued { .. }))
    }

    /// Every event so far, in (cycle, unit, the unit's order) order.
    pub fn events(&self) -> Vec<FollowEvent> {
        let mut v = self.0.events.lock().expect("not poisoned").clone();
        v.sort_by_key(|e| (e.cycle, e.order));
        v
    }
}

/// A unit's probe: which rays to log, and the log.
#[derive(Clone, Debug)]
pub struct Follower {
    shared: Arc<Shared>,
    unit: Arc<str>,
    index: u32,
    seq: u64,
}

impl Follower {
    fn wave(&self) -> u32 {
        self.shared.wave.load(Ordering::Relaxed)
    }

    /// Whether ray `ray_id` of the wavefront being traced is followed.
    pub fn wants(&self, ray_id: u32) -> bool {
        let w = self.wave();
        self.shared.targets.contains(&(w, ray_id))
    }

    /// The followed ray whose hit record is `index` (pixel * 2 + shadow).
    pub fn wants_hit(&self, index: u32) -> Option<u32> {
        let id = (index / 2) | if index & 1 != 0 { SHADOW_BIT } else { 0 };
        self.wants(id).then_some(id)
    }

    /// The followed ray of the wavefront before this run's (the one its
    /// shading pass shades) at `pixel`: its wavefront and id.
    pub fn wants_shade(&self, pixel: u32) -> Option<(u32, u32)> {
        let w = self.wave().checked_sub(1)?;
        self.shared
            .targets
            .iter()
            .find(|&&(tw, id)| tw == w && id & !SHADOW_BIT == pixel)
            .copied()
    }

    /// Logs an event of ray `ray_id` of the wavefront being traced.
    pub fn log(&mut self, cycle: u64, ray_id: u32, kind: FollowKind) {
        let w = self.wave();
        self.log_wave(cycle, w, ray_id, kind);
    }

    /// Logs an event of ray `ray_id` of wavefront `wave`.
    pub fn log_wave(&mut self, cycle: u64, wave: u32, ray_id: u32, kind: FollowKind) {
        self.seq += 1;
        let e = FollowEvent {
            cycle,
            unit: self.unit.clone(),
            wave,
            ray_id,
            kind,
            order: (self.index, self.seq),
        };
        self.shared.events.lock().expect("not poisoned").push(e);
    }
}
