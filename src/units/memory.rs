//! The memory unit: owns the DRAM image (`contract::SparseMem`) and serves 64 B
//! line reads (data in the response) and line or partial writes (data and byte
//! mask in the request), one request/response port pair per client lane (a client
//! that moves several lines per cycle, such as the stream scheduler's ray and scene
//! lanes, has a port per line per cycle). Every request is answered, writes too
//! (the requester learns its write is done).
//!
//! Timing model `fixed` (`chip.memory.model`, the default): a request accepted in cycle `a` is answered
//! so that the response is visible at `a + latency`; at most `bytes_per_cycle / 64`
//! requests are accepted per cycle over all ports (round-robin from
//! `cycle mod ports`), at most one per port. Data are applied at completion (the
//! cycle the response is pushed), in acceptance order per port.
//!
//! Timing model `gddr5` (stage B): this unit is also the channel router. It
//! accepts at most one request per port per cycle, decodes its channel with the
//! address mapping (`mem::AddrMap`) and pushes a `MemReq { addr, write, tag, id }`
//! into `ch_req[channel]` (at most one per channel link per cycle; a full link
//! leaves the request waiting in its port), `id` being the slot of an in-flight
//! table that remembers the port and the request. The `mem_ctrl` units (DRAM
//! clock) decide when a request completes: when the controller's `MemResp { id }`
//! is taken from `ch_resp[channel]` (visible when the last data beat ends), this
//! unit applies the data to the image (read: the line's bytes; write: the masked
//! bytes) and pushes the answer into `resp[port]` in the same cycle (one per port
//! per cycle; a full port leaves the controller's response in its link).
//! Clients must therefore not rely on order across ports, nor on the order of a
//! read and an older write to the same line on one port (the controllers may
//! reorder them); every client here waits for a write's response before reading
//! the line.

use std::collections::VecDeque;

use crate::contract::{LINE_BYTES, SparseMem};
use crate::mem::{AddrMap, MemReq, MemResp, StreamTag};
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::{Behavioural, Model};
use crate::rtl::{Ctx, In, LinkId, Logic, Next, Out, Ready, Status};

use super::l1::Line;

use serde::{Deserialize, Serialize};

/// Which timing model serves the memory unit's lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryModel {
    /// Fixed latency and a bandwidth limit (the "simple memory" switch of the
    /// paper group's simulator): an explicit choice (`--memory fixed`) for
    /// tests and quick looks; it misses the DRAM's row and bank effects
    /// (docs/speed-error.md measures what that costs).
    Fixed,
    /// The memory unit routes every line by the address mapping (`mem.mapping`)
    /// to one `mem_ctrl` unit per channel (`mem.geometry.channels`, 16) on the
    /// DRAM clock (`clocks.dram_ps`): timing, bandwidth, row hits and energy come
    /// from the GDDR5 model (`[mem]`), data from the DRAM image. The default:
    /// the paper's memory system [DS17 Table 1, §5.1] ("a full memory
    /// simulator is essential"); `latency` and `bytes_per_cycle` are then unused.
    Gddr5,
}

/// The memory unit (DRAM image + timing).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MemoryUnitCfg {
    /// The timing model in cycle mode: "gddr5" (the paper's 16 channels, as
    /// `[mem]` configures them; default) or "fixed" (`latency` and
    /// `bytes_per_cycle` below; `--memory` overrides it).
    pub model: MemoryModel,
    /// `fixed`: cycles from acceptance of a line request to its response being
    /// visible to the requester (response link included). Assumption: 100 core
    /// cycles, a loaded GDDR5 access at 1 GHz.
    pub latency: u32,
    /// `fixed`: peak bandwidth in bytes per core cycle: 512 GB/s at 1 GHz
    /// [DS17 §5.1] = 512 B = 8 lines per cycle.
    pub bytes_per_cycle: u32,
    /// `gddr5`: record every DRAM command and run the independent timing checker
    /// (`mem::checker`) after every wavefront; a violation stops the run. Costs
    /// memory and time: for tests.
    pub check_timing: bool,
}

impl MemoryModel {
    /// The model by its configuration name (`fixed`, `gddr5`), e.g. from `--memory`.
    pub fn parse(s: &str) -> Result<MemoryModel, super::UnitError> {
        match s {
            "fixed" => Ok(MemoryModel::Fixed),
            "gddr5" => Ok(MemoryModel::Gddr5),
            _ => Err(super::UnitError::UnknownMemoryModel {
                given: s.to_string(),
            }),
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            MemoryModel::Fixed => "fixed",
            MemoryModel::Gddr5 => "gddr5",
        }
    }
}

