//! Memory statistics: per channel and per stream tag, and the report that sums
//! them (reads, writes, row hits / misses / conflicts, bandwidth, latency with
//! tail, queue occupancy, energy by component).

use std::fmt;

use super::StreamTag;
use super::energy::Energy;

/// Latency histogram in cycles with one-cycle bins up to `BINS`; longer latencies
/// land in the last bin (the exact maximum is kept separately).
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    bins: Vec<u64>,
    pub count: u64,
    pub sum: u64,
    pub max: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram {
            bins: vec![0; Histogram::BINS],
            count: 0,
            sum: 0,
            max: 0,
        }
    }
}

impl Histogram {
    pub const BINS: usize = 4096;
    #[inline]
    pub fn add(&mut self, v: u64) {
        self.bins[(v as usize).min(Histogram::BINS - 1)] += 1;
        self.count += 1;
        self.sum += v;
        self.max = self.max.max(v);
    }
    pub fn merge(&mut self, o: &Histogram) {
        for (a, b) in self.bins.iter_mut().zip(&o.bins) {
            *a += b;
        }
        self.count += o.count;
        self.sum += o.sum;
        self.max = self.max.max(o.max);
    }
    pub fn mean(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            self.sum as f64 / self.count as f64
        }
    }
    /// The smallest latency with at least `q` of the samples at or below it.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.count == 0 {
            return 0;
        }
        let want = ((self.count as f64) * q).ceil().max(1.0) as u64;
        let mut acc = 0;
        for (i, &n) in self.bins.iter().enumerate() {
            acc += n;
            if acc >= want {
                return if i == Histogram::BINS - 1 {
                    self.max
                } else {
                    i as u64
                };
            }
        }
        self.max
    }
}

/// Per stream tag.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TagStats {
    pub reads: u64,
    pub writes: u64,
    pub latency_sum: u64,
    pub latency_max: u64,
}

/// Counters of one channel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChannelStats {
    pub reads: u64,
    pub writes: u64,
    pub row_hits: u64,
    pub row_misses: u64,
    pub row_conflicts: u64,
    pub acts: u64,
    pub pres: u64,
    pub refs: u64,
    pub rd_bursts: u64,
    pub wr_bursts: u64,
    /// Read latency: acceptance to the end of the last data beat.
    pub read_latency: Histogram,
    pub write_latency: Histogram,
    pub per_tag: [TagStats; StreamTag::COUNT],
    /// Sum over cycles of the queue occupancies, and their maxima.
    pub rq_occupancy_sum: u64,
    pub wq_occupancy_sum: u64,
    pub rq_max: u32,
    pub wq_max: u32,
    /// Cycles with at least one bank open / all banks closed.
    pub active_cycles: u64,
    pub precharged_cycles: u64,
    /// Cycle up to which the integrals above are taken.
    pub until: u64,
    /// Requests whose address was outside the configuration (a requester bug).
    pub bad_addresses: u64,
    pub energy: Energy,
}

impl ChannelStats {
    pub fn merge(&mut self, o: &ChannelStats) {
        self.reads += o.reads;
        self.writes += o.writes;
        self.row_hits += o.row_hits;
        self.row_misses += o.row_misses;
        self.row_conflicts += o.row_conflicts;
        self.acts += o.acts;
        self.pres += o.pres;
        self.refs += o.refs;
        self.rd_bursts += o.rd_bursts;
        self.wr_bursts += o.wr_bursts;
        self.read_latency.merge(&o.read_latency);
        self.write_latency.merge(&o.write_latency);
        for (a, b) in self.per_tag.iter_mut().zip(&o.per_tag) {
            a.reads += b.reads;
            a.writes += b.writes;
            a.latency_sum += b.latency_sum;
            a.latency_max = a.latency_max.max(b.latency_max);
        }
        self.rq_occupancy_sum += o.rq_occupancy_sum;
        self.wq_occupancy_sum += o.wq_occupancy_sum;
        self.rq_max = self.rq_max.max(o.rq_max);
        self.wq_max = self.wq_max.max(o.wq_max);
        self.active_cycles += o.active_cycles;
        self.precharged_cycles += o.precharged_cycles;
        self.until = self.until.max(o.until);
        self.bad_addresses += o.bad_addresses;
        self.energy.add(&o.energy);
    }
    pub fn requests(&self) -> u64 {
        self.reads + self.writes
    }
    pub fn row_hit_rate(&self) -> f64 {
        row_hit_rate(self.row_hits, self.row_misses, self.row_conflicts)
    }
}

