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

use crate::mem::{ChannelCtrl, MemCfg};
use crate::rtl::{Ctx, In, Logic, Next, Out, Status};

crate::unit! {
    /// GDDR5 channel controller: FR-FCFS, open page, write drain, refresh.
    pub struct MemCtrl : "mem_ctrl" {
        params {
            channel: u32 => "CHANNEL",
            banks: u32 => "BANKS",
            read_queue: u32 => "READ_QUEUE",
            write_queue: u32 => "WRITE_QUEUE"
        }
        inputs { req: MemReq }
        outputs { resp: MemResp }
        state { ctrl: ChannelCtrl }
        extra { resp_delay: u64 }
    }
}

impl MemCtrl {
    /// Controller of channel `channel` of `cfg` (validated), DRAM clock `tck_ps`;
    /// `resp` must have the delay `cfg.ctrl.resp_link.delay`.
    pub fn new(
        cfg: &MemCfg,
        tck_ps: u64,
        channel: u32,
        req: In<MemReq>,
        resp: Out<MemResp>,
    ) -> Self {
        MemCtrl {
            channel,
            banks: cfg.geometry.banks(),
            read_queue: cfg.ctrl.read_queue,
            write_queue: cfg.ctrl.write_queue,
            req,
            resp,
            ctrl: ChannelCtrl::new(cfg, tck_ps, channel),
            resp_delay: cfg.ctrl.resp_link.delay as u64,
        }
    }
}

impl Logic for MemCtrl {
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
        if self.ctrl.is_idle() && waiting.is_none() {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        }
        // Refreshes that fell due while idle, then this cycle's command, then the
        // new request (it joins the queue at the edge, as a registered write).
        self.ctrl.advance_to(c);
        self.ctrl.step(c);
        let mut blocked = false;
        if let Some(w) = waiting {
            if self.ctrl.can_accept(w) {
                let r = ctx.pop(&self.req).expect("peeked");
                self.ctrl.accept(c, r);
            } else {
                blocked = true;
            }
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
