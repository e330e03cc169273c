//! The TP's shading kernel (issue 6 stage C): the second program of the thread
//! processor, run between wavefronts on work items the stream scheduler hands out
//! through the staging buffer (a `SbRay` whose header segment is [`SHADE_SEG`] and
//! whose `ray_id` is the pixel).
//!
//! One item, through the TM's global-memory port (the L2; tag `shading`):
//! 1. read the pixel's path-state line; a finished path (no ray in flight) ends
//!    the item here;
//! 2. read the line holding its two hit records (bounce at `2*pixel`, shadow at
//!    `2*pixel + 1`, 32 B, one line);
//! 3. for a bounce hit: read the triangle-index word, the triangle (48 B, one or
//!    two lines) and its material;
//! 4. `shade_step` (the same function functional mode calls);
//! 5. send the new shadow and bounce rays to the root segment's queue (segment 0)
//!    on `ray_write`;
//! 6. write the path-state line, and reset the new rays' hit records (one masked
//!    write of the hit line); wait for both writes to be answered;
//! 7. send the item's end marker (`RayWrite { seg: SHADE_SEG, done: true }`) on the
//!    same path as its rays, so the scheduler knows when every emitted ray of the
//!    pass is in the root queue.
//!
//! Every load waits for its line before the next (the addresses depend on it).

use glam::Vec3;

use super::follow::FollowKind;
use super::l1::Line;
use super::memory::{MemLineReq, MemLineResp};
use super::shade::{ShadeConsts, shade_reads, shade_step};
use super::tp::{RayWrite, Tp, TpState};
use crate::contract::{
    HIT_BYTES, HitRec, LINE_BYTES, MemoryMap, PathRec, RayRec, TRI_BYTES, TriRec,
};
use crate::mem::StreamTag;
use crate::rtl::{Ctx, Next};

/// The header segment of a shading work item and of its end marker.
pub const SHADE_SEG: u32 = u32::MAX - 1;

/// The shading pass's control registers, loaded by the host before the frame
/// (the scene's constants and where the records live).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeRegs {
    pub consts: ShadeConsts,
    pub hits: u64,
    pub path: u64,
    pub tri_index: u64,
    pub scene: u64,
    pub materials: u64,
}

impl ShadeRegs {
    pub fn new(consts: ShadeConsts, map: &MemoryMap) -> Self {
        ShadeRegs {
            consts,
            hits: map.hits,
            path: map.path,
            tri_index: map.tri_index,
            scene: map.scene,
            materials: map.materials,
        }
    }
}

// What the TP waits for in `ShWait` (`sh_step`).
const STEP_PATH: u32 = 0;
const STEP_HIT: u32 = 1;
const STEP_TRI_INDEX: u32 = 2;
const STEP_TRI0: u32 = 3;
const STEP_TRI1: u32 = 4;
const STEP_MATERIAL: u32 = 5;
const STEP_ACK: u32 = 6;

const LINE: u64 = LINE_BYTES;

impl Tp {
    /// Loads the shading pass's control registers (`None`: the TP cannot shade).
    pub fn set_shading(&mut self, regs: Option<ShadeRegs>) {
        self.shading = regs;
    }

    fn regs(&self) -> ShadeRegs {
        self.shading
            .expect("a shading item reached a TP without shading registers (Tp::set_shading)")
    }

    fn pixel(&self) -> u64 {
        self.cur.get().ray.ray_id as u64
    }

    /// Byte offset of hit record `idx` in its line.
    fn hit_off(&self, idx: u64) -> usize {
        ((self.regs().hits + idx * HIT_BYTES as u64) % LINE) as usize
    }

    fn path(&self) -> PathRec {
        PathRec::decode(&self.line0.get().0)
    }

    /// The triangle from its first line and (if it straddles) its second.
    fn triangle_in(&self, l0: &Line, l1: &Line) -> TriRec {
        let off = (self.sh_tri_addr.val() % LINE) as usize;
        let mut b = [0u8; TRI_BYTES as usize];
        for (i, x) in b.iter_mut().enumerate() {
            let o = off + i;
            *x = if o < 64 { l0.0[o] } else { l1.0[o - 64] };
        }
        TriRec::decode(&b)
    }

    fn triangle(&self) -> TriRec {
        self.triangle_in(self.sh_tri0.get(), self.sh_tri1.get())
    }

    fn gmem(&mut self, ctx: &mut Ctx, r: MemLineReq) -> bool {
        let write = r.write;
        if ctx.offer(&self.gmem_req, r) {
            if write {
                self.stats.gmem_writes += 1;
            } else {
                self.stats.gmem_reads += 1;
            }
            true
        } else {
            false
        }
    }

