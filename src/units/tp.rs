//! A thread processor (TP, paper §4): the FSM of the segment traversal kernel.
//!
//! It takes a ray from the staging buffer, gets its inverse direction from the
//! TM's divider, and traverses the current segment exactly as
//! `render::traverse::traverse_segment` does (the scoreboard demands equality): pop
//! an entry; cull it beyond `cull(best)`; an exit sends the duplicate on `ray_write`;
//! an inner node is loaded through the L1 and both children are box-tested with
//! limit `cull(best)`, the far one pushed first; a leaf's triangles are loaded and
//! tested one by one with `t_max = best`; a shadow ray stops at its first hit. At
//! the end a hit is sent on `hit`. All geometry comes from the L1 line bytes.
//!
//! Timing: every computing state has a cost from `tm.costs` (cycles and the
//! instructions they stand for); its action happens in its last cycle, and the next
//! state begins in the following cycle. Waiting states end in the cycle the
//! response is visible, so a ray's time is the sum of state costs and round trips.

mod traverse;

use glam::Vec3;

use super::box_pipe::{BoxReq, BoxResp};
use super::divider::{DivReq, DivResp};
use super::follow::{FollowKind, Follower};
use super::l1::{L1Req, L1Resp, Line};
use super::memory::{MemLineReq, MemLineResp};
use super::staging_buffer::{SbHeader, SbRay};
use super::tm::{COST_NAMES, COSTS, TpCosts, round_trip};
pub use super::tp_shade::{SHADE_SEG, ShadeRegs};
use super::tri_pipe::{TriReq, TriResp};
use crate::contract::{HitRec, RayRec};
use crate::rtl::{Ctx, Declared, LinkId, Logic, Next, Ram, Ready, Reg, Status};

crate::payload_struct! {
    /// A duplicate: the ray, with its entry into the child segment `seg`; or, with
    /// `done`, the end marker of a ray in segment `seg` (sent after all its
    /// duplicates on the same path, so the stream scheduler knows when a segment's
    /// rays are finished).
    pub struct RayWrite {
        pub seg: u32,
        pub ray: RayRec,
        pub done: bool,
    }
}

crate::payload_struct! {
    /// A segment's best hit for the ray whose hit record is `index` (pixel*2+shadow).
    pub struct HitUpdate {
        pub index: u32,
        pub hit: HitRec,
    }
}

crate::payload_struct! {
    /// A traversal stack entry in the scratchpad: reference, segment word
    /// (`SEG_SAME` or an exit's child segment), entry distance.
    pub struct StackEntry {
        pub r: u32,
        pub seg: u32,
        pub t: f32,
    }
}

crate::fsm_states! {
    /// TP states. Computing states (cost from the config): Fetch, Init, Pop, Exit,
    /// NodeFetch, BoxIssue, NodePush, TriFetch, TriIssue, TriResult, Finish; the
    /// second box issue takes one cycle; the rest wait for a link.
    pub enum TpState {
        Idle, Fetch, DivWait, Init, Pop, Exit, NodeFetch, NodeWait, BoxIssue, BoxIssue1,
        BoxWait, NodePush, TriFetch, TriMemWait, TriIssue, TriTestWait, TriResult,
        Finish, Overflow,
        ShPath, ShLoad, ShWait, Shade, ShEmit, ShStore, ShStore1, ShDone,
    }
}

impl Default for SbRay {
    fn default() -> Self {
        SbRay {
            ray: RayRec {
                origin: Vec3::ZERO,
                dir: Vec3::ZERO,
                ray_id: 0,
                entry: 0,
            },
            hdr: SbHeader::default(),
        }
    }
}

/// An empty stack entry (the scratchpad's reset contents).
const NO_ENTRY: StackEntry = StackEntry {
    r: 0,
    seg: 0,
    t: 0.0,
};

