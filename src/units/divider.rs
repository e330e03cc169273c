//! The TM-shared divider (paper §5.1): each TP obtains the inverse of its ray's
//! direction here right after fetching the ray, for the box tests of a whole segment.
//! The result is `geom::inverse_dir`: exact IEEE reciprocals, ±0 giving ±inf.

use glam::Vec3;

use super::Tag;
use crate::geom::inverse_dir;
use crate::rtl::PipeCfg;
use crate::rtl::{Ctx, FixedPipe, LinkId, Logic, Next, Ready};

crate::payload_struct! {
    /// A direction to invert.
    pub struct DivReq {
        pub dir: Vec3,
        pub tag: Tag,
    }
}

crate::payload_struct! {
    /// Its component-wise reciprocal.
    pub struct DivResp {
        pub inv_dir: Vec3,
        pub tag: Tag,
    }
}

/// The function the divider computes.
pub fn div(r: &DivReq) -> DivResp {
    DivResp {
        inv_dir: inverse_dir(r.dir),
        tag: r.tag,
    }
}

crate::unit! {
    /// Shared reciprocal unit: inverse ray direction, three divides per request.
    pub struct Divider : "divider" {
        /// `out_delay` is the delay of the `resp` link, which counts toward the latency.
        new(cfg: &PipeCfg, out_delay: u32; ports: DividerPorts) {}
        params {
            latency: u32 = cfg.latency => "LATENCY",
            interval: u32 = cfg.interval => "II"
        }
        inputs { req: DivReq }
        outputs { resp: DivResp }
        state { pipe: FixedPipe<DivReq> = FixedPipe::new(cfg.latency - out_delay, cfg.interval) }
        extra { }
    }
}

impl Logic for Divider {
    #[inline]
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        self.pipe.step(ctx, &self.req, &self.resp, div)
    }
    /// By the initiation interval, room in the stages and no stall.
    fn can_accept(&self, _port: LinkId, at: &Ready) -> bool {
        self.pipe.can_accept(at.cycle(), at.out_ready(&self.resp))
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("divides", self.pipe.accepted() * 3),
            ("results", self.pipe.emitted()),
        ]
    }
}
