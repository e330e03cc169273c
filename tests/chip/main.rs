//! The cycle-level chip (stage A of issue 6): every ray agrees with functional mode,
//! the timing-independent counts match exactly, nothing is lost, small chips
//! force back-pressure, sleeping and evaluation order change nothing, and bad
//! configurations are named.

mod errors;
mod gddr5;
mod invariance;
mod passes;
mod streams;

use dualstream::accel::AccelCfg;
use dualstream::config::Config;
use dualstream::config::Shading;
use dualstream::render::{ChipRun, Frame, Mode, RenderCfg, WaveStats, render};
use dualstream::rtl::SimOptions;

/// The chip on the fixed-latency memory (`gddr5_cfg`: the default GDDR5).
fn chip_cfg(tms: u32, tps: u32) -> Config {
    let mut c = Config::default();
    c.chip.memory.model = dualstream::units::memory::MemoryModel::Fixed;
    c.chip.tms = tms;
    c.tm.tps = tps;
    c
}

/// Small segments so the small scenes have many segments and duplication.
fn rcfg(segment_kb: u32, chip: Option<(Config, SimOptions)>) -> RenderCfg {
    RenderCfg {
        accel: AccelCfg {
            segment_bytes: segment_kb << 10,
            ..AccelCfg::default()
        },
        chip: chip.map(|(config, sim)| {
            Box::new(ChipRun {
                config,
                sim,
                ..ChipRun::default()
            })
        }),
        ..RenderCfg::default()
    }
}

fn scene(name: &str, w: u32, h: u32, bounces: u32) -> dualstream::scene::Scene {
    let mut s = dualstream::scene::load(name).unwrap();
    s.settings.width = w;
    s.settings.height = h;
    s.settings.bounces = bounces;
    s
}

/// Timing-independent counts: everything but the hit-record traffic (merging in
/// the hit record updater depends on timing), the shading lines (the TPs read and
/// write through the memory port, the functional model counts records) and the
/// deepest stack (the TP counts its scratchpad occupancy, one entry more than the
/// functional traversal's).
fn timeless(w: &WaveStats) -> WaveStats {
    let mut t = w.traversal;
    t.max_stack = 0;
    WaveStats {
        hit_lines_read: 0,
        hit_lines_written: 0,
        shading_lines: 0,
        traversal: t,
        ..*w
    }
}

fn same_frame(f: &Frame, c: &Frame, what: &str) {
    assert_eq!(f.waves.len(), c.waves.len(), "{what}: wavefronts");
    for (k, (a, b)) in f.waves.iter().zip(&c.waves).enumerate() {
        assert_eq!(timeless(a), timeless(b), "{what}: wavefront {k} counts");
    }
    let bits = |fr: &Frame| -> Vec<u32> {
        fr.radiance
            .iter()
            .flat_map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect()
    };
    assert!(
        bits(f) == bits(c),
        "{what}: image differs from functional mode"
    );
}

