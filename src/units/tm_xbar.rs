//! The TM crossbar: connects the TPs to the TM-shared divider, ray-box pipeline and
//! ray-triangle pipelines, and merges their duplicates and hit updates into the TM's
//! two outside ports. It holds the ray-box pipeline (paper §5.1) between two FIFOs
//! with the timing of the TM's links (`box_req_q`, `box_resp_q`): one box test
//! takes the same cycles as through a separate unit on two links, but moves as
//! plain data inside one evaluation, where two kernel link hops per test were an
//! eighth of the chip's simulation time (docs/kernel.md).
//!
//! Arbitration: per shared resource, one request per cycle, round-robin from the TP
//! `cycle mod tps` on, a function of absolute time, so it does not depend on when
//! the crossbar was evaluated (sleeping stays exact). A triangle request goes to the
//! pipeline with room in its input link and the fewest tests in flight (ties: the
//! lowest index). Responses return by tag (TP index in the low byte; global memory:
//! the `id`, which a TP sets to its index). The crossbar is
//! one register stage each way: it adds the link delay to every round trip.

use super::box_pipe::{BoxReq, BoxResp, box_test};
use super::divider::{DivReq, DivResp};
use super::memory::{MemLineReq, MemLineResp};
use super::tp::{HitUpdate, RayWrite};
use super::tri_pipe::{TriReq, TriResp};
use crate::rtl::{
    Ctx, FixedPipe, In, LinkId, LocalEnds, LocalLink, Logic, Next, Out, Payload, PortArray, Ram,
    Ready, Status,
};

crate::unit! {
    /// TM crossbar: round-robin arbitration of the TPs onto the shared units and outputs.
    pub struct TmXbar : "tm_xbar" {
        /// The ray-box pipeline it holds is built from `cfg`: its request FIFO,
        /// the pipeline and its result FIFO (both FIFOs with the TM's link
        /// timing). The pipeline's latency counts its result FIFO's delay, as a
        /// separate unit's counts its output link's, so a test takes
        /// `box_pipe.latency` from grant to routing.
        new(cfg: &super::tm::TmSpec; ports: TmXbarPorts) {
            let (l, np) = (cfg.link, tri_req.len() as u32);
        }
        params {
            tps: u32 = tp_div_req.len() as u32 => "TPS",
            tri_pipes: u32 = np => "TRI_PIPES",
            box_latency: u32 = cfg.box_pipe.latency => "BOX_LATENCY",
            box_interval: u32 = cfg.box_pipe.interval => "BOX_II"
        }
        inputs { div_resp: DivResp, gmem_resp: MemLineResp }
        outputs {
            div_req: DivReq,
            ray_write: RayWrite,
            hit: HitUpdate,
            gmem_req: MemLineReq
        }
        in_arrays {
            tp_div_req: DivReq,
            tp_box_req: BoxReq,
            tp_tri_req: TriReq,
            tp_ray_write: RayWrite,
            tp_hit: HitUpdate,
            tp_gmem_req: MemLineReq,
            tri_resp: TriResp
        }
        out_arrays {
            tp_div_resp: DivResp,
            tp_box_resp: BoxResp,
            tp_tri_resp: TriResp,
            tp_gmem_resp: MemLineResp,
            tri_req: TriReq
        }
        state {
            tri_outstanding: Ram<u16> = Ram::new(np, np, 0).sized_by("TRI_PIPES"),
            box_req_q: LocalLink<BoxReq> = LocalLink::new(l),
            box_pipe: FixedPipe<BoxReq> =
                FixedPipe::new(cfg.box_pipe.latency - l.delay, cfg.box_pipe.interval),
            box_resp_q: LocalLink<BoxResp> = LocalLink::new(l)
        }
        extra { stats: XbarStats = XbarStats::default() }
    }
}