crate::unit! {
    /// Thread processor: the segment traversal kernel as an FSM with per-state costs.
    pub struct Tp : "tp" {
        new(cfg: &super::tm::TmSpec, index: u16; ports: TpPorts) {
            let entries = cfg.tm.stack_entries();
        }
        params {
            index: u16 = index => "INDEX",
            stack_entries: u32 = entries => "STACK_ENTRIES"
        }
        inputs {
            ray: SbRay,
            div_resp: DivResp,
            box_resp: BoxResp,
            tri_resp: TriResp,
            mem_resp: L1Resp,
            gmem_resp: MemLineResp
        }
        outputs {
            div_req: DivReq,
            box_req: BoxReq,
            tri_req: TriReq,
            mem_req: L1Req,
            ray_write: RayWrite,
            hit: HitUpdate,
            gmem_req: MemLineReq
        }
        state {
            state: Reg<TpState> = TpState::Idle,
            ray_index: Reg<u32> = 0,
            node_addr: Reg<u64> = 0,
            stack_depth: Reg<u16> = 0,
            act_at: Reg<u64> = 0,
            req_at: Reg<u64> = 0,
            cur: Reg<SbRay> = SbRay::default(),
            inv_dir: Reg<Vec3> = Vec3::ZERO,
            best: Reg<HitRec> = HitRec::NONE,
            entry: Reg<StackEntry> = NO_ENTRY,
            line0: Reg<Line> = Line::default(),
            line1: Reg<Line> = Line::default(),
            box0: Reg<Option<f32>> = None,
            box1: Reg<Option<f32>> = None,
            box_got: Reg<bool> = false,
            tri_k: Reg<u32> = 0,
            tri_end: Reg<u32> = 0,
            tri_hit: Reg<Option<HitRec>> = None,
            done_sent: Reg<bool> = false,
            sh_step: Reg<u32> = 0,
            sh_addr: Reg<u64> = 0,
            sh_tri_addr: Reg<u64> = 0,
            sh_tri0: Reg<Line> = Line::default(),
            sh_tri1: Reg<Line> = Line::default(),
            sh_albedo: Reg<Vec3> = Vec3::ZERO,
            sh_shadow: Reg<Option<RayRec>> = None,
            sh_bounce: Reg<Option<RayRec>> = None,
            sh_emitted: Reg<u32> = 0,
            sh_acks: Reg<u32> = 0,
            // Two write ports: a node pushes both children in one action.
            stack: Ram<StackEntry> = Ram::new(entries, 2, NO_ENTRY).sized_by("STACK_ENTRIES")
        }
        extra {
            costs: TpCosts = cfg.tm.costs.clone(),
            rt: [u64; 3] = [
                round_trip(&cfg.divider, &cfg.link),
                round_trip(&cfg.box_pipe, &cfg.link),
                round_trip(&cfg.tri_pipe, &cfg.link),
            ],
            stats: TpStats = TpStats::default(),
            log: Option<Vec<u64>> = None,
            shading: Option<ShadeRegs> = None,
            blocked_since: Option<u64> = None,
            // `--follow-ray`: a probe, not hardware (`units/follow.rs`): the
            // unit's probe, whether the ray it holds is followed, and the
            // followed ray (wavefront, id) whose pixel it shades.
            follow: Option<Follower> = None,
            followed: bool = false,
            followed_shade: Option<(u32, u32)> = None,
            // `costs.all()` builds its table on every call; the TP needs the
            // cycles on every state change.
            cost_cycles: [u32; COSTS] = cfg.tm.costs.all().map(|(_, k)| k.cycles)
        }
    }
}

/// Index of a computing state's cost in `TpCosts::all` (and `TpStats::uses`).
fn cost_index(s: TpState) -> Option<usize> {
    use TpState::*;
    Some(match s {
        Fetch => 0,
        Init => 1,
        Pop => 2,
        Exit => 3,
        NodeFetch => 4,
        BoxIssue => 5,
        NodePush => 6,
        TriFetch => 7,
        TriIssue => 8,
        TriResult => 9,
        Finish => 10,
        ShPath | ShLoad => 11,
        Shade => 12,
        ShEmit | ShDone => 13,
        ShStore => 14,
        _ => return None,
    })
}

/// Event counters of one TP.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TpStats {
    /// Actions of each computing state, in `TpCosts::all` order.
    pub uses: [u64; COSTS],
    pub rays: u64,
    pub box_tests: u64,
    pub tri_tests: u64,
    pub exits: u64,
    pub hits: u64,
    /// Triangle tests that hit.
    pub tri_hits: u64,
    pub l1_loads: u64,
    /// Cycles from a request to its response, per unit.
    pub wait: TpWaits,
    /// The part of `wait` beyond the idle round trip (contention).
    pub stall: TpStalls,
    /// Cycles a finished action waited for a full output link (a wait in progress
    /// is added when it ends).
    pub blocked: u64,
    pub max_stack: u64,
    pub first_ray: Option<u64>,
    /// Cycle of the last `Finish` action.
    pub last_finish: u64,
    /// Shading: work items (pixels), bounce hits shaded, shadow rays blocked,
    /// rays emitted, global-memory reads and writes.
    pub shade_items: u64,
    pub shade_hits: u64,
    pub shade_occluded: u64,
    pub shade_rays: u64,
    pub shade_shadow_rays: u64,
    pub gmem_reads: u64,
    pub gmem_writes: u64,
    /// Cycles waiting for global memory (the L2).
    pub gmem_wait: u64,
}

