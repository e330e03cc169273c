//! Hardware units, one per file. Each is declared once with `unit!`.
pub mod box_pipe;
pub mod divider;
mod error;
pub mod follow;
pub mod hit_record_updater;
pub mod l1;
pub mod l2;
pub mod mem_ctrl;
pub mod memory;
pub mod scene_buffer;
pub mod shade;
pub mod staging_buffer;
pub mod stream_scheduler;
pub mod tm;
pub mod tm_xbar;
pub mod tp;
pub mod tp_shade;
pub mod tri_pipe;

/// Identifies the requester (thread processor and slot) so a shared unit's result
/// can be routed back. 16 bits cover 16 TPs with room for per-TP sub-ids.
pub type Tag = u16;

pub use error::UnitError;

use crate::rtl::link::LinkId;
use crate::rtl::{In, Out, Unit};

/// The TM's own units (tp, l1, staging_buffer, tm_xbar) as constructed, on
/// placeholder links: their declarations are the catalog's.
pub fn tm_units(cfg: &tm::TmSpec) -> Vec<Box<dyn Unit>> {
    let n = cfg.tm.tps as usize;
    let np = cfg.tm.tri_pipes as usize;
    fn ins<T>(k: usize) -> Vec<In<T>> {
        (0..k).map(|j| In::new(LinkId(j as u32))).collect()
    }
    fn outs<T>(k: usize) -> Vec<Out<T>> {
        (0..k).map(|j| Out::new(LinkId(j as u32))).collect()
    }
    let (i, o) = (LinkId(0), LinkId(1));
    let tp = tp::Tp::new(
        cfg,
        0,
        tp::TpPorts {
            ray: In::new(i),
            div_req: Out::new(o),
            div_resp: In::new(i),
            box_req: Out::new(o),
            box_resp: In::new(i),
            tri_req: Out::new(o),
            tri_resp: In::new(i),
            mem_req: Out::new(o),
            mem_resp: In::new(i),
            ray_write: Out::new(o),
            hit: Out::new(o),
            gmem_req: Out::new(o),
            gmem_resp: In::new(i),
        },
    );
    let l1 = l1::L1::new(
        &cfg.tm.l1,
        cfg.link.delay,
        l1::L1Ports {
            req: ins(n),
            resp: outs(n),
            miss_req: Out::new(o),
            miss_resp: In::new(i),
        },
    );
    let sb = staging_buffer::StagingBuffer::new(
        &cfg.tm,
        staging_buffer::StagingBufferPorts {
            fill: In::new(i),
            ray: outs(n),
        },
    );
    let xbar = tm_xbar::TmXbar::new(
        cfg,
        tm_xbar::TmXbarPorts {
            div_resp: In::new(i),
            div_req: Out::new(o),
            ray_write: Out::new(o),
            hit: Out::new(o),
            gmem_resp: In::new(i),
            gmem_req: Out::new(o),
            tp_div_req: ins(n),
            tp_box_req: ins(n),
            tp_tri_req: ins(n),
            tp_ray_write: ins(n),
            tp_hit: ins(n),
            tp_gmem_req: ins(n),
            tri_resp: ins(np),
            tp_div_resp: outs(n),
            tp_box_resp: outs(n),
            tp_tri_resp: outs(n),
            tp_gmem_resp: outs(n),
            tri_req: outs(np),
        },
    );
    vec![Box::new(tp), Box::new(l1), Box::new(sb), Box::new(xbar)]
}