impl Default for MemoryUnitCfg {
    fn default() -> Self {
        MemoryUnitCfg {
            model: MemoryModel::Gddr5,
            latency: 100,
            bytes_per_cycle: 512,
            check_timing: false,
        }
    }
}

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

/// Requests in flight. `fixed`: per port, (cycle the response is pushed,
/// request). `gddr5`: the table indexed by the controllers' `id` (port, request),
/// with its free slots (reused last-freed first).
#[derive(Clone, Debug, Default)]
pub struct MemPipe {
    pub ports: Vec<VecDeque<(u64, MemLineReq)>>,
    pub table: Vec<Option<(u8, MemLineReq)>>,
    pub free: Vec<u32>,
}

impl MemPipe {
    pub fn in_flight(&self) -> usize {
        self.ports.iter().map(|q| q.len()).sum::<usize>() + self.table.len() - self.free.len()
    }
    fn alloc(&mut self, port: u8, r: MemLineReq) -> u32 {
        match self.free.pop() {
            Some(i) => {
                self.table[i as usize] = Some((port, r));
                i
            }
            None => {
                self.table.push(Some((port, r)));
                (self.table.len() - 1) as u32
            }
        }
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
        self.table.clear();
        self.free.clear();
    }
}

crate::unit! {
    /// Memory unit: the DRAM image behind line request ports (fixed latency and bandwidth, or routed to the GDDR5 channel controllers).
    pub struct Memory : "memory" {
        /// With the fixed timing model; `with_channels` routes it to the GDDR5
        /// channel controllers (`ch_req`, `ch_resp`: empty until then).
        new(cfg: &MemoryUnitCfg, out_delay: u32, image: SparseMem; ports: MemoryPorts) {
            assert_eq!(req.len(), resp.len(), "one response port per request port");
            let n = req.len();
        }
        params {
            ports_n: u32 = n as u32 => "PORTS",
            latency: u32 = cfg.latency => "LATENCY",
            lines_per_cycle: u32 =
                (cfg.bytes_per_cycle / LINE_BYTES as u32).max(1) => "LINES_PER_CYCLE",
            channels: u32 = 0 => "CHANNELS"
        }
        inputs { }
        outputs { }
        in_arrays { req: MemLineReq, ch_resp: MemResp }
        out_arrays { resp: MemLineResp, ch_req: MemReq }
        state {
            pipe: Model<MemPipe> = MemPipe {
                ports: vec![VecDeque::new(); n],
                ..MemPipe::default()
            }
        }
        extra {
            out_delay: u32 = out_delay,
            map: Option<AddrMap> = None,
            image: SparseMem = image,
            lines_read: [u64; StreamTag::COUNT] = [0; StreamTag::COUNT],
            lines_written: [u64; StreamTag::COUNT] = [0; StreamTag::COUNT],
            requests: u64 = 0,
            responses: u64 = 0
        }
    }
}

