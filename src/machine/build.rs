//! Elaboration: `Chip::new` builds the units and wires them through declared
//! links (the wiring is listed in the module docs of `machine`).

use crate::config::ChipCfg;
use crate::config::Config;
use crate::contract::{MemoryMap, SparseMem};
use crate::mem::config::EnergyCfg;
use crate::mem::energy::EnergyModel;
use crate::mem::{AddrMap, MemReq, MemResp};
use crate::rtl::{ClockId, In, Out, Sim, SimOptions};
use crate::units::hit_record_updater::{HitRecordUpdater, HitRecordUpdaterPorts};
use crate::units::l1::{L1Req, L1Resp};
use crate::units::l2::{L2, L2Flush, L2Ports};
use crate::units::mem_ctrl::{MemCtrl, MemCtrlPorts};
use crate::units::memory::{MemLineReq, MemLineResp, Memory, MemoryPorts};
use crate::units::scene_buffer::{SceneBuffer, SceneBufferPorts, SlotMap};
use crate::units::shade::ShadeConsts;
use crate::units::staging_buffer::SbFill;
use crate::units::stream_scheduler::{StreamScheduler, StreamSchedulerPorts, WaveStart};
use crate::units::tm::{self, TmPorts, TmUnits};
use crate::units::tp::{HitUpdate, RayWrite, ShadeRegs};

use super::host::Host;
use super::{Chip, ChipError, Dram, PORT_HITS, PORT_SCENE, PORT_SCHED};

