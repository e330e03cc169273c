//! Testbench stimulus for the TM-shared divider.

use glam::Vec3;

use super::pipe_tb::PipeKind;
use crate::config::Config;
use crate::rtl::PipeCfg;
use crate::rtl::{In, Out};
use crate::units::divider::{DivReq, DivResp, Divider, DividerPorts, div};
use crate::util::rng::Rng;

pub struct DivKind;

impl PipeKind for DivKind {
    type Req = DivReq;
    type Resp = DivResp;
    type Dut = Divider;
    const NAME: &'static str = "divider";
    fn cfg(c: &Config) -> PipeCfg {
        c.divider
    }
    fn build(cfg: &PipeCfg, out_delay: u32, req: In<DivReq>, resp: Out<DivResp>) -> Divider {
        Divider::new(cfg, out_delay, DividerPorts { req, resp })
    }
    fn reference(r: &DivReq) -> DivResp {
        div(r)
    }
    fn directed() -> Vec<DivReq> {
        [
            Vec3::new(1.0, 2.0, 4.0),
            Vec3::new(0.0, -0.0, 1.0),
            Vec3::new(1e-40, -1e-40, 3e38), // subnormals and a huge value
            Vec3::new(f32::INFINITY, f32::NEG_INFINITY, f32::NAN),
        ]
        .into_iter()
        .enumerate()
        .map(|(i, dir)| DivReq { dir, tag: i as u16 })
        .collect()
    }
    fn random(rng: &mut Rng, tag: u16) -> DivReq {
        let mut c = || match rng.below(10) {
            0 => 0.0,
            1 => -0.0,
            2 => f32::from_bits(rng.next_u32()), // any bit pattern, NaN included
            _ => rng.range_f32(-1.0, 1.0),
        };
        DivReq {
            dir: Vec3::new(c(), c(), c()),
            tag,
        }
    }
}