    fn read(&mut self, ctx: &mut Ctx, addr: u64, step: u32, c: u64) -> Option<Next> {
        let r = MemLineReq::read(addr, StreamTag::Shading, self.index as u32);
        if !self.gmem(ctx, r) {
            return None;
        }
        self.sh_step.set(step);
        self.req_at.set(c);
        Some(self.go(TpState::ShWait, c))
    }

    /// Loads `addr`'s line next (through `ShLoad`, which pays the address cost).
    fn load_next(&mut self, addr: u64, step: u32, c: u64) -> Next {
        self.sh_addr.set(addr & !(LINE - 1));
        self.sh_step.set(step);
        self.go(TpState::ShLoad, c)
    }

    /// `tri` = the triangle just read (its line registers are written at the edge).
    fn material_next(&mut self, tri: TriRec, c: u64) -> Next {
        let m = tri.material;
        let a = self.regs().materials + m as u64 * 16;
        self.load_next(a, STEP_MATERIAL, c)
    }

    /// A computing state of the shading kernel in cycle `c`; `None` if refused.
    pub(super) fn shade_act(&mut self, ctx: &mut Ctx, s: TpState, c: u64) -> Option<Next> {
        let pix = self.pixel();
        Some(match s {
            TpState::ShPath => {
                let a = self.regs().path + pix * crate::contract::PATH_BYTES as u64;
                return self.read(ctx, a, STEP_PATH, c);
            }
            TpState::ShLoad => {
                let (a, step) = (self.sh_addr.val(), self.sh_step.val());
                return self.read(ctx, a, step, c);
            }
            TpState::Shade => {
                let path = self.path();
                let (rs, rb) = shade_reads(&path);
                let hl = self.line1.get().clone();
                let rec = |idx: u64| {
                    let o = self.hit_off(idx);
                    HitRec::decode(&hl.0[o..o + HIT_BYTES as usize])
                };
                let shadow_hit = rs.then(|| rec(pix * 2 + 1));
                let bounce_hit = rb.then(|| rec(pix * 2));
                let tri = bounce_hit.filter(|h| h.is_hit()).map(|_| self.triangle());
                let albedo = self.sh_albedo.val();
                let out = shade_step(
                    &self.regs().consts,
                    pix as u32,
                    path,
                    shadow_hit,
                    bounce_hit,
                    tri.as_ref().map(|t| (t, albedo)),
                );
                self.stats.shade_hits += out.hit as u64;
                let (hit, occluded) = (out.hit, out.occluded);
                self.note_shade(c, |_| FollowKind::Shaded { hit, occluded });
                self.stats.shade_occluded += out.occluded as u64;
                self.line0.set(Line(out.path.encode()));
                self.sh_shadow.set(out.shadow);
                self.sh_bounce.set(out.bounce);
                self.sh_emitted.set(0);
                if out.shadow.is_some() || out.bounce.is_some() {
                    self.go(TpState::ShEmit, c)
                } else {
                    self.go(TpState::ShStore, c)
                }
            }
            TpState::ShEmit => {
                // Shadow first, then bounce: the order functional mode emits them.
                let (shadow, bounce) = (self.sh_shadow.val(), self.sh_bounce.val());
                let ray: RayRec = shadow.or(bounce).expect("ShEmit has a ray to send");
                let w = RayWrite {
                    seg: 0,
                    ray,
                    done: false,
                };
                if !ctx.offer(&self.ray_write, w) {
                    return None;
                }
                self.stats.shade_rays += 1;
                let ray_id = ray.ray_id;
                self.note_shade(c, |_| FollowKind::ShadeEmit { ray_id });
                self.stats.shade_shadow_rays += ray.is_shadow() as u64;
                self.sh_emitted
                    .set(self.sh_emitted.val() | 1 << ray.is_shadow() as u32);
                if shadow.is_some() {
                    self.sh_shadow.set(None);
                } else {
                    self.sh_bounce.set(None);
                }
                if shadow.is_some() && bounce.is_some() {
                    self.go(TpState::ShEmit, c)
                } else {
                    self.go(TpState::ShStore, c)
                }
            }
            TpState::ShStore => {
                let a = self.regs().path + pix * crate::contract::PATH_BYTES as u64;
                let r = MemLineReq {
                    addr: a,
                    write: true,
                    tag: StreamTag::Shading,
                    id: self.index as u32,
                    mask: u64::MAX,
                    data: self.line0.get().clone(),
                };
                if !self.gmem(ctx, r) {
                    return None;
                }
                self.sh_acks.set(1);
                self.req_at.set(c);
                if self.sh_emitted.val() != 0 {
                    // The hit-line write follows in the next cycle.
                    self.state.set(TpState::ShStore1);
                    self.act_at.set(c + 1);
                    Next::AtCycle(c + 1)
                } else {
                    self.sh_step.set(STEP_ACK);
                    self.go(TpState::ShWait, c)
                }
            }
            TpState::ShStore1 => {
                // Reset the hit records of the rays just emitted (bit 0: bounce,
                // bit 1: shadow), as functional mode's `emit` does.
                let e = self.sh_emitted.val();
                let mut data = Line::default();
                let mut mask = 0u64;
                for (bit, idx) in [(1, pix * 2), (2, pix * 2 + 1)] {
                    if e & bit != 0 {
                        let o = self.hit_off(idx);
                        data.0[o..o + HIT_BYTES as usize].copy_from_slice(&HitRec::NONE.encode());
                        mask |= ((1u64 << HIT_BYTES) - 1) << o;
                    }
                }
                let a = self.regs().hits + pix * 2 * HIT_BYTES as u64;
                let r = MemLineReq {
                    addr: a & !(LINE - 1),
                    write: true,
                    tag: StreamTag::Shading,
                    id: self.index as u32,
                    mask,
                    data,
                };
                if !self.gmem(ctx, r) {
                    return None;
                }
                self.sh_acks.set(2);
                self.sh_step.set(STEP_ACK);
                self.go(TpState::ShWait, c)
            }
            TpState::ShDone => {
                let m = RayWrite {
                    seg: super::tp_shade::SHADE_SEG,
                    ray: self.cur.get().ray,
                    done: true,
                };
                if !ctx.offer(&self.ray_write, m) {
                    return None;
                }
                self.note_shade(c, |_| FollowKind::ShadeDone);
                self.followed_shade = None;
                self.state.set(TpState::Idle);
                Next::Cycle
            }
            _ => unreachable!("not a shading state"),
        })
    }

