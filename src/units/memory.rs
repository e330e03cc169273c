//! The memory unit: owns the DRAM image (`contract::SparseMem`) and serves 64 B
//! line reads (data in the response) and line or partial writes (data and byte
//! mask in the request), one request/response port pair per client. Every request
//! is answered, writes too (the requester learns its write is done).
//!
//! Timing model `fixed` (this stage): a request accepted in cycle `a` is answered
//! so that the response is visible at `a + latency`; at most `bytes_per_cycle / 64`
//! requests are accepted per cycle over all ports (round-robin from
//! `cycle mod ports`), at most one per port. Data are applied at completion (the
//! cycle the response is pushed), in acceptance order per port.
//!
//! Seam for stage B (`gddr5`): the same ports go through a channel router to the
//! 16 `mem_ctrl` units; the controller decides when a request completes (its
//! `MemResp { id }`), and this unit applies the data at that completion. Clients
//! must therefore not rely on order across ports, nor on the order of a read
//! and an older write to the same line on one port (the controllers may reorder
//! them); every client here waits for a write's response before reading the line.

use std::collections::VecDeque;

use crate::contract::{LINE_BYTES, SparseMem};
use crate::machine::config::MemoryUnitCfg;
use crate::mem::StreamTag;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::{Behavioural, Model};
use crate::rtl::{Ctx, In, Logic, Next, Out, Status};

use super::l1::Line;

crate::payload_struct! {
    /// A line request: read (`write` = false) or write of the bytes of `data`
    /// selected by `mask` (bit i = byte i of the line).
    pub struct MemLineReq {
        pub addr: u64,
        pub write: bool,
        pub tag: StreamTag,
        /// Chosen by the requester; returned in the response.
        pub id: u32,
        pub mask: u64,
        pub data: Line,
    }
}

crate::payload_struct! {
    /// The answer: the line's bytes for a read (zeros for a write).
    pub struct MemLineResp {
        pub addr: u64,
        pub write: bool,
        pub tag: StreamTag,
        pub id: u32,
        pub data: Line,
    }
}

impl MemLineReq {
    pub fn read(addr: u64, tag: StreamTag, id: u32) -> Self {
        MemLineReq {
            addr: addr & !(LINE_BYTES - 1),
            write: false,
            tag,
            id,
            mask: 0,
            data: Line::default(),
        }
    }
}

/// Requests in flight, per port: (cycle the response is pushed, request).
#[derive(Clone, Debug, Default)]
pub struct MemPipe {
    pub ports: Vec<VecDeque<(u64, MemLineReq)>>,
}

impl MemPipe {
    pub fn in_flight(&self) -> usize {
        self.ports.iter().map(|q| q.len()).sum()
    }
}

impl Behavioural for MemPipe {
    fn declare(&self, out: &mut StateList) {
        // The DRAM and its timing model are not chip hardware: only the count of
        // requests in flight is shown.
        out.items.push(StateDecl::reg("in_flight", 16));
    }
    fn sample(&self, out: &mut Samples) {
        out.slot().push(self.in_flight() as u64, 16);
    }
    fn reset(&mut self) {
        self.ports.iter_mut().for_each(|q| q.clear());
    }
}

crate::unit! {
    /// Memory unit: the DRAM image behind line request ports (fixed latency and bandwidth).
    pub struct Memory : "memory" {
        params {
            ports_n: u32 => "PORTS",
            latency: u32 => "LATENCY",
            lines_per_cycle: u32 => "LINES_PER_CYCLE"
        }
        inputs { }
        outputs { }
        in_arrays { req: MemLineReq }
        out_arrays { resp: MemLineResp }
        state { pipe: Model<MemPipe> }
        extra {
            out_delay: u32,
            image: SparseMem,
            lines_read: [u64; StreamTag::COUNT],
            lines_written: [u64; StreamTag::COUNT],
            requests: u64,
            responses: u64
        }
    }
}

