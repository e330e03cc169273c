//! The TM crossbar: connects the TPs to the TM-shared divider, ray-box pipeline and
//! ray-triangle pipelines, and merges their duplicates and hit updates into the TM's
//! two outside ports.
//!
//! Arbitration: per shared resource, one request per cycle, round-robin from the TP
//! `cycle mod tps` on, a function of absolute time, so it does not depend on when
//! the crossbar was evaluated (sleeping stays exact). A triangle request goes to the
//! pipeline with room in its input link and the fewest tests in flight (ties: the
//! lowest index). Responses return by tag (TP index in the low byte; global memory:
//! the `id`, which a TP sets to its index). The crossbar is
//! one register stage each way: it adds the link delay to every round trip.

use super::box_pipe::{BoxReq, BoxResp};
use super::divider::{DivReq, DivResp};
use super::memory::{MemLineReq, MemLineResp};
use super::tp::{HitUpdate, RayWrite};
use super::tri_pipe::{TriReq, TriResp};
use crate::rtl::{Ctx, In, Logic, Next, Out, Payload, PortArray, Ram, Status};

crate::unit! {
    /// TM crossbar: round-robin arbitration of the TPs onto the shared units and outputs.
    pub struct TmXbar : "tm_xbar" {
        params { tps: u32 => "TPS", tri_pipes: u32 => "TRI_PIPES" }
        inputs { div_resp: DivResp, box_resp: BoxResp, gmem_resp: MemLineResp }
        outputs {
            div_req: DivReq,
            box_req: BoxReq,
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
        state { tri_outstanding: Ram<u16> }
        extra { stats: XbarStats }
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

/// Adds the conflicts of a wait in progress for its cycles before `c`.
fn flush_wait(s: &mut XbarStats, c: u64) {
    if let Some((since, w)) = s.wait.take() {
        for (k, n) in w.iter().enumerate() {
            s.conflicts[k] += n * (c - since);
        }
    }
}

impl Logic for TmXbar {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let start = ctx.round_robin_start(self.tps as usize);
        let mut worked = false;
        let mut waiting = false;
        // An input popped this cycle holds another entry.
        let mut more = false;
        // This cycle's conflicts, per class (added to the stats at the end).
        let mut cf = [0u64; 6];
        // Responses back to their TPs.
        for (w, b) in [
            route(ctx, &self.div_resp, &self.tp_div_resp, |r| r.tag, &mut more),
            route(ctx, &self.box_resp, &self.tp_box_resp, |r| r.tag, &mut more),
            route(
                ctx,
                &self.gmem_resp,
                &self.tp_gmem_resp,
                |r| r.id as u16,
                &mut more,
            ),
        ] {
            worked |= w;
            waiting |= b;
        }
        // Per-pipe scratch on the stack (the config allows at most 8 pipes): this
        // runs every busy cycle, so no allocation here.
        let np = self.tri_pipes as usize;
        let mut outstanding = [0u16; 8];
        for (p, o) in outstanding.iter_mut().enumerate().take(np) {
            *o = *self.tri_outstanding.read(p as u32);
        }
        let mut changed = [false; 8];
        for p in 0..self.tri_resp.len() {
            let tri = self.tri_resp.at(p);
            let (w, b) = route(ctx, &tri, &self.tp_tri_resp, |r| r.tag, &mut more);
            if w {
                outstanding[p] -= 1;
                changed[p] = true;
            }
            worked |= w;
            waiting |= b;
        }
        // Requests onto the shared units and outputs.
        macro_rules! forward {
            ($class:expr, $inputs:expr, $out:expr) => {{
                let free = ctx.can_push(&$out);
                if let Some((_, v)) = pick(ctx, &$inputs, start, free, &mut cf[$class], &mut more) {
                    ctx.push(&$out, v);
                    self.stats.grants[$class] += 1;
                    worked = true;
                }
                waiting |= cf[$class] > 0;
            }};
        }
        forward!(0, self.tp_div_req, self.div_req);
        forward!(1, self.tp_box_req, self.box_req);
        forward!(3, self.tp_ray_write, self.ray_write);
        forward!(4, self.tp_hit, self.hit);
        forward!(5, self.tp_gmem_req, self.gmem_req);
        let target = (0..self.tri_req.len())
            .filter(|&p| ctx.can_push(&self.tri_req.at(p)))
            .min_by_key(|&p| (outstanding[p], p));
        let free = target.is_some();
        if let Some((_, v)) = pick(ctx, &self.tp_tri_req, start, free, &mut cf[2], &mut more) {
            let p = target.expect("granted only with a target");
            ctx.push(&self.tri_req.at(p), v);
            outstanding[p] += 1;
            changed[p] = true;
            self.stats.grants[2] += 1;
            worked = true;
        }
        waiting |= cf[2] > 0;
        for p in 0..np {
            if changed[p] {
                self.tri_outstanding.write(p as u32, outstanding[p]);
            }
        }
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
            return Next::Idle;
        }
        flush_wait(s, c);
        for (k, n) in cf.iter().enumerate() {
            s.conflicts[k] += n;
        }
        if worked && !waiting && !more {
            // Every visible head went this cycle and none is left behind one: until
            // a push wakes it the crossbar would only find nothing, so it sleeps,
            // waiting for input from the next cycle on.
            ctx.set_status_from_next(Status::WaitInput);
            return Next::Idle;
        }
        if worked { Next::Cycle } else { Next::Idle }
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
        v
    }

    fn reset_counters(&mut self) {
        self.stats = XbarStats::default();
    }
}