/// Row hits over all row outcomes (0 with none).
pub fn row_hit_rate(hits: u64, misses: u64, conflicts: u64) -> f64 {
    let n = hits + misses + conflicts;
    if n == 0 { 0.0 } else { hits as f64 / n as f64 }
}

/// A whole memory system's statistics over a run.
#[derive(Clone, Debug, PartialEq)]
pub struct MemReport {
    pub preset: String,
    pub energy_preset: String,
    pub tck_ps: u64,
    pub line_bytes: u32,
    /// Peak bytes per cycle of all channels together.
    pub peak_bytes_per_cycle: f64,
    /// Cycles from the start to the last completion.
    pub cycles: u64,
    pub channels: Vec<ChannelStats>,
    pub total: ChannelStats,
    /// Timing-checker result, if the command log was checked.
    pub violations: Option<Vec<String>>,
}

impl MemReport {
    pub fn new(
        preset: &str,
        energy_preset: &str,
        tck_ps: u64,
        line_bytes: u32,
        peak_bytes_per_cycle: f64,
        cycles: u64,
        channels: Vec<ChannelStats>,
    ) -> Self {
        let mut total = ChannelStats::default();
        for c in &channels {
            total.merge(c);
        }
        MemReport {
            preset: preset.into(),
            energy_preset: energy_preset.into(),
            tck_ps,
            line_bytes,
            peak_bytes_per_cycle,
            cycles,
            channels,
            total,
            violations: None,
        }
    }
    pub fn seconds(&self) -> f64 {
        self.cycles as f64 * self.tck_ps as f64 * 1e-12
    }
    pub fn bytes(&self) -> u64 {
        self.total.requests() * self.line_bytes as u64
    }
    /// Achieved bandwidth in GB/s (1e9 bytes per second).
    pub fn bandwidth_gbs(&self) -> f64 {
        let s = self.seconds();
        if s == 0.0 {
            0.0
        } else {
            self.bytes() as f64 / s / 1e9
        }
    }
    pub fn peak_gbs(&self) -> f64 {
        self.peak_bytes_per_cycle / (self.tck_ps as f64 * 1e-12) / 1e9
    }
    /// The same run priced with another energy configuration (the energy model
    /// is linear in the command and standby counts).
    pub fn with_energy(
        &self,
        e: &super::config::EnergyCfg,
        t: &super::config::TimingCfg,
        burst_cycles: u32,
    ) -> MemReport {
        let em = super::energy::EnergyModel::new(e, t, burst_cycles, self.tck_ps);
        let chans = self
            .channels
            .iter()
            .map(|c| {
                let mut c = c.clone();
                c.energy = super::energy::energy_of(&c, &em);
                c
            })
            .collect();
        let mut r = MemReport::new(
            &self.preset,
            &e.preset,
            self.tck_ps,
            self.line_bytes,
            self.peak_bytes_per_cycle,
            self.cycles,
            chans,
        );
        r.violations = self.violations.clone();
        r
    }

    /// Energy per line moved, in nJ.
    pub fn nj_per_line(&self) -> f64 {
        let n = self.total.requests();
        if n == 0 {
            0.0
        } else {
            self.total.energy.total() / n as f64 * 1e9
        }
    }
}

/// Joules with an SI prefix.
pub fn joules(j: f64) -> String {
    let a = j.abs();
    let (v, u) = if a >= 1.0 {
        (j, "J")
    } else if a >= 1e-3 {
        (j * 1e3, "mJ")
    } else if a >= 1e-6 {
        (j * 1e6, "uJ")
    } else {
        (j * 1e9, "nJ")
    };
    format!("{v:.3} {u}")
}