/// Grants and losses per class: divider, box, triangle, ray write, hit, global
/// memory (shading's loads and stores through the L2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct XbarStats {
    pub grants: [u64; 6],
    /// Request-cycles a TP waited while another TP was granted or the unit was full
    /// (a wait in progress is added when it ends, see `wait`).
    pub conflicts: [u64; 6],
    /// A wait in progress: from cycle `.0` on, every cycle adds `.1` to `conflicts`
    /// (not yet added). While the crossbar only waits (nothing granted, nothing
    /// routed) nothing it sees can change until a push wakes it (a new request or
    /// response) or a pop frees a full output (which wakes its producer), so it
    /// sleeps and counts the wait in one step when it is evaluated again with a
    /// different picture. Simulation bookkeeping, not hardware state.
    pub wait: Option<(u64, [u64; 6])>,
}

pub const CLASSES: [&str; 6] = ["div", "box", "tri", "ray_write", "hit", "gmem"];

/// Round-robin pick among `inputs` with a visible head, from `start`; counts the
/// losers. Pops the winner only if `grant`; `more` is set if its link holds
/// another entry.
fn pick<T: Payload>(
    ctx: &mut Ctx,
    inputs: &PortArray<In<T>>,
    start: usize,
    grant: bool,
    conflicts: &mut u64,
    more: &mut bool,
) -> Option<(usize, T)> {
    let n = inputs.len();
    if n <= 64 {
        // The same choice from a bit mask of the visible heads: the first at or after
        // `start`, else the first; every other visible head is a conflict.
        let mask = ctx.visible_mask(inputs);
        if mask == 0 {
            return None;
        }
        let visible = mask.count_ones() as u64;
        if !grant {
            *conflicts += visible;
            return None;
        }
        let hi = mask & (!0u64 << start);
        let k = if hi != 0 { hi } else { mask }.trailing_zeros() as usize;
        *conflicts += visible - 1;
        let v = ctx.pop(&inputs.at(k)).expect("visible");
        *more |= ctx.holds_more(&inputs.at(k));
        return Some((k, v));
    }
    let mut won = None;
    // `start..n` then `0..start`: the round-robin order without a division per input.
    let order = (start..n).chain(0..start);
    for k in order {
        if !ctx.has_input(&inputs[k]) {
            continue;
        }
        if grant && won.is_none() {
            won = Some((k, ctx.pop(&inputs[k]).expect("peeked")));
            *more |= ctx.holds_more(&inputs[k]);
        } else {
            *conflicts += 1;
        }
    }
    won
}

/// Moves the head of `inp` to the output its tag names: (moved, blocked); `more`
/// is set if `inp` holds another entry.
fn route<T: Payload>(
    ctx: &mut Ctx,
    inp: &In<T>,
    outs: &PortArray<Out<T>>,
    tag: impl Fn(&T) -> u16,
    more: &mut bool,
) -> (bool, bool) {
    let Some(v) = ctx.peek(inp) else {
        return (false, false);
    };
    let out = outs.at((tag(v) & 0xFF) as usize);
    if !ctx.can_push(&out) {
        return (false, true);
    }
    let v = ctx.pop(inp).expect("peeked");
    *more |= ctx.holds_more(inp);
    ctx.push(&out, v);
    (true, false)
}

/// `route` for the ray-box pipeline's result FIFO in cycle `c`: (moved, blocked).
fn route_local(
    ctx: &mut Ctx,
    c: u64,
    inp: &mut LocalLink<BoxResp>,
    outs: &PortArray<Out<BoxResp>>,
) -> (bool, bool) {
    let Some(v) = inp.peek(c) else {
        return (false, false);
    };
    let out = outs.at((v.tag & 0xFF) as usize);
    if !ctx.can_push(&out) {
        return (false, true);
    }
    let v = inp.pop(c).expect("peeked");
    ctx.push(&out, v);
    (true, false)
}

/// Adds the conflicts of a wait in progress for its cycles before `c`.
fn flush_wait(s: &mut XbarStats, c: u64) {
    if let Some((since, w)) = s.wait.take() {
        for (k, n) in w.iter().enumerate() {
            s.conflicts[k] += n * (c - since);
        }
    }
}

