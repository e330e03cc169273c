//! The ray-box pipeline of a TM (paper §5.1: initiation interval 1, latency 8).
//!
//! One issue tests one axis-aligned box against one ray with the precomputed inverse
//! direction (Williams et al. 2005); the TP issues the two children of a BVH2 node
//! back to back. The test itself is `geom::ray_box`, the same function the software
//! reference calls, so the unit and the reference cannot disagree.
//!
//! The TM holds the same pipeline (`FixedPipe` and `box_test`) inside its crossbar,
//! between two FIFOs with its links' timing (`tm_xbar`); this stand-alone unit on
//! two links is the one its testbench drives (`tb box_pipe`).

use glam::Vec3;

use super::Tag;
use crate::geom::{Aabb, ray_box};
use crate::rtl::PipeCfg;
use crate::rtl::{Ctx, FixedPipe, LinkId, Logic, Next, Ready};

crate::payload_struct! {
    /// A box test request.
    pub struct BoxReq {
        pub origin: Vec3,
        pub inv_dir: Vec3,
        pub t_min: f32,
        pub t_max: f32,
        pub bmin: Vec3,
        pub bmax: Vec3,
        pub tag: Tag,
    }
}

crate::payload_struct! {
    /// A box test result: hit and entry distance, routed back by tag.
    pub struct BoxResp {
        pub hit: bool,
        pub t_entry: f32,
        pub tag: Tag,
    }
}

/// The function the pipeline computes.
pub fn box_test(r: &BoxReq) -> BoxResp {
    let hit = ray_box(
        r.origin,
        r.inv_dir,
        r.t_min,
        r.t_max,
        &Aabb {
            min: r.bmin,
            max: r.bmax,
        },
    );
    BoxResp {
        hit: hit.is_some(),
        t_entry: hit.unwrap_or(0.0),
        tag: r.tag,
    }
}

crate::unit! {
    /// Ray-box intersection pipeline (one box per issue, slab test with inverse direction).
    pub struct BoxPipe : "box_pipe" {
        /// `out_delay` is the delay of the `resp` link, which counts toward the latency.
        new(cfg: &PipeCfg, out_delay: u32; ports: BoxPipePorts) {}
        params {
            latency: u32 = cfg.latency => "LATENCY",
            interval: u32 = cfg.interval => "II"
        }
        inputs { req: BoxReq }
        outputs { resp: BoxResp }
        state { pipe: FixedPipe<BoxReq> = FixedPipe::new(cfg.latency - out_delay, cfg.interval) }
        extra { }
    }
}

impl Logic for BoxPipe {
    #[inline]
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        self.pipe.step(ctx, &self.req, &self.resp, box_test)
    }
    /// By the initiation interval, room in the stages and no stall.
    fn can_accept(&self, _port: LinkId, at: &Ready) -> bool {
        self.pipe.can_accept(at.cycle(), at.out_ready(&self.resp))
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("tests", self.pipe.accepted()),
            ("results", self.pipe.emitted()),
        ]
    }
}