#[test]
fn every_ray_agrees_on_small_chips() {
    for (name, w, h, seg_kb) in [
        ("tiny", 16, 16, 8),
        ("cornell", 16, 12, 8),
        ("spheres", 8, 8, 64),
    ] {
        let s = scene(name, w, h, 3);
        let f = render(&s, Mode::Functional, &rcfg(seg_kb, None), &mut |_| {}).unwrap();
        assert!(
            f.accel.segments > 1 || name == "tiny",
            "{name}: several segments"
        );
        for (tms, tps, shading) in [
            (1, 1, Shading::Tps),
            (1, 16, Shading::Tps),
            (2, 16, Shading::Tps),
            (2, 16, Shading::Host),
            (8, 16, Shading::Tps),
        ] {
            let mut cc = chip_cfg(tms, tps);
            cc.chip.shading = shading;
            let mut cfg = rcfg(seg_kb, Some((cc, SimOptions::default())));
            cfg.verify = true;
            let c = render(&s, Mode::Cycle, &cfg, &mut |_| {}).unwrap();
            same_frame(&f, &c, &format!("{name} on {tms}x{tps} {shading:?}"));
            // --verify: every ray's hit record checked against the reference.
            assert_eq!(c.verified_rays, c.total.rays, "{name}: every ray verified");
            let chip = c.chip.as_ref().unwrap();
            assert!(chip.total_cycles > 0);
            let tp = shading == Shading::Tps;
            // On the TPs the last run is the last wavefront's shading pass.
            assert_eq!(chip.waves.len(), f.waves.len() + tp as usize);
            if tp {
                let items: u64 = chip.waves.iter().map(|w| w.shade_items).sum();
                let pixels = (w * h) as u64;
                assert_eq!(
                    items,
                    pixels * f.waves.len() as u64,
                    "{name}: every pixel shaded per pass"
                );
                let emitted: u64 = chip.waves.iter().map(|w| w.shade_rays).sum();
                assert_eq!(
                    emitted + pixels,
                    c.total.rays,
                    "{name}: rays emitted by the TPs"
                );
                assert_eq!(chip.waves.last().unwrap().rays_emitted, 0);
                assert!(
                    chip.waves[1..]
                        .iter()
                        .all(|w| w.shade_cycles > 0 && w.shade_cycles < w.cycles)
                );
                let hits: u64 = chip.waves.iter().map(|w| w.shade_hits).sum();
                assert_eq!(hits, f.total.hits, "{name}: bounce hits shaded");
            }
        }
    }
}

// ---- sleeping, shadow mode and evaluation order (pattern of tests/kernel.rs) ----

use std::io::Write;
use std::sync::{Arc, Mutex};

use dualstream::contract::HitRec;
use dualstream::machine::Chip;
use dualstream::rtl::{TraceSpec, Tracer};

#[derive(Clone, Default)]
struct Buf(Arc<Mutex<Vec<u8>>>);
impl Write for Buf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325u64, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

#[derive(Debug, PartialEq)]
struct Outcome {
    cycles: u64,
    stats: Vec<dualstream::rtl::UnitStats>,
    vcd_hash: u64,
    hits: Vec<[u32; 4]>,
}

/// One primary wavefront of `cornell` 8x8 on a 1 x 4 chip, traced throughout.
fn run_tiny_chip(opts: SimOptions) -> Outcome {
    run_tiny_chip_with(chip_cfg(1, 4), opts, "")
}

/// `trace`: the units to trace (`TraceSpec::filter`, empty: all).
fn run_tiny_chip_with(cfg: Config, opts: SimOptions, trace: &str) -> Outcome {
    run_tiny_chip_traced(cfg, opts, Some(trace)).0
}

/// A chip for `cornell` 8x8 with 8 KB segments, the scene prepared for it and
/// the rays of its first treelet (their hit records reset).
fn tiny_chip(
    mut cfg: Config,
    opts: SimOptions,
) -> (
    Chip,
    dualstream::render::Prepared,
    Vec<dualstream::contract::RayRec>,
) {
    let s = scene("cornell", 8, 8, 1);
    let rc = rcfg(8, None);
    let mut p = dualstream::render::prepare(&s, &rc).unwrap();
    let rays = dualstream::testbench::tm_tb::treelet_rays(&p, &s, 0).swap_remove(0);
    for r in &rays {
        HitRec::NONE.write(&mut p.mem, p.map.hit_addr(r.hit_index()));
    }
    cfg.accel = rc.accel.clone();
    let consts = dualstream::render::shade_consts(&s, &p);
    let chip = Chip::new(&cfg, &p.map, p.seg.segments.len(), &consts, opts).unwrap();
    (chip, p, rays)
}