/// What one evaluation did, for its status, its statistics and its next
/// evaluation.
#[derive(Clone, Copy, Debug, Default)]
struct Outcome {
    worked: bool,
    waiting: bool,
    /// An input popped this cycle holds another entry.
    more: bool,
    /// This cycle's conflicts, per class (added to the stats at the end).
    cf: [u64; 6],
}

/// The triangle pipelines' tests in flight, as working copies on the stack (the
/// config allows at most 8 pipes): this runs every busy cycle, so no allocation.
#[derive(Clone, Copy, Debug, Default)]
struct TriCounts {
    outstanding: [u16; 8],
    changed: [bool; 8],
}

/// Grants class `k`'s round-robin pick among `inputs` onto `out` if it has room.
fn forward<T: Payload>(
    ctx: &mut Ctx,
    inputs: &PortArray<In<T>>,
    out: &Out<T>,
    start: usize,
    k: usize,
    grants: &mut u64,
    o: &mut Outcome,
) {
    let free = ctx.can_push(out);
    if let Some((_, v)) = pick(ctx, inputs, start, free, &mut o.cf[k], &mut o.more) {
        ctx.push(out, v);
        *grants += 1;
        o.worked = true;
    }
    o.waiting |= o.cf[k] > 0;
}

impl TmXbar {
    /// Responses of the divider, the ray-box pipeline and global memory back to
    /// their TPs; returns whether a box result was routed.
    fn route_responses(&mut self, ctx: &mut Ctx, c: u64, o: &mut Outcome) -> bool {
        let box_routed;
        for (w, b) in [
            route(
                ctx,
                &self.div_resp,
                &self.tp_div_resp,
                |r| r.tag,
                &mut o.more,
            ),
            {
                let r = route_local(ctx, c, &mut self.box_resp_q, &self.tp_box_resp);
                box_routed = r.0;
                r
            },
            route(
                ctx,
                &self.gmem_resp,
                &self.tp_gmem_resp,
                |r| r.id as u16,
                &mut o.more,
            ),
        ] {
            o.worked |= w;
            o.waiting |= b;
        }
        box_routed
    }

    /// The triangle pipelines' tests in flight, from their registers.
    fn load_tri_counts(&self) -> TriCounts {
        let mut tri = TriCounts::default();
        let np = self.tri_pipes as usize;
        for (p, t) in tri.outstanding.iter_mut().enumerate().take(np) {
            *t = *self.tri_outstanding.read(p as u32);
        }
        tri
    }

    /// The triangle pipelines' results back to their TPs.
    fn route_tri_responses(&mut self, ctx: &mut Ctx, tri: &mut TriCounts, o: &mut Outcome) {
        for p in 0..self.tri_resp.len() {
            let resp = self.tri_resp.at(p);
            let (w, b) = route(ctx, &resp, &self.tp_tri_resp, |r| r.tag, &mut o.more);
            if w {
                tri.outstanding[p] -= 1;
                tri.changed[p] = true;
            }
            o.worked |= w;
            o.waiting |= b;
        }
    }

    /// This cycle's divider grant.
    fn grant_div(&mut self, ctx: &mut Ctx, start: usize, o: &mut Outcome) {
        let g = &mut self.stats.grants[0];
        forward(ctx, &self.tp_div_req, &self.div_req, start, 0, g, o);
    }

    /// This cycle's grants onto the TM's outside ports: ray writes (duplicates
    /// and end markers), hit updates and global memory requests.
    fn grant_outputs(&mut self, ctx: &mut Ctx, start: usize, o: &mut Outcome) {
        let g = &mut self.stats.grants;
        forward(
            ctx,
            &self.tp_ray_write,
            &self.ray_write,
            start,
            3,
            &mut g[3],
            o,
        );
        forward(ctx, &self.tp_hit, &self.hit, start, 4, &mut g[4], o);
        forward(
            ctx,
            &self.tp_gmem_req,
            &self.gmem_req,
            start,
            5,
            &mut g[5],
            o,
        );
    }