/// A TP's cycles from a request to its response, per unit it waits for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TpWaits {
    pub divider: u64,
    pub box_pipe: u64,
    pub tri_pipe: u64,
    pub l1: u64,
}

/// The part of a TP's waits beyond the idle round trip (contention), per
/// pipelined unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TpStalls {
    pub divider: u64,
    pub box_pipe: u64,
    pub tri_pipe: u64,
}

impl TpStats {
    /// Adds another TP's additive counters (all but `max_stack`, `first_ray` and
    /// `last_finish`) to these.
    pub fn add(&mut self, o: &TpStats) {
        for (a, b) in self.uses.iter_mut().zip(o.uses) {
            *a += b;
        }
        self.wait.divider += o.wait.divider;
        self.wait.box_pipe += o.wait.box_pipe;
        self.wait.tri_pipe += o.wait.tri_pipe;
        self.wait.l1 += o.wait.l1;
        self.stall.divider += o.stall.divider;
        self.stall.box_pipe += o.stall.box_pipe;
        self.stall.tri_pipe += o.stall.tri_pipe;
        self.rays += o.rays;
        self.box_tests += o.box_tests;
        self.tri_tests += o.tri_tests;
        self.exits += o.exits;
        self.hits += o.hits;
        self.tri_hits += o.tri_hits;
        self.l1_loads += o.l1_loads;
        self.blocked += o.blocked;
        self.shade_items += o.shade_items;
        self.shade_hits += o.shade_hits;
        self.shade_occluded += o.shade_occluded;
        self.shade_rays += o.shade_rays;
        self.shade_shadow_rays += o.shade_shadow_rays;
        self.gmem_reads += o.gmem_reads;
        self.gmem_writes += o.gmem_writes;
        self.gmem_wait += o.gmem_wait;
    }

    /// Actions of the computing state named `name` (see `tm::COST_NAMES`).
    pub fn uses_of(&self, name: &str) -> u64 {
        let k = super::tm::TpCosts::index_of(name).expect("a computing state's name");
        self.uses[k]
    }
}

impl Tp {
    /// Logs the followed rays' events here (`units/follow.rs`).
    pub fn follow(&mut self, f: Follower) {
        self.follow = Some(f);
    }

    /// Logs `kind` (made from the TP's registers) if the ray held is followed.
    #[inline]
    pub(super) fn note(&mut self, c: u64, kind: impl FnOnce(&Self) -> FollowKind) {
        if self.followed {
            let (id, k) = (self.cur.get().ray.ray_id, kind(self));
            if let Some(f) = &mut self.follow {
                f.log(c, id, k);
            }
        }
    }

    /// Logs `kind` if the pixel being shaded is a followed ray's.
    #[inline]
    pub(super) fn note_shade(&mut self, c: u64, kind: impl FnOnce(&Self) -> FollowKind) {
        if let Some((w, id)) = self.followed_shade {
            let k = kind(self);
            if let Some(f) = &mut self.follow {
                f.log_wave(c, w, id, k);
            }
        }
    }

    /// Records the address of every L1 load (tests compare the visit order).
    pub fn enable_log(&mut self) {
        self.log = Some(Vec::new());
    }

    pub fn request_log(&self) -> &[u64] {
        self.log.as_deref().unwrap_or(&[])
    }

    /// Cycles of a computing state (`None` for the others).
    fn cost_cycles(&self, s: TpState) -> Option<u32> {
        cost_index(s).map(|k| self.cost_cycles[k])
    }

    /// Enters `s` in the cycle after `c`; a computing state acts in its last cycle.
    pub(super) fn go(&mut self, s: TpState, c: u64) -> Next {
        self.state.set(s);
        match self.cost_cycles(s) {
            Some(k) => {
                let at = c + k as u64;
                self.act_at.set(at);
                Next::AtCycle(at)
            }
            // A waiting state looks at its link from the next cycle on; one that
            // awaits the response to the request just sent sleeps instead
            // (`awaits_response`, in `eval`).
            None => Next::Cycle,
        }
    }

    fn used(&mut self, s: TpState) {
        if let Some(k) = cost_index(s) {
            self.stats.uses[k] += 1;
        }
    }