impl Memory {
    /// Timing model `gddr5`: route to the channel controllers through
    /// `ch_req[c]`/`ch_resp[c]` (channel `c` of `map`).
    pub fn with_channels(
        mut self,
        map: AddrMap,
        ch_req: Vec<Out<MemReq>>,
        ch_resp: Vec<In<MemResp>>,
    ) -> Self {
        assert_eq!(ch_req.len(), ch_resp.len(), "one response link per channel");
        self.channels = ch_req.len() as u32;
        self.latency = 0;
        self.lines_per_cycle = 0;
        self.map = Some(map);
        self.ch_req = ch_req.into();
        self.ch_resp = ch_resp.into();
        self
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

impl Memory {
    /// One cycle of the `gddr5` model (see the module docs).
    fn eval_routed(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let n = self.ports_n as usize;
        let nch = self.channels as usize;
        let mut worked = false;
        let mut blocked = false;
        // Completions: round-robin over the channels, one answer per port.
        let mut port_used = vec![false; n];
        for j in 0..nch {
            let ch = (c as usize + j) % nch;
            let Some(id) = ctx.peek(&self.ch_resp.at(ch)).map(|r| r.id) else {
                continue;
            };
            let p = self.pipe.r().table[id as usize]
                .as_ref()
                .expect("response to a live request")
                .0 as usize;
            if port_used[p] || !ctx.can_push(&self.resp.at(p)) {
                blocked = true;
                continue;
            }
            ctx.pop(&self.ch_resp.at(ch)).expect("peeked");
            let pipe = self.pipe.m();
            let (_, r) = pipe.table[id as usize].take().expect("live");
            pipe.free.push(id);
            let resp = self.complete(&r);
            ctx.push(&self.resp.at(p), resp);
            port_used[p] = true;
            worked = true;
        }
        // Acceptance: round-robin over the ports, one request per channel link.
        let mut ch_used = vec![false; nch];
        let mut left_waiting = false;
        for j in 0..n {
            let p = (c as usize + j) % n;
            let Some(r) = ctx.peek(&self.req.at(p)) else {
                continue;
            };
            let ch = self
                .map
                .as_ref()
                .expect("gddr5 has a map")
                .decode(r.addr)
                .map(|l| l.channel as usize)
                .unwrap_or(0);
            if ch_used[ch] || !ctx.can_push(&self.ch_req.at(ch)) {
                left_waiting = true;
                continue;
            }
            let r = ctx.pop(&self.req.at(p)).expect("peeked");
            self.requests += 1;
            let (addr, write, tag) = (r.addr, r.write, r.tag);
            let id = self.pipe.m().alloc(p as u8, r);
            ctx.push(
                &self.ch_req[ch],
                MemReq {
                    addr,
                    write,
                    tag,
                    id,
                },
            );
            ch_used[ch] = true;
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
        // Anything left waiting is retried when a full link drains (the kernel
        // wakes us) or next cycle if only this cycle's one-per-link rule held it.
        if worked { Next::Cycle } else { Next::Idle }
    }
}

impl Logic for Memory {
    /// With the fixed timing, a port always (the round-robin shares the
    /// cycle's line budget among them); routed to the channels, a request
    /// port while a channel link has room and a completion while a response
    /// port has (which one, the address or the id decides).
    fn can_accept(&self, port: LinkId, at: &Ready) -> bool {
        if self.map.is_none() {
            return true;
        }
        if self.req.index_of(port).is_some() {
            self.ch_req.iter().any(|o| at.out_ready(o))
        } else {
            self.resp.iter().any(|o| at.out_ready(o))
        }
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if self.map.is_some() {
            return self.eval_routed(ctx);
        }
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
            if !ctx.can_push(&self.resp.at(p)) {
                blocked = true;
                continue;
            }
            let (_, r) = self.pipe.m().ports[p].pop_front().expect("due");
            let resp = self.complete(&r);
            ctx.push(&self.resp.at(p), resp);
            worked = true;
        }
        // Acceptance: round-robin, one per port, `lines_per_cycle` in all.
        let mut budget = self.lines_per_cycle;
        let mut left_waiting = false;
        let due_at = c + self.latency as u64 - self.out_delay as u64;
        for j in 0..n {
            let p = (c as usize + j) % n;
            if ctx.peek(&self.req.at(p)).is_none() {
                continue;
            }
            if budget == 0 {
                left_waiting = true;
                continue;
            }
            let r = ctx.pop(&self.req.at(p)).expect("peeked");
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

/// What the chip top reads of the memory unit: requests and answers so far,
/// and the lines answered by stream tag (a probe, not hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryProbe {
    pub requests: u64,
    pub responses: u64,
    pub lines_read: [u64; StreamTag::COUNT],
    pub lines_written: [u64; StreamTag::COUNT],
    /// Requests accepted and not yet answered.
    pub in_flight: usize,
}

impl Memory {
    /// The counters (see [`MemoryProbe`]).
    pub fn probe(&self) -> MemoryProbe {
        MemoryProbe {
            requests: self.requests,
            responses: self.responses,
            lines_read: self.lines_read,
            lines_written: self.lines_written,
            in_flight: self.in_flight(),
        }
    }
    /// Exchanges the DRAM image with `image`: the chip lends it for a run and
    /// takes it back for the host.
    pub fn swap_image(&mut self, image: &mut SparseMem) {
        std::mem::swap(&mut self.image, image);
    }
    /// Replaces the DRAM image (a sampling window's snapshot).
    pub fn set_image(&mut self, image: SparseMem) {
        self.image = image;
    }
}
