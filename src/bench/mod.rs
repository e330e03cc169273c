//! Kernel benchmarks (`dualstream bench kernel`): how fast the simulator runs the
//! shared pipelines of many TMs. Measurements, not tests: the numbers go in reports.
//! `threads`: the lane counts of `--threads` against each other.

pub mod threads;
pub mod trace;

use std::time::Instant;

use glam::Vec3;

use crate::config::Config;
use crate::rtl::{ClockId, Sim, SimOptions, TraceSpec, Tracer};
use crate::testbench::{LoadGen, Sink};
use crate::units::box_pipe::{BoxPipe, BoxPipePorts, BoxReq};
use crate::units::divider::{DivReq, Divider, DividerPorts};
use crate::units::tri_pipe::{TriPipe, TriPipePorts, TriReq};
use crate::util::rng::Rng;

fn box_pool(rng: &mut Rng) -> Vec<BoxReq> {
    (0..64)
        .map(|i| {
            let o = Vec3::new(rng.range_f32(-5.0, 5.0), rng.range_f32(-5.0, 5.0), -10.0);
            BoxReq {
                origin: o,
                inv_dir: crate::geom::inverse_dir(Vec3::new(0.01, 0.02, 1.0)),
                t_min: 0.0,
                t_max: f32::INFINITY,
                bmin: Vec3::splat(-1.0),
                bmax: Vec3::splat(1.0),
                tag: i,
            }
        })
        .collect()
}

fn tri_pool(rng: &mut Rng) -> Vec<TriReq> {
    (0..64)
        .map(|i| TriReq {
            origin: Vec3::new(rng.range_f32(-1.0, 1.0), rng.range_f32(-1.0, 1.0), -3.0),
            dir: Vec3::Z,
            t_min: 0.0,
            t_max: f32::INFINITY,
            v0: Vec3::new(-1.0, -1.0, 0.0),
            v1: Vec3::new(1.0, -1.0, 0.0),
            v2: Vec3::new(0.0, 1.0, 0.0),
            tri_id: i as u32,
            tag: i,
        })
        .collect()
}

fn div_pool(rng: &mut Rng) -> Vec<DivReq> {
    (0..64)
        .map(|i| DivReq {
            dir: Vec3::new(rng.unit_f32(), rng.unit_f32(), 0.5),
            tag: i,
        })
        .collect()
}

/// Builds `tms` TMs, each with one box pipeline, two triangle pipelines and one
/// divider, each fed by a load generator of the given activity and drained by an
/// always-ready sink.
pub fn build_tms(tms: u32, activity: f64, opts: SimOptions, cfg: &Config) -> (Sim, ClockId) {
    let mut sim = Sim::new(opts);
    let clk = sim.clock("core", cfg.clocks.core_ps).expect("validated");
    let l = cfg.links.tm;
    let mut rng = Rng::new(7);
    let (bp, tp, dp) = (box_pool(&mut rng), tri_pool(&mut rng), div_pool(&mut rng));
    for t in 0..tms {
        let s = |n: &str| format!("chip.tm{t}.{n}");
        let seed = t as u64 * 16;
        let (o, i) = sim.link(&s("box_req"), l);
        let (ro, ri) = sim.link(&s("box_resp"), l);
        sim.add(
            &s("box_load"),
            clk,
            LoadGen::new(o, bp.clone(), activity, seed, u64::MAX),
        );
        sim.add(
            &s("box_pipe"),
            clk,
            BoxPipe::new(&cfg.box_pipe, l.delay, BoxPipePorts { req: i, resp: ro }),
        );
        sim.add(&s("box_sink"), clk, Sink::new(ri, 1.0, 0));
        for k in 0..2 {
            let (o, i) = sim.link(&s(&format!("tri{k}_req")), l);
            let (ro, ri) = sim.link(&s(&format!("tri{k}_resp")), l);
            sim.add(
                &s(&format!("tri_load{k}")),
                clk,
                LoadGen::new(o, tp.clone(), activity, seed + 1 + k, u64::MAX),
            );
            sim.add(
                &s(&format!("tri_pipe{k}")),
                clk,
                TriPipe::new(&cfg.tri_pipe, l.delay, TriPipePorts { req: i, resp: ro }),
            );
            sim.add(&s(&format!("tri_sink{k}")), clk, Sink::new(ri, 1.0, 0));
        }
        let (o, i) = sim.link(&s("div_req"), l);
        let (ro, ri) = sim.link(&s("div_resp"), l);
        sim.add(
            &s("div_load"),
            clk,
            LoadGen::new(o, dp.clone(), activity, seed + 3, u64::MAX),
        );
        sim.add(
            &s("divider"),
            clk,
            Divider::new(&cfg.divider, l.delay, DividerPorts { req: i, resp: ro }),
        );
        sim.add(&s("div_sink"), clk, Sink::new(ri, 1.0, 0));
    }
    sim.elaborate().expect("well-formed");
    (sim, clk)
}