    /// A computing state's action in cycle `c`; `None` if an output was full.
    fn act(&mut self, ctx: &mut Ctx, s: TpState, c: u64) -> Option<Next> {
        match s {
            TpState::Fetch => self.fetch(ctx, c),
            TpState::Init => Some(self.init(c)),
            TpState::Pop => Some(self.pop(c)),
            TpState::Exit => self.exit(ctx, c),
            TpState::NodeFetch => self.node_fetch(ctx, c),
            TpState::BoxIssue | TpState::BoxIssue1 => self.box_issue(ctx, s, c),
            TpState::NodePush => Some(self.node_push(c)),
            TpState::TriFetch => self.tri_fetch(ctx, c),
            TpState::TriIssue => self.tri_issue(ctx, c),
            TpState::TriResult => Some(self.tri_result(c)),
            TpState::Finish => self.finish(ctx, c),
            TpState::ShPath
            | TpState::ShLoad
            | TpState::Shade
            | TpState::ShEmit
            | TpState::ShStore
            | TpState::ShStore1
            | TpState::ShDone => self.shade_act(ctx, s, c),
            _ => unreachable!("not a computing state"),
        }
    }
}

/// A state that waits for the response to a request the TP sent as it entered
/// it (a response is at least a link's delay each way away).
fn awaits_response(s: TpState) -> bool {
    matches!(
        s,
        TpState::DivWait
            | TpState::NodeWait
            | TpState::BoxWait
            | TpState::TriMemWait
            | TpState::TriTestWait
            | TpState::ShWait
    )
}

/// A computing state whose action touches no link: what it does is seen outside
/// the TP only through the states after it.
fn internal(s: TpState) -> bool {
    matches!(
        s,
        TpState::Init | TpState::Pop | TpState::NodePush | TpState::TriResult | TpState::Shade
    )
}

impl Logic for Tp {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let mut n = self.step(ctx);
        if ctx.watched() {
            return n;
        }
        // Run through the internal states just entered (a pop after a node's
        // push, say) now rather than in evaluations of their own, and sleep until
        // the first state that offers on a link acts. Nothing else reads or
        // writes the TP's registers, so taking its edges early changes nothing
        // outside it: the links see the same operations at the same cycles, and
        // the status stays busy throughout. A traced TP goes state by state, so
        // the waveform shows every one. Only after an action of this evaluation
        // (`state` written): a TP that is evaluated early must change nothing.
        while let Next::AtCycle(at) = n {
            let s = *self.state.next();
            if !self.state.written() || !internal(s) {
                break;
            }
            Declared::commit_state(self);
            n = self
                .act(ctx, s, at)
                .expect("an internal state never offers on a link");
            self.used(s);
        }
        n
    }

    /// By FSM state: each input in the state that waits for it (the ray in
    /// Idle, a response in its wait state).
    fn can_accept(&self, port: LinkId, _at: &Ready) -> bool {
        use TpState::*;
        let s = self.state.val();
        if port == self.ray.id {
            s == Idle
        } else if port == self.div_resp.id {
            s == DivWait
        } else if port == self.box_resp.id {
            s == BoxWait
        } else if port == self.tri_resp.id {
            s == TriTestWait
        } else if port == self.mem_resp.id {
            matches!(s, NodeWait | TriMemWait)
        } else if port == self.gmem_resp.id {
            s == ShWait
        } else {
            false
        }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.stats;
        let mut v = vec![
            ("rays", s.rays),
            ("box_tests", s.box_tests),
            ("tri_tests", s.tri_tests),
            ("exits", s.exits),
            ("hits", s.hits),
            ("tri_hits", s.tri_hits),
            ("l1_loads", s.l1_loads),
            ("wait_div", s.wait.divider),
            ("wait_box", s.wait.box_pipe),
            ("wait_tri", s.wait.tri_pipe),
            ("wait_l1", s.wait.l1),
            ("stall_div", s.stall.divider),
            ("stall_box", s.stall.box_pipe),
            ("stall_tri", s.stall.tri_pipe),
            ("blocked", s.blocked),
            ("max_stack", s.max_stack),
            ("shade_items", s.shade_items),
            ("shade_hits", s.shade_hits),
            ("shade_occluded", s.shade_occluded),
            ("shade_rays", s.shade_rays),
            ("shade_shadow_rays", s.shade_shadow_rays),
            ("gmem_reads", s.gmem_reads),
            ("gmem_writes", s.gmem_writes),
            ("gmem_wait", s.gmem_wait),
        ];
        v.extend(COST_NAMES.into_iter().zip(s.uses));
        v
    }

    fn reset_counters(&mut self) {
        self.stats = TpStats::default();
        self.blocked_since = None;
        if let Some(l) = &mut self.log {
            l.clear();
        }
    }
}

