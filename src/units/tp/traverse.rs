//! The TP's traversal states (the segment traversal kernel, paper §4): the
//! computing states' actions (`Tp::act` calls them in a state's last cycle;
//! `None`: an output link was full, retry) and the waits for the divider, the
//! L1, the box and the triangle pipes (`Tp::step`).

use glam::Vec3;

use super::super::Tag;
use super::super::box_pipe::BoxReq;
use super::super::divider::DivReq;
use super::super::follow::FollowKind;
use super::super::l1::{L1Req, Line};
use super::super::staging_buffer::SbHeader;
use super::super::tri_pipe::TriReq;
use super::{HitUpdate, RayWrite, StackEntry, Tp, TpState, wait};
use crate::contract::{HitRec, NODE_BYTES, RayRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES, TRI_BYTES};
use crate::geom::cull;
use crate::rtl::{Ctx, Next, Status};

fn vec3_at(l: &Line, off: usize) -> Vec3 {
    Vec3::new(l.f32_at(off), l.f32_at(off + 4), l.f32_at(off + 8))
}

impl Tp {
    fn t_ray(&self) -> f32 {
        self.cur.get().ray.t_max()
    }

    fn hdr(&self) -> &SbHeader {
        &self.cur.get().hdr
    }

    fn tri_addr(&self, k: u32) -> u64 {
        let h = self.hdr();
        h.base
            + SEGMENT_HEADER_BYTES as u64
            + h.nodes as u64 * NODE_BYTES as u64
            + k as u64 * TRI_BYTES as u64
    }

    fn load(&mut self, ctx: &mut Ctx, addr: u64) -> bool {
        let line = addr & !63;
        if ctx.offer(&self.mem_req, L1Req { addr: line }) {
            self.stats.l1_loads += 1;
            if let Some(l) = &mut self.log {
                l.push(line);
            }
            true
        } else {
            false
        }
    }

    /// Fetch: asks the TM's divider for the ray's inverse direction.
    pub(super) fn fetch(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        let tag = self.index as Tag;
        let ray = self.cur.get().ray;
        if !ctx.offer(&self.div_req, DivReq { dir: ray.dir, tag }) {
            return None;
        }
        self.req_at.set(c);
        Some(self.go(TpState::DivWait, c))
    }

    /// Init: the stack holds the ray's entry into the segment; no hit yet.
    pub(super) fn init(&mut self, c: u64) -> Next {
        let ray = self.cur.get().ray;
        self.best.set(HitRec::NONE);
        self.stack.write(
            0,
            StackEntry {
                r: ray.entry,
                seg: SEG_SAME,
                t: 0.0,
            },
        );
        self.stack_depth.set(1);
        self.stats.max_stack = self.stats.max_stack.max(1);
        self.go(TpState::Pop, c)
    }

    /// Pop: the top stack entry; culled beyond the best hit, else an exit, a
    /// leaf's triangles or an inner node.
    pub(super) fn pop(&mut self, c: u64) -> Next {
        let depth = self.stack_depth.val();
        if depth == 0 {
            return self.go(TpState::Finish, c);
        }
        let e = self.stack.read(depth as u32 - 1).clone();
        self.stack_depth.set(depth - 1);
        self.entry.set(e.clone());
        let limit = self.best.get().t.min(self.t_ray());
        if e.t > cull(limit) {
            let (seg, t) = (self.hdr().seg, e.t);
            self.note(c, |_| FollowKind::Cull { seg, t });
            self.go(TpState::Pop, c)
        } else if e.seg != SEG_SAME {
            self.go(TpState::Exit, c)
        } else {
            match Ref::decode(e.r) {
                Ref::Leaf { first, count } => {
                    let seg = self.hdr().seg;
                    self.note(c, |_| FollowKind::Leaf { seg, first, count });
                    self.tri_k.set(first);
                    self.tri_end.set(first + count);
                    self.go(TpState::TriFetch, c)
                }
                Ref::Node(i) => {
                    let seg = self.hdr().seg;
                    self.note(c, |_| FollowKind::Node { seg, node: i });
                    let h = self.hdr();
                    let a = h.base + SEGMENT_HEADER_BYTES as u64 + i as u64 * NODE_BYTES as u64;
                    self.node_addr.set(a);
                    self.go(TpState::NodeFetch, c)
                }
                Ref::None => self.go(TpState::Pop, c),
            }
        }
    }

    /// Exit: the duplicate, with its entry into the child segment, on `ray_write`.
    pub(super) fn exit(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        let ray = self.cur.get().ray;
        let e = self.entry.get().clone();
        let w = RayWrite {
            seg: e.seg,
            ray: RayRec { entry: e.r, ..ray },
            done: false,
        };
        if !ctx.offer(&self.ray_write, w) {
            return None;
        }
        self.stats.exits += 1;
        let seg = self.hdr().seg;
        self.note(c, |_| FollowKind::Exit {
            seg,
            child: e.seg,
            entry: e.r,
        });
        Some(self.go(TpState::Pop, c))
    }