/// Also returns the steps evaluated on two threads. `trace: None`: no waveform
/// (two threads are used only without one).
fn run_tiny_chip_traced(cfg: Config, opts: SimOptions, trace: Option<&str>) -> (Outcome, u64) {
    let (o, parallel, _) = run_tiny_chip_balanced(cfg, opts, trace, false);
    (o, parallel)
}

/// `moving`: two threads move a TM between them every 8 parallel steps (asserted
/// to happen).
fn run_tiny_chip_balanced(
    cfg: Config,
    opts: SimOptions,
    trace: Option<&str>,
    moving: bool,
) -> (Outcome, u64, u64) {
    let auto = opts.auto_lanes;
    let (mut chip, mut p, rays) = tiny_chip(cfg, opts);
    if moving {
        chip.sim.set_balance(8, true);
    }
    if auto {
        // Switch among 1, 2, ... lanes every few steps (the measured choice
        // would rarely switch in so short a run).
        chip.sim.force_lane_switches(40);
    }
    let buf = Buf::default();
    if let Some(trace) = trace {
        chip.sim
            .attach_tracer(
                Tracer::new(
                    Box::new(buf.clone()),
                    TraceSpec {
                        filter: trace.into(),
                        ..TraceSpec::all()
                    },
                )
                .unwrap(),
            )
            .unwrap();
    }
    let w = chip.trace_wave(&mut p.mem, &rays).unwrap();
    if trace.is_some() {
        chip.sim.finish_trace().unwrap().unwrap();
    }
    let vcd = buf.0.lock().unwrap().clone();
    let out = Outcome {
        cycles: w.cycles,
        stats: chip.sim.all_stats(),
        vcd_hash: fnv(&vcd),
        hits: rays
            .iter()
            .map(|r| {
                let h = HitRec::read(&p.mem, p.map.hit_addr(r.hit_index()));
                [h.t.to_bits(), h.tri_id, h.u.to_bits(), h.v.to_bits()]
            })
            .collect(),
    };
    if moving {
        assert!(
            chip.sim.balance_moves() > 0,
            "no TM moved between the threads"
        );
    }
    if auto {
        assert!(chip.sim.lane_switches() > 2, "the lane count never changed");
        let by = chip.sim.steps_by_lanes();
        assert!(
            by.iter().filter(|&&n| n > 0).count() >= 3,
            "not every lane count ran: {by:?}"
        );
    }
    let tp_evals = chip
        .sim
        .evals_by_module()
        .iter()
        .find(|m| m.module == "tp")
        .map_or(0, |m| m.evals);
    (out, chip.sim.parallel_steps, tp_evals)
}

fn variants() -> [(&'static str, SimOptions); 3] {
    [
        (
            "sleep off",
            SimOptions {
                sleep: false,
                ..SimOptions::default()
            },
        ),
        (
            "shadow",
            SimOptions {
                sleep: false,
                shadow: true,
                ..SimOptions::default()
            },
        ),
        (
            "shuffle",
            SimOptions {
                shuffle_seed: Some(7),
                threads: 1,
                ..SimOptions::default()
            },
        ),
    ]
}

/// A cycle-mode frame with 8 KB segments on the given chip.
fn cycle_frame(
    s: &dualstream::scene::Scene,
    cfg: Config,
) -> Result<Frame, dualstream::render::RenderError> {
    render(
        s,
        Mode::Cycle,
        &rcfg(8, Some((cfg, SimOptions::default()))),
        &mut |_| {},
    )
}

fn gddr5_cfg(tms: u32, tps: u32) -> Config {
    let mut c = chip_cfg(tms, tps);
    c.chip.memory.model = dualstream::units::memory::MemoryModel::Gddr5;
    c.chip.memory.check_timing = true;
    c
}

fn sched_counter(o: &Outcome, name: &str) -> u64 {
    o.stats
        .iter()
        .find(|u| u.path == "chip.scheduler")
        .and_then(|u| u.counters.iter().find(|(n, _)| *n == name))
        .map(|(_, v)| *v)
        .unwrap()
}