    /// A global-memory response in `ShWait`, in cycle `c`.
    pub(super) fn shade_response(&mut self, ctx: &mut Ctx, r: MemLineResp, c: u64) -> Next {
        let pix = self.pixel();
        match self.sh_step.val() {
            STEP_ACK => {
                debug_assert!(r.write, "only write answers are outstanding");
                let left = self.sh_acks.val() - 1;
                self.sh_acks.set(left);
                if left == 0 {
                    self.go(TpState::ShDone, c)
                } else {
                    // Still waiting: the next answer's push wakes the TP.
                    ctx.set_status(crate::rtl::Status::ResourceBusy);
                    Next::Idle
                }
            }
            // Registers written here show their new value from the next cycle: decide
            // on the response's bytes.
            STEP_PATH => {
                let (rs, rb) = shade_reads(&PathRec::decode(&r.data.0));
                self.line0.set(r.data);
                if !rs && !rb {
                    // A finished path: nothing to shade, nothing to write.
                    return self.go(TpState::ShDone, c);
                }
                let a = self.regs().hits + pix * 2 * HIT_BYTES as u64;
                self.load_next(a, STEP_HIT, c)
            }
            STEP_HIT => {
                let (_, rb) = shade_reads(&self.path());
                let o = self.hit_off(pix * 2);
                let h = HitRec::decode(&r.data.0[o..o + HIT_BYTES as usize]);
                self.line1.set(r.data);
                if rb && h.is_hit() {
                    let a = self.regs().tri_index + h.tri_id as u64 * 4;
                    self.sh_tri_addr.set(a);
                    self.load_next(a, STEP_TRI_INDEX, c)
                } else {
                    self.go(TpState::Shade, c)
                }
            }
            STEP_TRI_INDEX => {
                let off = (self.sh_tri_addr.val() % LINE) as usize;
                let ti = r.data.u32_at(off);
                let a = self.regs().scene + ti as u64 * 16;
                self.sh_tri_addr.set(a);
                self.load_next(a, STEP_TRI0, c)
            }
            STEP_TRI0 => {
                let a = self.sh_tri_addr.val();
                let last = (a + TRI_BYTES as u64 - 1) & !(LINE - 1);
                if last != a & !(LINE - 1) {
                    self.sh_tri0.set(r.data);
                    self.load_next(last, STEP_TRI1, c)
                } else {
                    let tri = self.triangle_in(&r.data, &r.data);
                    self.sh_tri0.set(r.data);
                    self.material_next(tri, c)
                }
            }
            STEP_TRI1 => {
                let tri = self.triangle_in(self.sh_tri0.get(), &r.data);
                self.sh_tri1.set(r.data);
                self.material_next(tri, c)
            }
            STEP_MATERIAL => {
                let m = self.triangle().material;
                let off = ((self.regs().materials + m as u64 * 16) % LINE) as usize;
                let d = &r.data;
                self.sh_albedo.set(Vec3::new(
                    d.f32_at(off),
                    d.f32_at(off + 4),
                    d.f32_at(off + 8),
                ));
                self.go(TpState::Shade, c)
            }
            s => unreachable!("unknown shading step {s}"),
        }
    }
}