    /// One step of the ray-box pipeline on its two FIFOs (their registered room
    /// and visibility make the order of this, the box grant and the routing
    /// irrelevant); returns the pipeline's own next step.
    fn step_box_pipe(&mut self, c: u64) -> Next {
        // (An empty pipeline with empty FIFOs has nothing to step: most
        // evaluations.)
        let box_busy = !self.box_req_q.is_empty() || self.box_pipe.occupancy() > 0;
        if box_busy {
            self.box_pipe
                .step_on(
                    c,
                    &mut LocalEnds {
                        now: c,
                        input: &mut self.box_req_q,
                        output: &mut self.box_resp_q,
                    },
                    box_test,
                )
                .1
        } else {
            Next::Idle
        }
    }

    /// This cycle's box grant into the ray-box pipeline's request FIFO.
    fn grant_box(&mut self, ctx: &mut Ctx, c: u64, start: usize, o: &mut Outcome) {
        let free = self.box_req_q.can_push();
        if let Some((_, v)) = pick(
            ctx,
            &self.tp_box_req,
            start,
            free,
            &mut o.cf[1],
            &mut o.more,
        ) {
            self.box_req_q.push(c, v);
            self.stats.grants[1] += 1;
            o.worked = true;
        }
        o.waiting |= o.cf[1] > 0;
    }

    /// This cycle's triangle grant, to the pipeline with room and the fewest
    /// tests in flight.
    fn grant_tri(&mut self, ctx: &mut Ctx, start: usize, tri: &mut TriCounts, o: &mut Outcome) {
        let target = (0..self.tri_req.len())
            .filter(|&p| ctx.can_push(&self.tri_req.at(p)))
            .min_by_key(|&p| (tri.outstanding[p], p));
        let free = target.is_some();
        if let Some((_, v)) = pick(
            ctx,
            &self.tp_tri_req,
            start,
            free,
            &mut o.cf[2],
            &mut o.more,
        ) {
            let p = target.expect("granted only with a target");
            ctx.push(&self.tri_req.at(p), v);
            tri.outstanding[p] += 1;
            tri.changed[p] = true;
            self.stats.grants[2] += 1;
            o.worked = true;
        }
        o.waiting |= o.cf[2] > 0;
    }

    /// Writes the changed counts of tests in flight back to their registers.
    fn store_tri_counts(&mut self, tri: &TriCounts) {
        for p in 0..self.tri_pipes as usize {
            if tri.changed[p] {
                self.tri_outstanding.write(p as u32, tri.outstanding[p]);
            }
        }
    }

    /// When the pipeline and its FIFOs need the crossbar again without any link
    /// waking it: the pipeline's own next step, the next request or result
    /// becoming visible (one behind a result routed now, too; a visible result
    /// that stays is blocked by its TP's full link, whose pop wakes us), and
    /// room freed in a full FIFO (seen from the next cycle).
    fn box_wake(&self, c: u64, pipe_next: Next, box_routed: bool) -> Next {
        let mut wake = match pipe_next {
            Next::Cycle => Some(c + 1),
            Next::AtCycle(t) => Some(t),
            Next::Idle => None,
        };
        let mut at = |t: u64| wake = Some(wake.map_or(t, |w: u64| w.min(t)));
        if let Some(t) = self.box_req_q.next_visible()
            && t > c
        {
            at(t);
        }
        if let Some(t) = self.box_resp_q.next_visible()
            && (box_routed || t > c)
        {
            at(t.max(c + 1));
        }
        if self.box_req_q.freed_full() || self.box_resp_q.freed_full() {
            at(c + 1);
        }
        match wake {
            Some(t) => Next::AtCycle(t.max(c + 1)),
            None => Next::Idle,
        }
    }