impl Memory {
    pub fn new(
        cfg: &MemoryUnitCfg,
        out_delay: u32,
        image: SparseMem,
        req: Vec<In<MemLineReq>>,
        resp: Vec<Out<MemLineResp>>,
    ) -> Self {
        assert_eq!(req.len(), resp.len(), "one response port per request port");
        let n = req.len();
        Memory {
            ports_n: n as u32,
            latency: cfg.latency,
            lines_per_cycle: (cfg.bytes_per_cycle / LINE_BYTES as u32).max(1),
            req,
            resp,
            pipe: Model::new(MemPipe {
                ports: vec![VecDeque::new(); n],
            }),
            out_delay,
            image,
            lines_read: [0; StreamTag::COUNT],
            lines_written: [0; StreamTag::COUNT],
            requests: 0,
            responses: 0,
        }
    }

    /// Requests accepted and not yet answered.
    pub fn in_flight(&self) -> usize {
        self.pipe.r().in_flight()
    }

    fn complete(&mut self, r: &MemLineReq) -> MemLineResp {
        let mut data = Line::default();
        if r.write {
            if r.mask == u64::MAX {
                self.image.write(r.addr, &r.data.0);
            } else {
                // Runs of enabled bytes.
                let mut i = 0usize;
                while i < 64 {
                    if r.mask >> i & 1 == 1 {
                        let s = i;
                        while i < 64 && r.mask >> i & 1 == 1 {
                            i += 1;
                        }
                        self.image.write(r.addr + s as u64, &r.data.0[s..i]);
                    } else {
                        i += 1;
                    }
                }
            }
            self.lines_written[r.tag as usize] += 1;
        } else {
            self.image.read(r.addr, &mut data.0);
            self.lines_read[r.tag as usize] += 1;
        }
        self.responses += 1;
        MemLineResp {
            addr: r.addr,
            write: r.write,
            tag: r.tag,
            id: r.id,
            data,
        }
    }
}

impl Logic for Memory {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let n = self.ports_n as usize;
        let mut worked = false;
        let mut blocked = false;
        // Completions: the oldest due request of each port, if its link has room.
        for p in 0..n {
            let due = matches!(self.pipe.r().ports[p].front(), Some((d, _)) if *d <= c);
            if !due {
                continue;
            }
            if !ctx.can_push(&self.resp[p]) {
                blocked = true;
                continue;
            }
            let (_, r) = self.pipe.m().ports[p].pop_front().expect("due");
            let resp = self.complete(&r);
            ctx.push(&self.resp[p], resp);
            worked = true;
        }
        // Acceptance: round-robin, one per port, `lines_per_cycle` in all.
        let mut budget = self.lines_per_cycle;
        let mut left_waiting = false;
        let due_at = c + self.latency as u64 - self.out_delay as u64;
        for j in 0..n {
            let p = (c as usize + j) % n;
            if ctx.peek(&self.req[p]).is_none() {
                continue;
            }
            if budget == 0 {
                left_waiting = true;
                continue;
            }
            let r = ctx.pop(&self.req[p]).expect("peeked");
            self.requests += 1;
            self.pipe.m().ports[p].push_back((due_at, r));
            budget -= 1;
            worked = true;
        }
        ctx.set_status(if blocked {
            Status::OutputBlocked
        } else if left_waiting {
            Status::ResourceBusy
        } else if worked || self.in_flight() > 0 {
            Status::Busy
        } else {
            Status::WaitInput
        });
        if worked || left_waiting {
            return Next::Cycle;
        }
        // Sleep to the next completion that is not blocked (a blocked one is woken
        // by its link draining).
        let next = self
            .pipe
            .r()
            .ports
            .iter()
            .filter_map(|q| q.front().map(|(d, _)| *d))
            .filter(|&d| d > c)
            .min();
        match next {
            Some(d) => Next::AtCycle(d),
            None => Next::Idle,
        }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let mut v = vec![("requests", self.requests), ("responses", self.responses)];
        const R: [&str; 5] = [
            "ray_lines_read",
            "scene_lines_read",
            "hit_lines_read",
            "shading_lines_read",
            "other_lines_read",
        ];
        const W: [&str; 5] = [
            "ray_lines_written",
            "scene_lines_written",
            "hit_lines_written",
            "shading_lines_written",
            "other_lines_written",
        ];
        for k in 0..StreamTag::COUNT {
            v.push((R[k], self.lines_read[k]));
            v.push((W[k], self.lines_written[k]));
        }
        v
    }

    fn reset_counters(&mut self) {
        self.lines_read = [0; StreamTag::COUNT];
        self.lines_written = [0; StreamTag::COUNT];
        self.requests = 0;
        self.responses = 0;
    }
}
