//! `dualstream bench dram`: simulated requests per wall second of the trace
//! replay on random and streaming traces, with bandwidth, row-hit rate, latency
//! and energy per line. Measurements, not tests.

use std::time::Instant;

use super::MemError;
use super::config::{EnergyCfg, MemCfg};
use super::replay::{ReplayOptions, replay};
use super::trace::generate;

/// One replay measured.
pub struct BenchRow {
    pub preset: &'static str,
    pub kind: &'static str,
    pub requests: u64,
    pub seconds: f64,
    pub report: super::MemReport,
    /// nJ per line under each energy preset.
    pub nj_per_line: Vec<(String, f64)>,
}

pub fn run(scale: f64) -> Result<Vec<BenchRow>, MemError> {
    let n = ((1_000_000.0 * scale) as u64).max(1000);
    let mut rows = Vec::new();
    for preset in ["dramsim3-gddr5", "paper"] {
        let (m, tck) = MemCfg::preset(preset)?;
        for kind in ["random", "stream"] {
            let reqs = generate(kind, n, 42, &m, 0, 0.0)?;
            let opts = ReplayOptions {
                check: false,
                preset: preset.into(),
                ..ReplayOptions::default()
            };
            let t0 = Instant::now();
            let r = replay(&m, tck, &reqs, &opts)?;
            let seconds = t0.elapsed().as_secs_f64();
            let mut nj = Vec::new();
            for e in EnergyCfg::PRESETS {
                let ec = EnergyCfg::by_name(e, &m.geometry)?;
                let rr = r
                    .report
                    .with_energy(&ec, &m.timing, m.geometry.burst_cycles());
                nj.push((e.to_string(), rr.nj_per_line()));
            }
            rows.push(BenchRow {
                preset: if preset == "paper" {
                    "paper"
                } else {
                    "dramsim3-gddr5"
                },
                kind: if kind == "random" { "random" } else { "stream" },
                requests: n,
                seconds,
                report: r.report,
                nj_per_line: nj,
            });
        }
    }
    Ok(rows)
}

pub fn report(scale: f64) -> Result<String, MemError> {
    use std::fmt::Write;
    let rows = run(scale)?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "dram replay benchmark (release build recommended; unthrottled traces, reads only, in-order issue of one request per DRAM cycle as DRAMsim3's trace CPU)"
    );
    for r in &rows {
        let rep = &r.report;
        let _ = writeln!(
            s,
            "{:<15} {:<7} {} requests in {:.3} s = {:.0} requests/s; {:.1} GB/s ({:.1}% of {:.0} GB/s peak), row hits {:.1}%, read latency avg {:.1} cycles ({:.1} ns) p99 {}",
            r.preset,
            r.kind,
            r.requests,
            r.seconds,
            r.requests as f64 / r.seconds,
            rep.bandwidth_gbs(),
            100.0 * rep.bandwidth_gbs() / rep.peak_gbs(),
            rep.peak_gbs(),
            100.0 * rep.total.row_hit_rate(),
            rep.total.read_latency.mean(),
            rep.total.read_latency.mean() * rep.tck_ps as f64 / 1000.0,
            rep.total.read_latency.quantile(0.99),
        );
        let e: Vec<String> = r
            .nj_per_line
            .iter()
            .map(|(k, v)| format!("{k} {v:.2}"))
            .collect();
        let _ = writeln!(
            s,
            "{:<15} {:<7} energy per {} B line (nJ): {}",
            "",
            "",
            rep.line_bytes,
            e.join(", ")
        );
    }
    Ok(s)
}
