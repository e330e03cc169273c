//! DRAM energy after the Micron power equations (TN-41-01) as USIMM and DRAMsim3
//! apply them (hardware reference §3.2). Currents in mA x volts x cycles x tCK in
//! ns gives pJ; every figure is per device and multiplied by the devices charged
//! per channel (`mem.energy.devices_per_channel`, the difference between the
//! `paper` and `physical` presets).

use super::config::{EnergyCfg, TimingCfg};

/// Per-event energies of one channel, in picojoules.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyModel {
    pub preset: String,
    /// One ACT and its PRE: VDD (IDD0 tRC - (IDD3N tRAS + IDD2N tRP)).
    pub act_pre_pj: f64,
    /// One read burst: VDD (IDD4R - IDD3N) x burst cycles.
    pub rd_burst_pj: f64,
    /// One write burst: VDD (IDD4W - IDD3N) x burst cycles.
    pub wr_burst_pj: f64,
    /// Read I/O during one burst.
    pub rd_io_pj: f64,
    /// One all-bank REF: VDD (IDD5 - IDD3N) tRFC.
    pub ref_pj: f64,
    /// Background per cycle with any bank open (IDD3N) or all closed (IDD2N).
    pub act_stby_pj: f64,
    pub pre_stby_pj: f64,
}

impl EnergyModel {
    pub fn new(e: &EnergyCfg, t: &TimingCfg, burst_cycles: u32, tck_ps: u64) -> Self {
        let ns = tck_ps as f64 / 1000.0;
        let d = e.devices_per_channel;
        let cyc = |x: u32| x as f64 * ns;
        EnergyModel {
            preset: e.preset.clone(),
            act_pre_pj: e.vdd
                * (e.idd0 * cyc(t.rc) - (e.idd3n * cyc(t.ras) + e.idd2n * cyc(t.rp)))
                * d,
            rd_burst_pj: e.vdd * (e.idd4r - e.idd3n) * cyc(burst_cycles) * d,
            wr_burst_pj: e.vdd * (e.idd4w - e.idd3n) * cyc(burst_cycles) * d,
            rd_io_pj: e.read_io_mw * cyc(burst_cycles) * d,
            ref_pj: e.vdd * (e.idd5 - e.idd3n) * cyc(t.rfc) * d,
            act_stby_pj: e.vdd * e.idd3n * ns * d,
            pre_stby_pj: e.vdd * e.idd2n * ns * d,
        }
    }
}

/// Energy of a channel's activity: commands and standby cycles times the
/// per-event energies (the model is linear, so any preset can be applied to the
/// same counts).
pub fn energy_of(s: &super::stats::ChannelStats, em: &EnergyModel) -> Energy {
    let j = |n: u64, pj: f64| n as f64 * pj * 1e-12;
    Energy {
        act_pre: j(s.acts, em.act_pre_pj),
        read: j(s.rd_bursts, em.rd_burst_pj),
        write: j(s.wr_bursts, em.wr_burst_pj),
        read_io: j(s.rd_bursts, em.rd_io_pj),
        refresh: j(s.refs, em.ref_pj),
        active_standby: j(s.active_cycles, em.act_stby_pj),
        precharge_standby: j(s.precharged_cycles, em.pre_stby_pj),
    }
}

/// Energy by component, in joules.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Energy {
    pub act_pre: f64,
    pub read: f64,
    pub write: f64,
    pub read_io: f64,
    pub refresh: f64,
    pub active_standby: f64,
    pub precharge_standby: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.act_pre
            + self.read
            + self.write
            + self.read_io
            + self.refresh
            + self.active_standby
            + self.precharge_standby
    }
    pub fn add(&mut self, o: &Energy) {
        self.act_pre += o.act_pre;
        self.read += o.read;
        self.write += o.write;
        self.read_io += o.read_io;
        self.refresh += o.refresh;
        self.active_standby += o.active_standby;
        self.precharge_standby += o.precharge_standby;
    }
    pub fn components(&self) -> [(&'static str, f64); 7] {
        [
            ("act_pre", self.act_pre),
            ("read", self.read),
            ("write", self.write),
            ("read_io", self.read_io),
            ("refresh", self.refresh),
            ("active_standby", self.active_standby),
            ("precharge_standby", self.precharge_standby),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mem::config::{GeometryCfg, MemCfg};

    #[test]
    fn paper_preset_matches_the_reference_sheet() {
        // HWREF §3.3: USIMM set A, per device, tCK 0.5 ns: 549 pJ array + 64 pJ
        // DQ per 64 B line (two bursts here), 31.8 nJ per REF at tRFC 220 (ours
        // is tRFC 74, so 74/220 of it).
        let m = MemCfg::paper();
        let mut e = m.energy.clone();
        e.devices_per_channel = 1.0;
        let em = EnergyModel::new(&e, &m.timing, m.geometry.burst_cycles(), 500);
        assert!((2.0 * em.rd_burst_pj - 549.0).abs() < 1.0, "{em:?}");
        assert!((2.0 * em.rd_io_pj - 64.0).abs() < 1.0);
        assert!((em.ref_pj - 31_845.0 * 74.0 / 220.0).abs() < 50.0);
        // Physical is 8x less than paper on a 32-bit channel.
        let g = GeometryCfg::default();
        let p = EnergyModel::new(&EnergyCfg::physical(&g), &m.timing, 2, 500);
        let q = EnergyModel::new(&EnergyCfg::paper(), &m.timing, 2, 500);
        assert!((q.act_pre_pj / p.act_pre_pj - 8.0).abs() < 1e-9);
    }
}
