//! The host (the driver, not hardware): emits the primary rays into the root queue
//! (one per cycle through the scheduler's `emit` port) and then `start`; for later
//! wavefronts it only sends `start` with the pixel count, and the shading pass on
//! the TPs emits the rays (stage C). With `chip.shading = "host"` it emits the
//! host-shaded rays of every wavefront (stage A).

use std::collections::VecDeque;

use crate::contract::RayRec;
use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, Payload, PortDecl, PortDir, Status, UnitDecl,
};
use crate::units::l2::L2Flush;
use crate::units::stream_scheduler::WaveStart;
use crate::units::tp::RayWrite;

pub struct Host {
    pub emit: Out<RayWrite>,
    pub start: Out<WaveStart>,
    rays: VecDeque<RayRec>,
    wave: Option<(u32, u32)>,
    pub sent: u64,
    /// The L2's flush ports (when the chip has an L2).
    pub flush: Option<(Out<L2Flush>, In<L2Flush>)>,
    flush_req: Option<bool>,
    /// Flushes answered.
    pub flushed: u64,
}

impl Host {
    pub fn new(emit: Out<RayWrite>, start: Out<WaveStart>) -> Self {
        Host {
            emit,
            start,
            rays: VecDeque::new(),
            wave: None,
            sent: 0,
            flush: None,
            flush_req: None,
            flushed: 0,
        }
    }
    /// Connects the L2's `flush` / `flush_done` ports.
    pub fn with_flush(mut self, req: Out<L2Flush>, done: In<L2Flush>) -> Self {
        self.flush = Some((req, done));
        self
    }
    /// Asks the L2 to write back (and with `invalidate` drop) every line; wake
    /// the unit afterwards. The answer is counted in `flushed`.
    pub fn request_flush(&mut self, invalidate: bool) {
        self.flush_req = Some(invalidate);
    }
    /// Queues a wavefront: `rays` to emit, then `start` (with `shade_pixels` > 0
    /// the shading pass emits the rays); wake the unit afterwards.
    pub fn load(&mut self, rays: Vec<RayRec>, wave: u32, shade_pixels: u32) {
        self.rays = rays.into();
        self.wave = Some((wave, shade_pixels));
    }
}

impl Declared for Host {
    fn decl(&self) -> UnitDecl {
        UnitDecl {
            module: "host",
            source: file!(),
            doc: "stage A host stand-in for the shading pass",
            params: vec![],
            ports: self.ports(),
            state: StateList::default().items,
        }
    }
    fn ports(&self) -> Vec<PortDecl> {
        let mut v = vec![
            PortDecl {
                name: "emit",
                dir: PortDir::Out,
                width: RayWrite::BITS,
                ty: RayWrite::sv_type(),
                fields: RayWrite::field_list(),
                link: self.emit.id,
            },
            PortDecl {
                name: "start",
                dir: PortDir::Out,
                width: WaveStart::BITS,
                ty: WaveStart::sv_type(),
                fields: WaveStart::field_list(),
                link: self.start.id,
            },
        ];
        if let Some((q, d)) = &self.flush {
            v.push(PortDecl {
                name: "flush",
                dir: PortDir::Out,
                width: L2Flush::BITS,
                ty: L2Flush::sv_type(),
                fields: L2Flush::field_list(),
                link: q.id,
            });
            v.push(PortDecl {
                name: "flush_done",
                dir: PortDir::In,
                width: L2Flush::BITS,
                ty: L2Flush::sv_type(),
                fields: L2Flush::field_list(),
                link: d.id,
            });
        }
        v
    }
    fn sample_state(&self, _cycle: u64, _out: &mut Samples) {}
    fn commit_state(&mut self) {}
    fn reset_state(&mut self) {}
    fn state_pending(&self) -> bool {
        false
    }
}

impl Logic for Host {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if let Some((_, done)) = &self.flush
            && ctx.pop(done).is_some()
        {
            self.flushed += 1;
        }
        if let (Some(inv), Some((q, _))) = (self.flush_req, &self.flush) {
            if ctx.offer(q, L2Flush { invalidate: inv }) {
                self.flush_req = None;
                ctx.set_status(Status::Busy);
                return Next::Cycle;
            }
            ctx.set_status(Status::OutputBlocked);
            return Next::Idle;
        }
        if let Some(r) = self.rays.front() {
            let w = RayWrite {
                seg: 0,
                ray: *r,
                done: false,
            };
            if ctx.offer(&self.emit, w) {
                self.rays.pop_front();
                self.sent += 1;
                ctx.set_status(Status::Busy);
                return Next::Cycle;
            }
            ctx.set_status(Status::OutputBlocked);
            return Next::Idle;
        }
        if let Some((wave, shade_pixels)) = self.wave {
            if ctx.offer(&self.start, WaveStart { wave, shade_pixels }) {
                self.wave = None;
                ctx.set_status(Status::Busy);
                return Next::Cycle;
            }
            ctx.set_status(Status::OutputBlocked);
            return Next::Idle;
        }
        ctx.set_status(Status::WaitInput);
        Next::Idle
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("sent", self.sent), ("flushed", self.flushed)]
    }
}
