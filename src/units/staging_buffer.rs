//! The ray staging buffer of a TM (paper §4.1, Table 1: 2 x 2 KB). Two halves of
//! one bucket each: the TPs drain one while the stream scheduler fills the other
//! through the fill port; when the drained half runs dry and the other holds a
//! complete bucket, they swap. There is no fixed mapping between TPs and rays: each
//! cycle the next ray goes to the first TP, round-robin from `cycle mod tps`, whose
//! one-entry ray link has room (so every free TP holds its next ray).

use crate::contract::RayRec;
use crate::rtl::{Ctx, LinkId, Logic, Next, Ram, Ready, Reg, Status};

use super::follow::{FollowKind, Follower};
use super::tm::TmCfg;
use super::tp_shade::SHADE_SEG;

crate::payload_struct! {
    /// Where the rays of a half traverse: the segment and what the TPs need to
    /// address its records (the scheduler has them from the segment table).
    #[derive(Default)]
    pub struct SbHeader {
        pub seg: u32,
        /// Segment base address (the header; nodes follow at +64).
        pub base: u64,
        /// Inner nodes in the segment (the triangles follow them).
        pub nodes: u32,
    }
}

crate::payload_struct! {
    /// One ray of a bucket on the fill port; `last` closes the bucket.
    pub struct SbFill {
        pub ray: RayRec,
        pub hdr: SbHeader,
        pub last: bool,
    }
}

crate::payload_struct! {
    /// A ray handed to a TP, with its half's header.
    pub struct SbRay {
        pub ray: RayRec,
        pub hdr: SbHeader,
    }
}

crate::unit! {
    /// Double-buffered ray staging buffer: one half drains to the TPs while the other fills.
    pub struct StagingBuffer : "staging_buffer" {
        new(cfg: &TmCfg; ports: StagingBufferPorts) {
            let half = cfg.half_rays();
        }
        params { half_rays: u32 = half => "HALF_RAYS", tps: u32 = ray.len() as u32 => "TPS" }
        inputs { fill: SbFill }
        outputs { }
        out_arrays { ray: SbRay }
        state {
            rays: Ram<RayRec> = Ram::new(2 * half, 1, NO_RAY).sized_by("2 * HALF_RAYS"),
            drain_half: Reg<bool> = false,
            count0: Reg<u16> = 0,
            count1: Reg<u16> = 0,
            sealed0: Reg<bool> = false,
            sealed1: Reg<bool> = false,
            hdr0: Reg<SbHeader> = SbHeader::default(),
            hdr1: Reg<SbHeader> = SbHeader::default(),
            read_idx: Reg<u16> = 0
        }
        extra {
            rays_in: u64 = 0,
            rays_out: u64 = 0,
            swaps: u64 = 0,
            // `--follow-ray`: a probe, not hardware (`units/follow.rs`).
            follow: Option<Follower> = None
        }
    }
}

const NO_RAY: RayRec = RayRec {
    origin: glam::Vec3::ZERO,
    dir: glam::Vec3::ZERO,
    ray_id: 0,
    entry: 0,
};

impl StagingBuffer {
    /// Logs the followed rays' events here (`units/follow.rs`).
    pub fn follow(&mut self, f: Follower) {
        self.follow = Some(f);
    }

    /// Logs `kind` if `ray` (not a shading item) is followed.
    fn note(&mut self, c: u64, ray: &RayRec, seg: u32, kind: impl FnOnce() -> FollowKind) {
        if let Some(f) = &mut self.follow
            && seg != SHADE_SEG
            && f.wants(ray.ray_id)
        {
            f.log(c, ray.ray_id, kind());
        }
    }

    fn count(&self, h: bool) -> u16 {
        if h {
            self.count1.val()
        } else {
            self.count0.val()
        }
    }
    fn sealed(&self, h: bool) -> bool {
        if h {
            self.sealed1.val()
        } else {
            self.sealed0.val()
        }
    }
    fn set_half(&mut self, h: bool, count: u16, sealed: bool) {
        if h {
            self.count1.set(count);
            self.sealed1.set(sealed);
        } else {
            self.count0.set(count);
            self.sealed0.set(sealed);
        }
    }
}

impl Logic for StagingBuffer {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let d = self.drain_half.val();
        let f = !d;
        let mut worked = false;
        let mut blocked = false;
        // Fill port: into the half that is not being drained, until it is sealed.
        let (fc, fs) = (self.count(f), self.sealed(f));
        if !fs
            && (fc as u32) < self.half_rays
            && let Some(x) = ctx.pop(&self.fill)
        {
            let idx = f as u32 * self.half_rays + fc as u32;
            self.rays.write(idx, x.ray);
            let (seg, half, slot) = (x.hdr.seg, f as u32, fc as u32);
            self.note(ctx.cycle(), &x.ray, seg, || FollowKind::Staged {
                seg,
                half,
                slot,
            });
            let n = fc + 1;
            self.set_half(f, n, x.last || n as u32 == self.half_rays);
            if f {
                self.hdr1.set(x.hdr);
            } else {
                self.hdr0.set(x.hdr);
            }
            self.rays_in += 1;
            worked = true;
        }
        // Drain: one ray per cycle to a TP with room.
        let ri = self.read_idx.val();
        if ri < self.count(d) {
            let n = self.ray.len();
            let start = ctx.round_robin_start(n);
            let free = (0..n)
                .map(|j| (start + j) % n)
                .find(|&p| ctx.can_push(&self.ray.at(p)));
            match free {
                Some(p) => {
                    let ray = *self.rays.read(d as u32 * self.half_rays + ri as u32);
                    let hdr = if d {
                        self.hdr1.get().clone()
                    } else {
                        self.hdr0.get().clone()
                    };
                    let (seg, tp) = (hdr.seg, p as u32);
                    self.note(ctx.cycle(), &ray, seg, || FollowKind::ToTp { seg, tp });
                    ctx.push(&self.ray.at(p), SbRay { ray, hdr });
                    self.read_idx.set(ri + 1);
                    self.rays_out += 1;
                    worked = true;
                }
                None => blocked = true,
            }
        } else if self.sealed(f) {
            // The drained half ran dry and the other holds a whole bucket: swap.
            self.drain_half.set(f);
            self.read_idx.set(0);
            self.set_half(d, 0, false);
            self.swaps += 1;
            worked = true;
        }
        ctx.set_status(if worked {
            Status::Busy
        } else if blocked {
            Status::OutputBlocked
        } else {
            Status::WaitInput
        });
        // Idle: a fill push or a TP taking its ray (a pop from a full link) wakes it.
        if worked { Next::Cycle } else { Next::Idle }
    }

    /// The fill port, while the half being filled has room and is not sealed.
    fn can_accept(&self, _port: LinkId, _at: &Ready) -> bool {
        let f = !self.drain_half.val();
        !self.sealed(f) && (self.count(f) as u32) < self.half_rays
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("rays_in", self.rays_in),
            ("rays_out", self.rays_out),
            ("swaps", self.swaps),
        ]
    }

    fn reset_counters(&mut self) {
        self.rays_in = 0;
        self.rays_out = 0;
        self.swaps = 0;
    }
}