    /// The evaluation's status and conflict counts, and when the crossbar must
    /// be evaluated next (`idle`: when the ray-box pipeline needs it).
    fn settle(&mut self, ctx: &mut Ctx, c: u64, o: &Outcome, idle: Next) -> Next {
        let (worked, waiting, cf) = (o.worked, o.waiting, o.cf);
        ctx.set_status(if worked {
            Status::Busy
        } else if waiting {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        });
        let s = &mut self.stats;
        if !worked && waiting {
            // Only waiting: sleep until a push or a pop wakes us (see `XbarStats::wait`).
            // The same picture again (an evaluation that was not needed) changes nothing.
            match s.wait {
                Some((_, w)) if w == cf => {}
                _ => {
                    flush_wait(s, c);
                    s.wait = Some((c, cf));
                }
            }
            return idle;
        }
        flush_wait(s, c);
        for (k, n) in cf.iter().enumerate() {
            s.conflicts[k] += n;
        }
        if worked && !waiting && !o.more {
            // Every visible head went this cycle and none is left behind one: until
            // a push wakes it the crossbar would only find nothing, so it sleeps,
            // waiting for input from the next cycle on.
            ctx.set_status_from_next(Status::WaitInput);
            return idle;
        }
        if worked { Next::Cycle } else { idle }
    }
}

/// Whether any of `outs` had room at the start of the cycle.
fn any_ready<T>(at: &Ready, outs: &PortArray<Out<T>>) -> bool {
    outs.iter().any(|o| at.out_ready(o))
}

impl Logic for TmXbar {
    /// A TP's request class is ready while what it is granted onto has room
    /// (the grant goes to one of them, round-robin); a response input while
    /// a TP link it may be routed to has room (which one, its tag says).
    fn can_accept(&self, port: LinkId, at: &Ready) -> bool {
        if port == self.div_resp.id {
            any_ready(at, &self.tp_div_resp)
        } else if port == self.gmem_resp.id {
            any_ready(at, &self.tp_gmem_resp)
        } else if self.tri_resp.index_of(port).is_some() {
            any_ready(at, &self.tp_tri_resp)
        } else if self.tp_div_req.index_of(port).is_some() {
            at.out_ready(&self.div_req)
        } else if self.tp_box_req.index_of(port).is_some() {
            self.box_req_q.can_push()
        } else if self.tp_tri_req.index_of(port).is_some() {
            any_ready(at, &self.tri_req)
        } else if self.tp_ray_write.index_of(port).is_some() {
            at.out_ready(&self.ray_write)
        } else if self.tp_hit.index_of(port).is_some() {
            at.out_ready(&self.hit)
        } else if self.tp_gmem_req.index_of(port).is_some() {
            at.out_ready(&self.gmem_req)
        } else {
            false
        }
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let start = ctx.round_robin_start(self.tps as usize);
        let mut o = Outcome::default();
        let box_routed = self.route_responses(ctx, c, &mut o);
        let mut tri = self.load_tri_counts();
        self.route_tri_responses(ctx, &mut tri, &mut o);
        // Requests onto the shared units and outputs.
        self.grant_div(ctx, start, &mut o);
        // The ray-box pipeline: one step on its two FIFOs, then this cycle's box
        // grant into its request FIFO.
        let pipe_next = self.step_box_pipe(c);
        self.grant_box(ctx, c, start, &mut o);
        self.grant_outputs(ctx, start, &mut o);
        self.grant_tri(ctx, start, &mut tri, &mut o);
        self.store_tri_counts(&tri);
        let idle = self.box_wake(c, pipe_next, box_routed);
        self.settle(ctx, c, &o, idle)
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.stats;
        let names_g = [
            "div_grants",
            "box_grants",
            "tri_grants",
            "ray_write_grants",
            "hit_grants",
            "gmem_grants",
        ];
        let names_c = [
            "div_conflicts",
            "box_conflicts",
            "tri_conflicts",
            "ray_write_conflicts",
            "hit_conflicts",
            "gmem_conflicts",
        ];
        let mut v: Vec<(&'static str, u64)> = names_g.iter().copied().zip(s.grants).collect();
        v.extend(names_c.iter().copied().zip(s.conflicts));
        v.push(("box_tests", self.box_pipe.accepted()));
        v.push(("box_results", self.box_pipe.emitted()));
        v.push(("box_occupied_cycles", self.box_pipe.occupied_cycles()));
        v
    }

    fn reset_counters(&mut self) {
        self.stats = XbarStats::default();
    }
}
