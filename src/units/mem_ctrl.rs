//! The GDDR5 memory controller of one channel, on the DRAM command clock.
//!
//! A requester pushes a `MemReq` (line address, read/write, stream tag, id) into
//! `req`; the controller queues it (read and write queues of the configured
//! depths; a full queue leaves it waiting in the link), schedules DRAM commands
//! FR-FCFS with an open-page policy (`mem::ctrl`), and pushes a `MemResp` (id,
//! tag, write) into `resp` so that it is visible to the requester exactly when the
//! last data beat ends: CL + burst cycles after the last RD for a read, CWL +
//! burst after the last WR for a write. Responses come back in completion order,
//! not request order; route them by id.
//!
//! The address must belong to this controller's channel (decode it with
//! `mem::AddrMap`); others are counted as `bad_addresses`.

pub use crate::mem::{MemReq, MemResp, StreamTag};

use crate::mem::config::CtrlPolicy;
use crate::mem::{ChannelCtrl, MemCfg};
use crate::rtl::{Ctx, LinkId, Logic, Next, Ready, Status};

crate::unit! {
    /// GDDR5 channel controller: FR-FCFS, open page, write drain, refresh.
    pub struct MemCtrl : "mem_ctrl" {
        /// Controller of channel `channel` of `cfg` (validated), DRAM clock `tck_ps`;
        /// `resp` must have the delay `cfg.ctrl.resp_link.delay`.
        new(cfg: &MemCfg, tck_ps: u64, channel: u32; ports: MemCtrlPorts) {}
        params {
            channel: u32 = channel => "CHANNEL",
            banks: u32 = cfg.geometry.banks() => "BANKS",
            read_queue: u32 = cfg.ctrl.read_queue => "READ_QUEUE",
            write_queue: u32 = cfg.ctrl.write_queue => "WRITE_QUEUE"
        }
        inputs { req: MemReq }
        outputs { resp: MemResp }
        state { ctrl: ChannelCtrl = ChannelCtrl::new(cfg, tck_ps, channel) }
        extra {
            resp_delay: u64 = cfg.ctrl.resp_link.delay as u64,
            // CL + one burst: a read's latency.
            stall_poll: u64 = (cfg.timing.cl + cfg.geometry.burst_cycles()).max(1) as u64
        }
    }
}

impl MemCtrl {
    /// The unit schedules FR-FCFS (`mem::ctrl`); DRAMsim3's controller rules
    /// (`mem::dramsim3`) run in the trace replay only.
    pub fn supports(cfg: &MemCfg) -> Result<(), super::UnitError> {
        match cfg.ctrl.policy {
            CtrlPolicy::Frfcfs => Ok(()),
            CtrlPolicy::Dramsim3 => Err(super::UnitError::Unsupported(
                "mem.ctrl.policy = \"dramsim3\" (DRAMsim3's controller) runs only in trace replay (`dualstream dram`); the mem_ctrl unit schedules FR-FCFS: set mem.ctrl.policy = \"frfcfs\""
                    .into(),
            )),
        }
    }
}

impl Logic for MemCtrl {
    /// While the read or the write queue has room, or a command due this
    /// cycle may free one (which queue a request needs, its `write` says).
    fn can_accept(&self, _port: LinkId, at: &Ready) -> bool {
        self.ctrl.can_accept(false)
            || self.ctrl.can_accept(true)
            || self.ctrl.next_event() <= at.cycle()
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let d = self.resp_delay;
        // Hand over the oldest finished response, `d` cycles before its data ends.
        let mut stalled = false;
        if let Some(r) = self.ctrl.peek_response(c + d).cloned() {
            if ctx.offer(&self.resp, r) {
                self.ctrl.pop_response(c, c + d);
            } else {
                stalled = true;
            }
        }
        let waiting = ctx.peek(&self.req).map(|r| r.write);
        let (rq, wq, _) = self.ctrl.queue_lengths();
        if rq == 0 && wq == 0 && waiting.is_none() {
            // No request to schedule: the command engine rests (refreshes that
            // fall due meanwhile are caught up by `advance_to` when one arrives).
            // Only finished responses may wait: wake for the next one, or, when
            // the link is full, when it drains (the kernel wakes us). A wake-up
            // for the refresh deadline here would outlive the work and hold the
            // pass open for up to tREFI after its last ray.
            let next = self.ctrl.next_response();
            ctx.set_status(if stalled {
                Status::OutputBlocked
            } else if next.is_some() {
                Status::Busy
            } else {
                Status::WaitInput
            });
            return match next {
                Some(r) if !stalled => Next::AtCycle(r.saturating_sub(d).max(c + 1)),
                _ => Next::Idle,
            };
        }
        // Refreshes that fell due while idle, then this cycle's command, then the
        // new request (it joins the queue at the edge, as a registered write).
        self.ctrl.advance_to(c);
        self.ctrl.step(c);
        let mut blocked = false;
        let mut more = false;
        if let Some(w) = waiting {
            if self.ctrl.can_accept(w) {
                let r = ctx.pop(&self.req).expect("peeked");
                self.ctrl.accept(c, r);
                more = ctx.holds_more(&self.req);
            } else {
                blocked = true;
            }
        }
        // A request left behind the one taken is taken in the next cycle (its
        // wake-up may have passed); otherwise the next cycle's evaluation only to
        // learn that no command can go is spared. A refused request needs none:
        // the queue has room again only after a command, and `look_ahead` wakes
        // the controller for the next one.
        if !more {
            self.ctrl.look_ahead(c);
        }
        ctx.set_status(if stalled {
            Status::OutputBlocked
        } else if blocked {
            Status::ResourceBusy
        } else if self.ctrl.is_idle() {
            Status::WaitInput
        } else {
            Status::Busy
        });
        if self.ctrl.is_idle() {
            return Next::Idle;
        }
        let mut n = self.ctrl.next_event();
        if !stalled && let Some(r) = self.ctrl.next_response() {
            n = n.min(r.saturating_sub(d));
        }
        // A stalled response is retried when the link drains (the kernel wakes us).
        // Meanwhile the engine may have nothing to do before the refresh deadline;
        // a wake-up that far ahead outlives the queue when it empties after the
        // stall and holds the pass open for up to tREFI after its last ray, so a
        // stalled controller re-checks once per read latency instead (the extra
        // evaluations do nothing: `step` acts only at `next_event`).
        if stalled {
            n = n.min(c + self.stall_poll);
        }
        if n == u64::MAX {
            Next::Idle
        } else {
            Next::AtCycle(n.max(c + 1))
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        self.ctrl.counters()
    }
}

impl MemCtrl {
    /// Records the issued DRAM commands (`chip.memory.check_timing`).
    pub fn record_commands(&mut self, on: bool) {
        self.ctrl.record_commands(on);
    }
    /// The channel's statistics up to DRAM cycle `end` (a probe: the controller
    /// is not advanced).
    pub fn stats_at(&self, end: u64) -> crate::mem::stats::ChannelStats {
        self.ctrl.stats_at(end)
    }
    /// The commands issued up to DRAM cycle `end` (empty unless recorded).
    pub fn commands_until(&self, end: u64) -> Vec<crate::mem::Command> {
        self.ctrl.commands_until(end)
    }
}