pub struct Measure {
    pub label: String,
    pub cycles: u64,
    pub seconds: f64,
    pub evals: u64,
    pub vcd_changes: u64,
    pub vcd_bytes: u64,
}

impl Measure {
    pub fn cycles_per_s(&self) -> f64 {
        self.cycles as f64 / self.seconds
    }
    pub fn evals_per_s(&self) -> f64 {
        self.evals as f64 / self.seconds
    }
}

/// Runs `cycles` cycles of `tms` TMs at `activity`, optionally tracing `trace`.
pub fn measure(label: &str, tms: u32, activity: f64, cycles: u64, trace: Option<&str>) -> Measure {
    let cfg = Config::default();
    let (mut sim, clk) = build_tms(tms, activity, SimOptions::default(), &cfg);
    let path = std::env::temp_dir().join(format!("dualstream-bench-{}.vcd", std::process::id()));
    if let Some(f) = trace {
        // A measurement of the tracer's speed: no size guard.
        let spec = TraceSpec {
            filter: f.to_string(),
            from: 0,
            to: u64::MAX,
            max_bytes: 0,
            every_edge: false,
            show: Default::default(),
            cycles_of: None,
        };
        sim.attach_tracer(Tracer::to_file(&path, spec).expect("temp file"))
            .expect("filter matches");
    }
    let start = Instant::now();
    sim.run_cycles(clk, cycles).expect("runs clean");
    let (mut ch, mut by) = (0, 0);
    if let Some(r) = sim.finish_trace() {
        let st = r.expect("trace written");
        (ch, by) = (st.changes, st.bytes);
    }
    let seconds = start.elapsed().as_secs_f64();
    let _ = std::fs::remove_file(&path);
    // Sinks and load generators are testbench units; count only the pipelines'
    // share of evaluations for "unit evaluations" of busy pipelines.
    Measure {
        label: label.into(),
        cycles,
        seconds,
        evals: sim.evals,
        vcd_changes: ch,
        vcd_bytes: by,
    }
}

/// The kernel benchmark report.
pub fn kernel_report(scale: f64) -> String {
    let c = |n: f64| ((n * scale) as u64).max(100);
    let mut out = String::new();
    let mut line = |m: &Measure, extra: String| {
        out.push_str(&format!(
            "{:<44} {:>9} cycles {:>8.3} s {:>11.0} cycles/s {:>12.0} evals/s{}\n",
            m.label,
            m.cycles,
            m.seconds,
            m.cycles_per_s(),
            m.evals_per_s(),
            extra
        ));
    };
    let busy = measure(
        "1 TM, 4 pipelines at 100% (busy units)",
        1,
        1.0,
        c(200_000.0),
        None,
    );
    line(&busy, String::new());
    let mut chip = Vec::new();
    for (a, n) in [(1.0, 5_000.0), (0.1, 20_000.0), (0.01, 100_000.0)] {
        let m = measure(
            &format!("128 TMs x (box + 2 tri + div) at {:>3}%", a * 100.0),
            128,
            a,
            c(n),
            None,
        );
        line(&m, String::new());
        chip.push(m);
    }
    let traced = measure(
        "128 TMs at 10%, one box pipe traced",
        128,
        0.1,
        c(20_000.0),
        Some("chip.tm0.box_pipe"),
    );
    let slow = chip[1].cycles_per_s() / traced.cycles_per_s();
    line(&traced, format!("  slowdown x{slow:.2}"));
    let full = measure(
        "1 TM at 100%, every unit traced",
        1,
        1.0,
        c(50_000.0),
        Some(""),
    );
    let s = full.seconds;
    line(
        &full,
        format!(
            "  {:.2} M changes/s, {:.0} bytes/cycle",
            full.vcd_changes as f64 / s / 1e6,
            full.vcd_bytes as f64 / full.cycles as f64
        ),
    );
    out
}