    /// NodeFetch: loads the inner node's line through the L1.
    pub(super) fn node_fetch(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        if !self.load(ctx, self.node_addr.val()) {
            return None;
        }
        self.req_at.set(c);
        Some(self.go(TpState::NodeWait, c))
    }

    /// BoxIssue, BoxIssue1: the node's two child boxes to the box pipe, one per
    /// cycle.
    pub(super) fn box_issue(&mut self, ctx: &mut Ctx, s: TpState, c: u64) -> Option<Next> {
        let tag = self.index as Tag;
        let ray = self.cur.get().ray;
        let side = (s == TpState::BoxIssue1) as usize;
        let l = self.line0.get();
        let lim = cull(self.best.get().t.min(self.t_ray()));
        let req = BoxReq {
            origin: ray.origin,
            inv_dir: self.inv_dir.val(),
            t_min: 0.0,
            t_max: lim,
            bmin: vec3_at(l, 24 * side),
            bmax: vec3_at(l, 24 * side + 12),
            tag: tag | (side as Tag) << 8,
        };
        if !ctx.offer(&self.box_req, req) {
            return None;
        }
        self.stats.box_tests += 1;
        if side == 0 {
            self.box_got.set(false);
            self.state.set(TpState::BoxIssue1);
            self.act_at.set(c + 1);
            Some(Next::AtCycle(c + 1))
        } else {
            self.req_at.set(c);
            Some(self.go(TpState::BoxWait, c))
        }
    }

    /// NodePush: pushes the hit children, the far one first.
    pub(super) fn node_push(&mut self, c: u64) -> Next {
        let l = self.line0.get().clone();
        let hit = [self.box0.val(), self.box1.val()];
        // Push the far child first so the near one is visited first.
        let order = match (hit[0], hit[1]) {
            (Some(a), Some(b)) if b < a => [0, 1],
            _ => [1, 0],
        };
        let mut depth = self.stack_depth.val() as u32;
        for side in order {
            if let Some(t) = hit[side] {
                if depth >= self.stack_entries {
                    // The config promised a deep enough scratchpad; stop loudly.
                    self.state.set(TpState::Overflow);
                    return Next::Idle;
                }
                self.stack.write(
                    depth,
                    StackEntry {
                        r: l.u32_at(48 + 4 * side),
                        seg: l.u32_at(56 + 4 * side),
                        t,
                    },
                );
                depth += 1;
            }
        }
        self.stack_depth.set(depth as u16);
        self.stats.max_stack = self.stats.max_stack.max(depth as u64);
        self.go(TpState::Pop, c)
    }

    /// TriFetch: loads the leaf's next triangle through the L1.
    pub(super) fn tri_fetch(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        let a = self.tri_addr(self.tri_k.val());
        if !self.load(ctx, a) {
            return None;
        }
        self.req_at.set(c);
        Some(self.go(TpState::TriMemWait, c))
    }

    /// TriIssue: the triangle, from its line(s), to the triangle pipe.
    pub(super) fn tri_issue(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        let tag = self.index as Tag;
        let ray = self.cur.get().ray;
        let a = self.tri_addr(self.tri_k.val());
        let off = (a & 63) as usize;
        let mut b = [0u8; 48];
        for (i, x) in b.iter_mut().enumerate() {
            let o = off + i;
            *x = if o < 64 {
                self.line0.get().0[o]
            } else {
                self.line1.get().0[o - 64]
            };
        }
        let mut l = Line::default();
        l.0[..48].copy_from_slice(&b);
        let req = TriReq {
            origin: ray.origin,
            dir: ray.dir,
            t_min: 0.0,
            t_max: self.best.get().t.min(self.t_ray()),
            v0: vec3_at(&l, 0),
            v1: vec3_at(&l, 12),
            v2: vec3_at(&l, 24),
            tri_id: l.u32_at(36),
            tag,
        };
        if !ctx.offer(&self.tri_req, req) {
            return None;
        }
        self.stats.tri_tests += 1;
        self.req_at.set(c);
        Some(self.go(TpState::TriTestWait, c))
    }

    /// TriResult: keeps a closer hit; a shadow ray stops at its first; next triangle.
    pub(super) fn tri_result(&mut self, c: u64) -> Next {
        let ray = self.cur.get().ray;
        if let Some(h) = self.tri_hit.val() {
            if h.closer_than(self.best.get()) {
                self.best.set(h);
                let seg = self.hdr().seg;
                self.note(c, |_| FollowKind::Closer {
                    seg,
                    t: h.t,
                    tri_id: h.tri_id,
                });
            }
            if ray.is_shadow() {
                return self.go(TpState::Finish, c);
            }
        }
        let k = self.tri_k.val() + 1;
        self.tri_k.set(k);
        if k < self.tri_end.val() {
            self.go(TpState::TriFetch, c)
        } else {
            self.go(TpState::Pop, c)
        }
    }

