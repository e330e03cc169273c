//! Testbench stimulus for the ray-box pipeline.

use glam::Vec3;

use super::pipe_tb::PipeKind;
use crate::config::Config;
use crate::geom::inverse_dir;
use crate::rtl::PipeCfg;
use crate::rtl::{In, Out};
use crate::units::box_pipe::{BoxPipe, BoxPipePorts, BoxReq, BoxResp, box_test};
use crate::util::rng::Rng;

pub struct BoxKind;

fn req(o: Vec3, d: Vec3, bmin: Vec3, bmax: Vec3, tag: u16) -> BoxReq {
    BoxReq {
        origin: o,
        inv_dir: inverse_dir(d),
        t_min: 0.0,
        t_max: f32::INFINITY,
        bmin,
        bmax,
        tag,
    }
}

/// A direction component from a set that includes the hard values.
fn component(rng: &mut Rng) -> f32 {
    match rng.below(8) {
        0 => 0.0,
        1 => -0.0,
        2 => 1e-30,
        _ => rng.range_f32(-1.0, 1.0),
    }
}

impl PipeKind for BoxKind {
    type Req = BoxReq;
    type Resp = BoxResp;
    type Dut = BoxPipe;
    const NAME: &'static str = "box_pipe";
    fn cfg(c: &Config) -> PipeCfg {
        c.box_pipe
    }
    fn build(cfg: &PipeCfg, out_delay: u32, req: In<BoxReq>, resp: Out<BoxResp>) -> BoxPipe {
        BoxPipe::new(cfg, out_delay, BoxPipePorts { req, resp })
    }
    fn reference(r: &BoxReq) -> BoxResp {
        box_test(r)
    }
    fn directed() -> Vec<BoxReq> {
        let (lo, hi) = (Vec3::splat(-1.0), Vec3::splat(1.0));
        vec![
            req(Vec3::new(0.0, 0.0, -5.0), Vec3::Z, lo, hi, 0), // straight hit
            req(Vec3::new(0.0, 0.0, -5.0), -Vec3::Z, lo, hi, 1), // pointing away
            req(
                Vec3::new(1.0, 0.0, -5.0),
                Vec3::new(-0.0, 0.0, 1.0),
                lo,
                hi,
                2,
            ), // on a slab plane, -0
            req(Vec3::new(2.0, 0.0, -5.0), Vec3::Z, lo, hi, 3), // parallel outside
            req(Vec3::ZERO, Vec3::X, lo, hi, 4),                // origin inside
            req(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X, lo, hi, 5), // NaN origin
            req(
                Vec3::new(0.0, 0.0, -5.0),
                Vec3::Z,
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                6,
            ), // flat box
        ]
    }
    fn random(rng: &mut Rng, tag: u16) -> BoxReq {
        let c = Vec3::new(
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
        );
        let h = Vec3::new(
            rng.range_f32(0.0, 3.0),
            rng.range_f32(0.0, 3.0),
            rng.range_f32(0.0, 3.0),
        );
        let o = Vec3::new(
            rng.range_f32(-12.0, 12.0),
            rng.range_f32(-12.0, 12.0),
            rng.range_f32(-12.0, 12.0),
        );
        let mut d = Vec3::new(component(rng), component(rng), component(rng));
        if rng.chance(0.5) {
            d = c - o; // aimed at the box: mostly hits
        }
        let mut r = req(o, d, c - h, c + h, tag);
        r.t_max = if rng.chance(0.2) {
            rng.range_f32(0.0, 20.0)
        } else {
            f32::INFINITY
        };
        r
    }
}
