//! Testbench stimulus for the ray-triangle pipeline.

use glam::Vec3;

use super::pipe_tb::PipeKind;
use crate::config::Config;
use crate::rtl::PipeCfg;
use crate::rtl::{In, Out};
use crate::units::tri_pipe::{TriPipe, TriPipePorts, TriReq, TriResp, tri_test};
use crate::util::rng::Rng;

pub struct TriKind;

fn req(o: Vec3, d: Vec3, v: [Vec3; 3], tri_id: u32, tag: u16) -> TriReq {
    TriReq {
        origin: o,
        dir: d,
        t_min: 0.0,
        t_max: f32::INFINITY,
        v0: v[0],
        v1: v[1],
        v2: v[2],
        tri_id,
        tag,
    }
}

fn point(rng: &mut Rng, s: f32) -> Vec3 {
    Vec3::new(
        rng.range_f32(-s, s),
        rng.range_f32(-s, s),
        rng.range_f32(-s, s),
    )
}

impl PipeKind for TriKind {
    type Req = TriReq;
    type Resp = TriResp;
    type Dut = TriPipe;
    const NAME: &'static str = "tri_pipe";
    fn cfg(c: &Config) -> PipeCfg {
        c.tri_pipe
    }
    fn build(cfg: &PipeCfg, out_delay: u32, req: In<TriReq>, resp: Out<TriResp>) -> TriPipe {
        TriPipe::new(cfg, out_delay, TriPipePorts { req, resp })
    }
    fn reference(r: &TriReq) -> TriResp {
        tri_test(r)
    }
    fn directed() -> Vec<TriReq> {
        let t = [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let o = Vec3::new(0.0, 0.0, -2.0);
        vec![
            req(o, Vec3::Z, t, 0, 0),                           // centre hit
            req(o, -Vec3::Z, t, 1, 1),                          // behind
            req(Vec3::new(0.0, -1.0, -2.0), Vec3::Z, t, 2, 2),  // on an edge
            req(Vec3::new(-1.0, -1.0, -2.0), Vec3::Z, t, 3, 3), // through a vertex
            req(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, t, 4, 4),   // in the plane (grazing)
            req(o, Vec3::Z, [t[0], t[0], t[2]], 5, 5),          // degenerate
            req(o, Vec3::new(f32::NAN, 0.0, 1.0), t, 6, 6),     // NaN direction
            req(
                o + Vec3::new(148376.0, 1234.0, -223423.0),
                Vec3::Z,
                t.map(|v| v + Vec3::new(148376.0, 1234.0, -223423.0)),
                7,
                7,
            ), // far away
        ]
    }
    fn random(rng: &mut Rng, tag: u16) -> TriReq {
        let v = [point(rng, 5.0), point(rng, 5.0), point(rng, 5.0)];
        let o = point(rng, 10.0);
        let d = if rng.chance(0.6) {
            // Aimed at a random point of the triangle (barycentrics may leave it).
            let (a, b) = (rng.range_f32(-0.1, 1.0), rng.range_f32(-0.1, 1.0));
            v[0] + (v[1] - v[0]) * a + (v[2] - v[0]) * b - o
        } else {
            point(rng, 1.0)
        };
        let mut r = req(o, d, v, rng.next_u32(), tag);
        if rng.chance(0.2) {
            r.t_max = rng.range_f32(0.0, 2.0);
        }
        r
    }
}
