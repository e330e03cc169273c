//! Elaboration: `Chip::new` builds the units and wires them through declared
//! links (the wiring is listed in the module docs of `machine`).

use crate::config::Config;
use crate::contract::{MemoryMap, SparseMem};
use crate::mem::config::EnergyCfg;
use crate::mem::energy::EnergyModel;
use crate::mem::{AddrMap, MemReq, MemResp};
use crate::rtl::{Sim, SimOptions};
use crate::units::hit_record_updater::HitRecordUpdater;
use crate::units::l1::{L1Req, L1Resp};
use crate::units::l2::{L2, L2Flush};
use crate::units::mem_ctrl::MemCtrl;
use crate::units::memory::{MemLineReq, MemLineResp, Memory};
use crate::units::scene_buffer::{SceneBuffer, SlotMap};
use crate::units::shade::ShadeConsts;
use crate::units::staging_buffer::SbFill;
use crate::units::stream_scheduler::{StreamScheduler, WaveStart};
use crate::units::tm::{self, TmPorts};
use crate::units::tp::{HitUpdate, RayWrite, ShadeRegs};

use super::host::Host;
use super::{Chip, Dram, PORT_HITS, PORT_L2, PORT_SCENE, PORT_SCHED};

impl Chip {
    /// Builds the chip for a scene laid out by `map` with `segments` segments.
    pub fn new(
        cfg: &Config,
        map: &MemoryMap,
        segments: usize,
        shade: &ShadeConsts,
        opts: SimOptions,
    ) -> Result<Chip, String> {
        cfg.validate()?;
        let ch = &cfg.chip;
        let mut sim = Sim::new(opts);
        let clock = sim
            .clock("core", cfg.clocks.core_ps)
            .map_err(|e| e.to_string())?;
        let l = ch.links;
        let n = ch.tms as usize;
        // Memory ports.
        let mut mreq_o = Vec::new();
        let mut mreq_i = Vec::new();
        let mut mresp_o = Vec::new();
        let mut mresp_i = Vec::new();
        let with_l2 = ch.l2.enabled;
        let port2 = if with_l2 { "l2" } else { "hits" };
        for (k, who) in ["sched", "scene", port2].iter().enumerate() {
            let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req{k}_{who}"), l);
            mreq_o.push(Some(a));
            mreq_i.push(b);
            let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp{k}_{who}"), l);
            mresp_o.push(a);
            mresp_i.push(Some(b));
        }
        // Further stream lanes (one memory port per line per cycle): their links
        // now, their memory ports after the TMs' (ports 0-2 stay the first lanes).
        let (mut lane_req_o, mut lane_req_i, mut lane_resp_o, mut lane_resp_i) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (who, lanes) in [
            ("sched", ch.scheduler.ray_lines_per_cycle),
            ("scene", ch.scheduler.scene_lines_per_cycle),
        ] {
            for j in 1..lanes {
                let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req_{who}{j}"), l);
                lane_req_o.push(a);
                lane_req_i.push(b);
                let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp_{who}{j}"), l);
                lane_resp_o.push(a);
                lane_resp_i.push(b);
            }
        }
        let ray_extra = ch.scheduler.ray_lines_per_cycle as usize - 1;
        let mut lane_req_o = lane_req_o.into_iter();
        let mut lane_resp_i = lane_resp_i.into_iter();
        let sched_req: Vec<_> = std::iter::once(mreq_o[PORT_SCHED].take().expect("port"))
            .chain(lane_req_o.by_ref().take(ray_extra))
            .collect();
        let sched_resp: Vec<_> = std::iter::once(mresp_i[PORT_SCHED].take().expect("port"))
            .chain(lane_resp_i.by_ref().take(ray_extra))
            .collect();
        let scene_req: Vec<_> = std::iter::once(mreq_o[PORT_SCENE].take().expect("port"))
            .chain(lane_req_o)
            .collect();
        let scene_fill: Vec<_> = std::iter::once(mresp_i[PORT_SCENE].take().expect("port"))
            .chain(lane_resp_i)
            .collect();
        let (emit_o, emit_i) = sim.link::<RayWrite>("chip.emit", l);
        let (start_o, start_i) = sim.link::<WaveStart>("chip.start", l);
        let (map_o, map_i) = sim.link::<SlotMap>("chip.slot_map", l);
        // One kind of TM link at a time: each array port (the scheduler's
        // `ray_write`, the hit record updater's `hit`, the L2's clients) then has
        // consecutive links, so an arbiter finds its visible inputs in a word of
        // the non-empty bitset instead of loading every link's head.
        macro_rules! per_tm {
            ($t:ty, $name:literal) => {
                sim.links::<$t>(n, |k| format!("chip.tm{k}_{}", $name), l)
            };
        }
        let (fill_o, fill_i) = per_tm!(SbFill, "fill");
        let (miss_o, sbq_i) = per_tm!(L1Req, "miss_req");
        let (sbr_o, miss_i) = per_tm!(L1Resp, "miss_resp");
        let (rw_o, rw_i) = per_tm!(RayWrite, "ray_write");
        let (hit_o, hit_i) = per_tm!(HitUpdate, "hit");
        // The hit record updater is the L2's client 0, the TMs 1..: its links go
        // right before the TMs'.
        let hru_l2_req = with_l2.then(|| sim.link::<MemLineReq>("chip.l2_req0_hits", l));
        let (gq_o, mut gmem_i) = per_tm!(MemLineReq, "gmem_req");
        let hru_l2_resp = with_l2.then(|| sim.link::<MemLineResp>("chip.l2_resp0_hits", l));
        let (mut gmem_o, gr_i) = per_tm!(MemLineResp, "gmem_resp");
        let tm_ports: Vec<TmPorts> = (0..n)
            .map(|k| TmPorts {
                fill: fill_i[k],
                miss_req: miss_o[k],
                miss_resp: miss_i[k],
                ray_write: rw_o[k],
                hit: hit_o[k],
                gmem_req: gq_o[k],
                gmem_resp: gr_i[k],
            })
            .collect();
        // The L2 between its clients and memory port 2.
        let mut l2_unit = None;
        let mut host_unit = Host::new(emit_o, start_o);
        let (mut l2_lane_req_i, mut l2_lane_resp_o) = (Vec::new(), Vec::new());
        let (hru_req, hru_resp) = if with_l2 {
            // The L2's memory lanes: lane 0 is port 2, the further ones are
            // appended after the scheduler's lanes.
            let mut l2_mreq = vec![mreq_o[PORT_L2].take().expect("port")];
            let mut l2_mresp = vec![mresp_i[PORT_L2].take().expect("port")];
            for j in 1..ch.l2.mem_lines_per_cycle {
                let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req_l2_lane{j}"), l);
                l2_mreq.push(a);
                l2_lane_req_i.push(b);
                let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp_l2_lane{j}"), l);
                l2_lane_resp_o.push(a);
                l2_mresp.push(b);
            }
            let (ho, hi) = hru_l2_req.expect("made with the L2");
            let (hro, hri) = hru_l2_resp.expect("made with the L2");
            let (fo, fi) = sim.link::<L2Flush>("chip.l2_flush", l);
            let (fdo, fdi) = sim.link::<L2Flush>("chip.l2_flush_done", l);
            host_unit = host_unit.with_flush(fo, fdi);
            let mut reqs = vec![hi];
            reqs.append(&mut gmem_i);
            let mut resps = vec![hro];
            resps.append(&mut gmem_o);
            l2_unit = Some(L2::new(
                &ch.l2, l.delay, reqs, resps, l2_mreq, l2_mresp, fi, fdo,
            ));
            (ho, hri)
        } else {
            (
                mreq_o[PORT_HITS].take().expect("port"),
                mresp_i[PORT_HITS].take().expect("port"),
            )
        };
        let host = sim.add("chip.host", clock, host_unit);
        let scheduler = sim.add(
            "chip.scheduler",
            clock,
            StreamScheduler::new(
                &ch.scheduler,
                &ch.scene_buffer,
                map,
                segments,
                emit_i,
                start_i,
                sched_resp,
                map_o,
                scene_req,
                sched_req,
                rw_i,
                fill_o,
            ),
        );
        let scene_buffer = sim.add(
            "chip.scene_buffer",
            clock,
            SceneBuffer::new(&ch.scene_buffer, l.delay, map_i, scene_fill, sbq_i, sbr_o),
        );
        let hit_updater = sim.add(
            "chip.hit_updater",
            clock,
            HitRecordUpdater::new(&ch.hit_updater, map.hits, hit_i, hru_req, hru_resp),
        );
        let l2 = l2_unit.map(|u| sim.add("chip.l2", clock, u));
        // Without the L2 the TMs' global-memory ports (the shading pass) go to
        // the memory too (empty with it).
        mreq_i.extend(gmem_i);
        mresp_o.extend(gmem_o);
        mreq_i.extend(lane_req_i);
        mresp_o.extend(lane_resp_o);
        mreq_i.extend(l2_lane_req_i);
        mresp_o.extend(l2_lane_resp_o);
        let mut memory_unit = Memory::new(
            &ch.memory,
            l.delay,
            SparseMem::new(map.capacity),
            mreq_i,
            mresp_o,
        );
        let mut dram = None;
        if ch.memory.model == crate::units::memory::MemoryModel::Gddr5 {
            let m = &cfg.mem;
            MemCtrl::supports(m)?;
            let dclk = sim
                .clock("dram", cfg.clocks.dram_ps)
                .map_err(|e| e.to_string())?;
            let amap = AddrMap::new(&m.geometry, &m.mapping)?;
            let mut ch_req = Vec::new();
            let mut ch_resp = Vec::new();
            let mut ctrls = Vec::new();
            for c in 0..m.geometry.channels {
                let (qo, qi) = sim.link::<MemReq>(&format!("chip.dram_req{c}"), m.ctrl.req_link);
                let (ro, ri) = sim.link::<MemResp>(&format!("chip.dram_resp{c}"), m.ctrl.resp_link);
                let mut u = MemCtrl::new(m, cfg.clocks.dram_ps, c, qi, ro);
                u.ctrl.record_commands(ch.memory.check_timing);
                ctrls.push(sim.add(&format!("chip.mem_ctrl{c}"), dclk, u));
                ch_req.push(qo);
                ch_resp.push(ri);
            }
            memory_unit = memory_unit.with_channels(amap, ch_req, ch_resp);
            let g = &m.geometry;
            let em = |name: &str| -> Result<EnergyModel, String> {
                Ok(EnergyModel::new(
                    &EnergyCfg::by_name(name, g)?,
                    &m.timing,
                    g.burst_cycles(),
                    cfg.clocks.dram_ps,
                ))
            };
            dram = Some(Dram {
                clock: dclk,
                ctrls,
                cfg: m.clone(),
                paper: em("paper")?,
                physical: em("physical")?,
                check: ch.memory.check_timing,
            });
        }
        let memory = sim.add("chip.memory", clock, memory_unit);
        let mut tms = Vec::with_capacity(n);
        let tm_spec = cfg.tm_spec();
        for (k, ports) in tm_ports.into_iter().enumerate() {
            tms.push(tm::build(
                &mut sim,
                clock,
                &tm_spec,
                &format!("chip.tm{k}"),
                ports,
            ));
        }
        // Several evaluation lanes: the TMs spread over them, the first lane (a
        // worker's) also takes the hit record updater and the scene buffer, the
        // last (this thread's) the other global units (the DRAM controllers' own
        // clock edges then need no hand-over) and the step's bookkeeping.
        if n >= 2 {
            sim.set_lane_plan(
                tms.iter().map(|t| t.all().collect()).collect(),
                vec![hit_updater, scene_buffer],
            );
        }
        sim.elaborate().map_err(|e| e.to_string())?;
        let mut chip = Chip {
            sim,
            clock,
            tms,
            scheduler,
            scene_buffer,
            hit_updater,
            memory,
            host,
            l2,
            l2_invalidate: ch.shading == crate::config::Shading::Host,
            flush_cycles: 0,
            dram,
            watchdog: ch.watchdog_cycles,
            segments,
            wave: 0,
            stack_need: None,
            stack_cfg: (cfg.tm.scratchpad_bytes, cfg.tm.stack_entry_bytes),
            total_cycles: 0,
            wall_s: 0.0,
        };
        let shading = ShadeRegs::new(*shade, map);
        for u in chip.tps().collect::<Vec<_>>() {
            chip.tp_mut(u).set_shading(Some(shading));
        }
        Ok(chip)
    }
}
