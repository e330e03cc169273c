//! A ray-triangle pipeline of a TM (paper §5.1: two per TM, initiation interval 18,
//! latency 31). The test is `geom::ray_triangle`: Plücker coordinates with the
//! division deferred until a hit, watertight, shared with the software reference.

use glam::Vec3;

use super::Tag;
use crate::geom::{Triangle, ray_triangle};
use crate::rtl::PipeCfg;
use crate::rtl::{Ctx, FixedPipe, LinkId, Logic, Next, Ready};

crate::payload_struct! {
    /// A triangle test request.
    pub struct TriReq {
        pub origin: Vec3,
        pub dir: Vec3,
        pub t_min: f32,
        pub t_max: f32,
        pub v0: Vec3,
        pub v1: Vec3,
        pub v2: Vec3,
        pub tri_id: u32,
        pub tag: Tag,
    }
}

crate::payload_struct! {
    /// A triangle test result: on a hit, distance and barycentrics (u for v1, v for v2).
    pub struct TriResp {
        pub hit: bool,
        pub t: f32,
        pub u: f32,
        pub v: f32,
        pub tri_id: u32,
        pub tag: Tag,
    }
}

/// The function the pipeline computes.
pub fn tri_test(r: &TriReq) -> TriResp {
    let tri = Triangle {
        v0: r.v0,
        v1: r.v1,
        v2: r.v2,
    };
    match ray_triangle(r.origin, r.dir, r.t_min, r.t_max, &tri) {
        Some(h) => TriResp {
            hit: true,
            t: h.t,
            u: h.u,
            v: h.v,
            tri_id: r.tri_id,
            tag: r.tag,
        },
        None => TriResp {
            hit: false,
            t: 0.0,
            u: 0.0,
            v: 0.0,
            tri_id: r.tri_id,
            tag: r.tag,
        },
    }
}

crate::unit! {
    /// Ray-triangle intersection pipeline (Plücker test, division deferred to a hit).
    pub struct TriPipe : "tri_pipe" {
        /// `out_delay` is the delay of the `resp` link, which counts toward the latency.
        new(cfg: &PipeCfg, out_delay: u32; ports: TriPipePorts) {}
        params {
            latency: u32 = cfg.latency => "LATENCY",
            interval: u32 = cfg.interval => "II"
        }
        inputs { req: TriReq }
        outputs { resp: TriResp }
        state { pipe: FixedPipe<TriReq> = FixedPipe::new(cfg.latency - out_delay, cfg.interval) }
        extra { }
    }
}

impl Logic for TriPipe {
    #[inline]
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        self.pipe.step(ctx, &self.req, &self.resp, tri_test)
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