impl Chip {
    /// Builds the chip for a scene laid out by `map` with `segments` segments.
    /// The steps run in a fixed order: link and unit ids (and so the waveform
    /// and the evaluation order) follow it.
    pub fn new(
        cfg: &Config,
        map: &MemoryMap,
        segments: usize,
        shade: &ShadeConsts,
        opts: SimOptions,
    ) -> Result<Chip, ChipError> {
        cfg.validate()?;
        let ch = &cfg.chip;
        let mut sim = Sim::new(opts);
        let clock = sim.clock("core", cfg.clocks.core_ps)?;
        let l = ch.links;
        let mut mem = MemPorts::link(&mut sim, ch);
        let (emit_o, emit_i) = sim.link::<RayWrite>("chip.emit", l);
        let (start_o, start_i) = sim.link::<WaveStart>("chip.start", l);
        let (map_o, map_i) = sim.link::<SlotMap>("chip.slot_map", l);
        let mut tml = TmLinks::link(&mut sim, ch);
        let l2_side = L2Side::link(&mut sim, ch, &mut mem, &mut tml, Host::new(emit_o, start_o));
        let host = sim.add("chip.host", clock, l2_side.host);
        let scheduler = sim.add(
            "chip.scheduler",
            clock,
            StreamScheduler::new(
                &ch.scheduler,
                &ch.scene_buffer,
                map,
                segments,
                StreamSchedulerPorts {
                    emit: emit_i,
                    start: start_i,
                    mem_resp: mem.sched_resp,
                    slot_map: map_o,
                    scene_req: mem.scene_req,
                    mem_req: mem.sched_req,
                    ray_write: tml.ray_write,
                    fill: tml.fill,
                },
            ),
        );
        let scene_buffer = sim.add(
            "chip.scene_buffer",
            clock,
            SceneBuffer::new(
                &ch.scene_buffer,
                l.delay,
                SceneBufferPorts {
                    slot_map: map_i,
                    fill: mem.scene_fill,
                    req: tml.miss_req,
                    resp: tml.miss_resp,
                },
            ),
        );
        let hit_updater = sim.add(
            "chip.hit_updater",
            clock,
            HitRecordUpdater::new(
                &ch.hit_updater,
                map.hits,
                HitRecordUpdaterPorts {
                    hit: tml.hit,
                    mem_req: l2_side.hru_req,
                    mem_resp: l2_side.hru_resp,
                },
            ),
        );
        let l2 = l2_side.unit.map(|u| sim.add("chip.l2", clock, u));
        let memory_unit = mem.memory.into_memory(
            ch,
            map,
            (tml.gmem_req, tml.gmem_resp),
            (l2_side.lane_req, l2_side.lane_resp),
        );
        let (memory_unit, dram) = add_dram(&mut sim, cfg, memory_unit)?;
        let memory = sim.add("chip.memory", clock, memory_unit);
        let tms = add_tms(&mut sim, clock, cfg, tml.ports);
        // Several evaluation lanes: the TMs spread over them, the first lane (a
        // worker's) also takes the hit record updater and the scene buffer, the
        // last (this thread's) the other global units (the DRAM controllers' own
        // clock edges then need no hand-over) and the step's bookkeeping.
        if tms.len() >= 2 {
            sim.set_lane_plan(
                tms.iter().map(|t| t.all().collect()).collect(),
                vec![hit_updater, scene_buffer],
            );
        }
        sim.elaborate()?;
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
            follow: None,
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

/// The memory unit's line ports: ports 0-2 (scheduler, scene stream, port 2),
/// then the streams' further lanes (one port per line per cycle). The
/// requesters take their ends; the memory's ends, in port order, become its
/// port lists.
struct MemPorts {
    memory: MemSide,
    /// Port 2's requester ends (the L2's memory side, or the hit record updater).
    port2: Option<(Out<MemLineReq>, In<MemLineResp>)>,
    /// The scheduler's ray-stream lanes and scene-stream lanes (port 0 and
    /// port 1 first).
    sched_req: Vec<Out<MemLineReq>>,
    sched_resp: Vec<In<MemLineResp>>,
    scene_req: Vec<Out<MemLineReq>>,
    scene_fill: Vec<In<MemLineResp>>,
}

/// The memory's ends of its line ports.
struct MemSide {
    /// Ports 0-2.
    req: Vec<In<MemLineReq>>,
    resp: Vec<Out<MemLineResp>>,
    /// The further lanes: their ports come after the TMs'.
    lane_req: Vec<In<MemLineReq>>,
    lane_resp: Vec<Out<MemLineResp>>,
}

impl MemPorts {
    fn link(sim: &mut Sim, ch: &ChipCfg) -> MemPorts {
        let l = ch.links;
        let mut mreq_o = Vec::new();
        let mut mreq_i = Vec::new();
        let mut mresp_o = Vec::new();
        let mut mresp_i = Vec::new();
        let port2 = if ch.l2.enabled { "l2" } else { "hits" };
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
        // Port 2 (`PORT_HITS`, `PORT_L2`): the hit record updater's or the L2's.
        let port2 = Some((
            mreq_o[PORT_HITS].take().expect("port"),
            mresp_i[PORT_HITS].take().expect("port"),
        ));
        MemPorts {
            memory: MemSide {
                req: mreq_i,
                resp: mresp_o,
                lane_req: lane_req_i,
                lane_resp: lane_resp_o,
            },
            port2,
            sched_req,
            sched_resp,
            scene_req,
            scene_fill,
        }
    }
}

impl MemSide {
    /// The memory unit on its ports: 0-2, then the TMs' global-memory ports
    /// `gmem` (without the L2; empty with it), the streams' further lanes, the
    /// L2's further lanes `l2_lanes`.
    fn into_memory(
        mut self,
        ch: &ChipCfg,
        map: &MemoryMap,
        gmem: (Vec<In<MemLineReq>>, Vec<Out<MemLineResp>>),
        l2_lanes: (Vec<In<MemLineReq>>, Vec<Out<MemLineResp>>),
    ) -> Memory {
        // Without the L2 the TMs' global-memory ports (the shading pass) go to
        // the memory too (empty with it).
        self.req.extend(gmem.0);
        self.resp.extend(gmem.1);
        self.req.extend(self.lane_req);
        self.resp.extend(self.lane_resp);
        self.req.extend(l2_lanes.0);
        self.resp.extend(l2_lanes.1);
        Memory::new(
            &ch.memory,
            ch.links.delay,
            SparseMem::new(map.capacity),
            MemoryPorts {
                req: self.req,
                resp: self.resp,
                ch_req: Vec::new(),
                ch_resp: Vec::new(),
            },
        )
    }
}

/// The TMs' links to the global units, the other ends of each TM's ports.
struct TmLinks {
    /// Each TM's own ends.
    ports: Vec<TmPorts>,
    /// The scheduler's, the scene buffer's and the hit record updater's ends.
    fill: Vec<Out<SbFill>>,
    miss_req: Vec<In<L1Req>>,
    miss_resp: Vec<Out<L1Resp>>,
    ray_write: Vec<In<RayWrite>>,
    hit: Vec<In<HitUpdate>>,
    /// The hit record updater's links to the L2 (client 0), with the L2.
    hru_l2_req: Option<(Out<MemLineReq>, In<MemLineReq>)>,
    hru_l2_resp: Option<(Out<MemLineResp>, In<MemLineResp>)>,
    /// The far ends of the TMs' global-memory ports: the L2's clients 1.., or
    /// memory ports without the L2.
    gmem_req: Vec<In<MemLineReq>>,
    gmem_resp: Vec<Out<MemLineResp>>,
}

impl TmLinks {
    fn link(sim: &mut Sim, ch: &ChipCfg) -> TmLinks {
        let (l, n) = (ch.links, ch.tms as usize);
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
        let with_l2 = ch.l2.enabled;
        let hru_l2_req = with_l2.then(|| sim.link::<MemLineReq>("chip.l2_req0_hits", l));
        let (gq_o, gmem_i) = per_tm!(MemLineReq, "gmem_req");
        let hru_l2_resp = with_l2.then(|| sim.link::<MemLineResp>("chip.l2_resp0_hits", l));
        let (gmem_o, gr_i) = per_tm!(MemLineResp, "gmem_resp");
        let ports: Vec<TmPorts> = (0..n)
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
        TmLinks {
            ports,
            fill: fill_o,
            miss_req: sbq_i,
            miss_resp: sbr_o,
            ray_write: rw_i,
            hit: hit_i,
            hru_l2_req,
            hru_l2_resp,
            gmem_req: gmem_i,
            gmem_resp: gmem_o,
        }
    }
}

/// What sits at memory port 2: the L2 (`chip.l2.enabled`, with its clients,
/// its further memory lanes and the host's flush links), or the hit record
/// updater alone.
struct L2Side {
    unit: Option<L2>,
    /// The host, with the flush links when there is an L2.
    host: Host,
    /// The hit record updater's memory-side ends (to the L2 or to port 2).
    hru_req: Out<MemLineReq>,
    hru_resp: In<MemLineResp>,
    /// The memory's ends of the L2's further lanes: their ports come last.
    lane_req: Vec<In<MemLineReq>>,
    lane_resp: Vec<Out<MemLineResp>>,
}

impl L2Side {
    /// Takes port 2 from `mem` and, with the L2, the TMs' global-memory ends
    /// from `tml` (as its clients 1..).
    fn link(
        sim: &mut Sim,
        ch: &ChipCfg,
        mem: &mut MemPorts,
        tml: &mut TmLinks,
        host: Host,
    ) -> L2Side {
        let l = ch.links;
        let (port2_req, port2_resp) = mem.port2.take().expect("port 2");
        if !ch.l2.enabled {
            return L2Side {
                unit: None,
                host,
                hru_req: port2_req,
                hru_resp: port2_resp,
                lane_req: Vec::new(),
                lane_resp: Vec::new(),
            };
        }
        let (mut l2_lane_req_i, mut l2_lane_resp_o) = (Vec::new(), Vec::new());
        // The L2's memory lanes: lane 0 is port 2, the further ones are
        // appended after the scheduler's lanes.
        let mut l2_mreq = vec![port2_req];
        let mut l2_mresp = vec![port2_resp];
        for j in 1..ch.l2.mem_lines_per_cycle {
            let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req_l2_lane{j}"), l);
            l2_mreq.push(a);
            l2_lane_req_i.push(b);
            let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp_l2_lane{j}"), l);
            l2_lane_resp_o.push(a);
            l2_mresp.push(b);
        }
        let (ho, hi) = tml.hru_l2_req.take().expect("made with the L2");
        let (hro, hri) = tml.hru_l2_resp.take().expect("made with the L2");
        let (fo, fi) = sim.link::<L2Flush>("chip.l2_flush", l);
        let (fdo, fdi) = sim.link::<L2Flush>("chip.l2_flush_done", l);
        let mut reqs = vec![hi];
        reqs.append(&mut tml.gmem_req);
        let mut resps = vec![hro];
        resps.append(&mut tml.gmem_resp);
        L2Side {
            unit: Some(L2::new(
                &ch.l2,
                l.delay,
                L2Ports {
                    req: reqs,
                    resp: resps,
                    mem_req: l2_mreq,
                    mem_resp: l2_mresp,
                    flush: fi,
                    flush_done: fdo,
                },
            )),
            host: host.with_flush(fo, fdi),
            hru_req: ho,
            hru_resp: hri,
            lane_req: l2_lane_req_i,
            lane_resp: l2_lane_resp_o,
        }
    }
}

/// `chip.memory.model = "gddr5"`: one controller per channel on the DRAM
/// clock behind the memory unit, and the energy models of its figures; the
/// memory unit unchanged with `fixed`.
fn add_dram(
    sim: &mut Sim,
    cfg: &Config,
    memory_unit: Memory,
) -> Result<(Memory, Option<Dram>), ChipError> {
    let ch = &cfg.chip;
    if ch.memory.model != crate::units::memory::MemoryModel::Gddr5 {
        return Ok((memory_unit, None));
    }
    let m = &cfg.mem;
    MemCtrl::supports(m)?;
    let dclk = sim.clock("dram", cfg.clocks.dram_ps)?;
    let amap = AddrMap::new(&m.geometry, &m.mapping)?;
    let mut ch_req = Vec::new();
    let mut ch_resp = Vec::new();
    let mut ctrls = Vec::new();
    for c in 0..m.geometry.channels {
        let (qo, qi) = sim.link::<MemReq>(&format!("chip.dram_req{c}"), m.ctrl.req_link);
        let (ro, ri) = sim.link::<MemResp>(&format!("chip.dram_resp{c}"), m.ctrl.resp_link);
        let ports = MemCtrlPorts { req: qi, resp: ro };
        let mut u = MemCtrl::new(m, cfg.clocks.dram_ps, c, ports);
        u.record_commands(ch.memory.check_timing);
        ctrls.push(sim.add(&format!("chip.mem_ctrl{c}"), dclk, u));
        ch_req.push(qo);
        ch_resp.push(ri);
    }
    let memory_unit = memory_unit.with_channels(amap, ch_req, ch_resp);
    let g = &m.geometry;
    let em = |name: &str| -> Result<EnergyModel, ChipError> {
        Ok(EnergyModel::new(
            &EnergyCfg::by_name(name, g)?,
            &m.timing,
            g.burst_cycles(),
            cfg.clocks.dram_ps,
        ))
    };
    let dram = Dram {
        clock: dclk,
        ctrls,
        cfg: m.clone(),
        paper: em("paper")?,
        physical: em("physical")?,
        check: ch.memory.check_timing,
    };
    Ok((memory_unit, Some(dram)))
}

/// The TMs, `chip.tm<k>`, each on its ports.
fn add_tms(sim: &mut Sim, clock: ClockId, cfg: &Config, ports: Vec<TmPorts>) -> Vec<TmUnits> {
    let mut tms = Vec::with_capacity(ports.len());
    let tm_spec = cfg.tm_spec();
    for (k, ports) in ports.into_iter().enumerate() {
        tms.push(tm::build(
            sim,
            clock,
            &tm_spec,
            &format!("chip.tm{k}"),
            ports,
        ));
    }
    tms
}