impl Tp {
    /// One cycle of the TP, state by state.
    fn step(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let s = self.state.val();
        let costed =
            self.cost_cycles(s).is_some() || s == TpState::BoxIssue1 || s == TpState::ShStore1;
        if costed {
            return self.act_when_due(ctx, s, c);
        }
        match s {
            TpState::Idle => self.idle(ctx, c),
            TpState::DivWait => self.div_wait(ctx, c),
            TpState::NodeWait => self.node_wait(ctx, c),
            TpState::BoxWait => self.box_wait(ctx, c),
            TpState::TriMemWait => self.tri_mem_wait(ctx, c),
            TpState::TriTestWait => self.tri_test_wait(ctx, c),
            TpState::ShWait => self.sh_wait(ctx, c),
            _ => {
                // Overflow: stopped for good, reported by the testbench.
                ctx.set_status(Status::ResourceBusy);
                Next::Idle
            }
        }
    }

    /// A computing state: busy until its last cycle, then its action (a refused
    /// offer sleeps until the link has room).
    fn act_when_due(&mut self, ctx: &mut Ctx, s: TpState, c: u64) -> Next {
        if c < self.act_at.val() {
            ctx.set_status(Status::Busy);
            return Next::AtCycle(self.act_at.val());
        }
        match self.act(ctx, s, c) {
            Some(n) => {
                if let Some(b) = self.blocked_since.take() {
                    self.stats.blocked += c - b;
                }
                self.used(s);
                ctx.set_status(Status::Busy);
                if n == Next::Cycle && awaits_response(*self.state.next()) {
                    // The request just sent cannot be answered by the next
                    // cycle: wait from then on, asleep until the response's
                    // push wakes the TP.
                    ctx.set_status_from_next(Status::ResourceBusy);
                    return Next::Idle;
                }
                n
            }
            None => {
                // Offered and refused: the link holds the offer, and the pop that
                // makes room wakes the TP (a pop from a full link wakes its
                // producer), which then offers the same again. Until then nothing
                // can change, so the TP sleeps; its blocked cycles are counted
                // when the offer is taken (`blocked_since`, the first refusal).
                self.blocked_since.get_or_insert(c);
                ctx.set_status(Status::OutputBlocked);
                Next::Idle
            }
        }
    }

    /// Idle: takes the next ray, or a shading work item, from the staging buffer.
    fn idle(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.ray) {
            Some(r) if r.hdr.seg == SHADE_SEG => {
                // A shading work item: the pixel in `ray_id`.
                let pixel = r.ray.ray_id;
                self.followed_shade = self.follow.as_ref().and_then(|f| f.wants_shade(pixel));
                self.note_shade(c, |_| FollowKind::ShadeTaken { pixel });
                self.ray_index.set(r.ray.ray_id);
                self.cur.set(r);
                self.stats.shade_items += 1;
                ctx.set_status(Status::Busy);
                self.go(TpState::ShPath, c)
            }
            Some(r) => {
                self.ray_index.set(r.ray.ray_id);
                if let Some(f) = &mut self.follow {
                    self.followed = f.wants(r.ray.ray_id);
                    if self.followed {
                        let kind = FollowKind::Taken {
                            seg: r.hdr.seg,
                            origin: r.ray.origin,
                            dir: r.ray.dir,
                            entry: r.ray.entry,
                        };
                        f.log(c, r.ray.ray_id, kind);
                    }
                }
                self.cur.set(r);
                self.stats.rays += 1;
                self.stats.first_ray.get_or_insert(c);
                ctx.set_status(Status::Busy);
                self.go(TpState::Fetch, c)
            }
            None => wait(ctx, Status::WaitInput),
        }
    }

    /// ShWait: a global-memory answer for the shading kernel.
    fn sh_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.gmem_resp) {
            Some(r) => {
                self.stats.gmem_wait += c - self.req_at.val();
                ctx.set_status(Status::Busy);
                self.shade_response(ctx, r, c)
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }
}

/// A waiting state with nothing on its link yet: status `st`, asleep.
fn wait(ctx: &mut Ctx, st: Status) -> Next {
    ctx.set_status(st);
    Next::Idle // a push onto the awaited link wakes the TP
}

impl Tp {
    /// Whether the TP stopped on a stack overflow.
    pub fn overflowed(&self) -> bool {
        self.state.val() == TpState::Overflow
    }
}

impl Tp {
    /// The TP's event counters (a probe, not hardware; by reference: the chip
    /// adds up every TP's at each snapshot).
    pub fn probe(&self) -> &TpStats {
        &self.stats
    }
    /// Whether the TP holds work (a ray or a shading item): not idle.
    pub fn holds_work(&self) -> bool {
        self.state.val() != TpState::Idle
    }
}