impl fmt::Display for MemReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = &self.total;
        let ns = self.tck_ps as f64 / 1000.0;
        writeln!(
            f,
            "memory: preset {}, energy preset {}, {} channel(s), tCK {} ps, {} B lines",
            self.preset,
            self.energy_preset,
            self.channels.len(),
            self.tck_ps,
            self.line_bytes
        )?;
        writeln!(
            f,
            "  requests {} (reads {}, writes {}) in {} cycles ({:.3} us)",
            t.requests(),
            t.reads,
            t.writes,
            self.cycles,
            self.seconds() * 1e6
        )?;
        writeln!(
            f,
            "  bandwidth {:.2} GB/s of {:.2} GB/s peak ({:.1}%)",
            self.bandwidth_gbs(),
            self.peak_gbs(),
            100.0 * self.bandwidth_gbs() / self.peak_gbs().max(1e-30)
        )?;
        writeln!(
            f,
            "  row hits {} misses {} conflicts {} (hit rate {:.1}%)",
            t.row_hits,
            t.row_misses,
            t.row_conflicts,
            100.0 * t.row_hit_rate()
        )?;
        writeln!(
            f,
            "  commands ACT {} PRE {} RD {} WR {} REF {}",
            t.acts, t.pres, t.rd_bursts, t.wr_bursts, t.refs
        )?;
        for (name, h) in [("read", &t.read_latency), ("write", &t.write_latency)] {
            if h.count > 0 {
                writeln!(
                    f,
                    "  {name} latency (cycles, accept to last data): avg {:.1} ({:.1} ns) p50 {} p99 {} max {}",
                    h.mean(),
                    h.mean() * ns,
                    h.quantile(0.5),
                    h.quantile(0.99),
                    h.max
                )?;
            }
        }
        let c = self.cycles.max(1) as f64 * self.channels.len().max(1) as f64;
        writeln!(
            f,
            "  queue occupancy per channel: read avg {:.1} max {}, write avg {:.1} max {}",
            t.rq_occupancy_sum as f64 / c,
            t.rq_max,
            t.wq_occupancy_sum as f64 / c,
            t.wq_max
        )?;
        writeln!(
            f,
            "  energy ({} preset): total {}, {:.2} nJ per {} B line, {:.2} W average",
            self.energy_preset,
            joules(t.energy.total()),
            self.nj_per_line(),
            self.line_bytes,
            t.energy.total() / self.seconds().max(1e-30)
        )?;
        for (k, v) in t.energy.components() {
            writeln!(
                f,
                "    {k:<18} {:>12} {:5.1}%",
                joules(v),
                100.0 * v / t.energy.total().max(1e-300)
            )?;
        }
        let tags: Vec<_> = StreamTag::ALL
            .iter()
            .zip(&t.per_tag)
            .filter(|(_, s)| s.reads + s.writes > 0)
            .collect();
        if !tags.is_empty() {
            writeln!(f, "  per stream: lines (reads/writes), avg latency")?;
            for (tag, s) in tags {
                let n = s.reads + s.writes;
                writeln!(
                    f,
                    "    {:<8} {} ({}/{}) avg {:.1} max {}",
                    tag.name(),
                    n,
                    s.reads,
                    s.writes,
                    s.latency_sum as f64 / n as f64,
                    s.latency_max
                )?;
            }
        }
        if self.channels.len() > 1 {
            writeln!(
                f,
                "  per channel: requests, row hit %, read avg latency, energy"
            )?;
            for (i, ch) in self.channels.iter().enumerate() {
                writeln!(
                    f,
                    "    ch{i:<3} {} {:.1}% {:.1} {}",
                    ch.requests(),
                    100.0 * ch.row_hit_rate(),
                    ch.read_latency.mean(),
                    joules(ch.energy.total())
                )?;
            }
        }
        if t.bad_addresses > 0 {
            writeln!(
                f,
                "  WARNING: {} requests had addresses outside the configuration",
                t.bad_addresses
            )?;
        }
        if let Some(v) = &self.violations {
            if v.is_empty() {
                writeln!(f, "  timing checker: 0 violations")?;
            } else {
                writeln!(f, "  timing checker: {} violations, first:", v.len())?;
                for x in v.iter().take(10) {
                    writeln!(f, "    {x}")?;
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_quantiles() {
        let mut h = Histogram::default();
        for v in 1..=100 {
            h.add(v);
        }
        h.add(100_000);
        assert_eq!(h.quantile(0.5), 51);
        assert_eq!(h.quantile(1.0), 100_000);
        assert_eq!(h.max, 100_000);
        assert!((h.mean() - (5050.0 + 100_000.0) / 101.0).abs() < 1e-9);
    }
}