    /// Finish: the end marker, then the hit (if any); back to Idle.
    pub(super) fn finish(&mut self, ctx: &mut Ctx, c: u64) -> Option<Next> {
        let ray = self.cur.get().ray;
        // The end marker first (same path as the duplicates, so it arrives
        // after them), then the hit; a refused hit retries without the marker.
        if !self.done_sent.val() {
            let m = RayWrite {
                seg: self.hdr().seg,
                ray,
                done: true,
            };
            if !ctx.offer(&self.ray_write, m) {
                return None;
            }
            self.done_sent.set(true);
        }
        let best = self.best.val();
        if best.is_hit() {
            let u = HitUpdate {
                index: ray.hit_index() as u32,
                hit: best,
            };
            if !ctx.offer(&self.hit, u) {
                return None;
            }
            self.stats.hits += 1;
        }
        self.stats.last_finish = c;
        let seg = self.hdr().seg;
        let best = best.is_hit().then_some((best.t, best.tri_id));
        self.note(c, |_| FollowKind::Finish { seg, best });
        self.followed = false;
        self.done_sent.set(false);
        self.state.set(TpState::Idle);
        // The next ray may already wait in the link: look next cycle.
        Some(Next::Cycle)
    }

    /// DivWait: the inverse direction from the divider.
    pub(super) fn div_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.div_resp) {
            Some(r) => {
                self.inv_dir.set(r.inv_dir);
                let w = c - self.req_at.val();
                self.stats.wait.divider += w;
                self.stats.stall.divider += w.saturating_sub(self.rt[0]);
                ctx.set_status(Status::Busy);
                self.go(TpState::Init, c)
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }

    /// NodeWait: the node's line from the L1.
    pub(super) fn node_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.mem_resp) {
            Some(r) => {
                self.line0.set(r.line);
                self.stats.wait.l1 += c - self.req_at.val();
                ctx.set_status(Status::Busy);
                self.go(TpState::BoxIssue, c)
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }

    /// BoxWait: the two box results, one at a time.
    pub(super) fn box_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.box_resp) {
            Some(r) => {
                let v = r.hit.then_some(r.t_entry);
                if r.tag >> 8 == 0 {
                    self.box0.set(v);
                } else {
                    self.box1.set(v);
                }
                let (seg, side) = (self.hdr().seg, (r.tag >> 8) as u32);
                self.note(c, |_| FollowKind::BoxTest { seg, side, hit: v });
                ctx.set_status(Status::Busy);
                if self.box_got.val() {
                    let w = c - self.req_at.val();
                    self.stats.wait.box_pipe += w;
                    self.stats.stall.box_pipe += w.saturating_sub(self.rt[1]);
                    self.go(TpState::NodePush, c)
                } else {
                    self.box_got.set(true);
                    Next::Cycle
                }
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }

    /// TriMemWait: the triangle's line(s) from the L1 (a straddling triangle
    /// loads its second line when the first arrives).
    pub(super) fn tri_mem_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.mem_resp) {
            Some(r) => {
                self.stats.wait.l1 += c - self.req_at.val();
                ctx.set_status(Status::Busy);
                let a = self.tri_addr(self.tri_k.val());
                let last = (a + TRI_BYTES as u64 - 1) & !63;
                if r.addr == a & !63 {
                    self.line0.set(r.line);
                    if last != r.addr {
                        // The triangle straddles two lines: load the second now.
                        let ok = self.load(ctx, last);
                        assert!(ok, "a TP's load link is empty while it waits");
                        self.req_at.set(c);
                        return Next::Cycle;
                    }
                } else {
                    self.line1.set(r.line);
                }
                self.go(TpState::TriIssue, c)
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }

    /// TriTestWait: the triangle pipe's result.
    pub(super) fn tri_test_wait(&mut self, ctx: &mut Ctx, c: u64) -> Next {
        match ctx.pop(&self.tri_resp) {
            Some(r) => {
                self.stats.tri_hits += r.hit as u64;
                let seg = self.hdr().seg;
                self.note(c, |_| FollowKind::TriTest {
                    seg,
                    tri_id: r.tri_id,
                    hit: r.hit.then_some(r.t),
                });
                self.tri_hit.set(r.hit.then_some(HitRec {
                    t: r.t,
                    tri_id: r.tri_id,
                    u: r.u,
                    v: r.v,
                }));
                let w = c - self.req_at.val();
                self.stats.wait.tri_pipe += w;
                self.stats.stall.tri_pipe += w.saturating_sub(self.rt[2]);
                ctx.set_status(Status::Busy);
                self.go(TpState::TriResult, c)
            }
            None => wait(ctx, Status::ResourceBusy),
        }
    }
}
