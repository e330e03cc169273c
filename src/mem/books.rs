//! What every channel controller keeps besides its scheduling: the statistics,
//! the command log, the energy model and the integrals of queue occupancy and
//! background (standby) time. The FR-FCFS controller (`ctrl.rs`) and the
//! DRAMsim3-rule one (`dramsim3.rs`) share it.

use super::config::MemCfg;
use super::energy::EnergyModel;
use super::stats::ChannelStats;
use super::timing::{Command, DramCmd};

#[derive(Clone, Debug)]
pub(crate) struct Books {
    pub log: Option<Vec<Command>>,
    pub stats: ChannelStats,
    em: EnergyModel,
    occ_since: u64,
    bg_since: u64,
    banks_per_group: u32,
}

impl Books {
    pub fn new(cfg: &MemCfg, tck_ps: u64) -> Books {
        let g = &cfg.geometry;
        Books {
            log: None,
            stats: ChannelStats::default(),
            em: EnergyModel::new(&cfg.energy, &cfg.timing, g.burst_cycles(), tck_ps),
            occ_since: 0,
            bg_since: 0,
            banks_per_group: g.banks_per_group,
        }
    }

    /// Queue occupancy up to cycle `c`, `reads` and `writes` held since the last call.
    pub fn occupancy(&mut self, c: u64, reads: usize, writes: usize) {
        if c > self.occ_since {
            let d = c - self.occ_since;
            self.stats.rq_occupancy_sum += reads as u64 * d;
            self.stats.wq_occupancy_sum += writes as u64 * d;
            self.occ_since = c;
        }
    }

    /// Background (standby) time up to cycle `c`, with a bank open (`active`) or
    /// all precharged since the last call.
    pub fn background(&mut self, c: u64, active: bool) {
        if c > self.bg_since {
            let d = c - self.bg_since;
            if active {
                self.stats.active_cycles += d;
            } else {
                self.stats.precharged_cycles += d;
            }
            self.bg_since = c;
        }
    }

    /// Logs and counts a command issued in cycle `c`; returns it.
    pub fn issued(&mut self, c: u64, kind: DramCmd, bank: u32, row: u32, column: u32) -> Command {
        let cmd = Command {
            cycle: c,
            kind,
            bank_group: bank / self.banks_per_group,
            bank,
            row,
            column,
        };
        if let Some(l) = &mut self.log {
            l.push(cmd);
        }
        let s = &mut self.stats;
        match kind {
            DramCmd::Act => s.acts += 1,
            DramCmd::Pre => s.pres += 1,
            DramCmd::Rd => s.rd_bursts += 1,
            DramCmd::Wr => s.wr_bursts += 1,
            DramCmd::Ref => s.refs += 1,
            DramCmd::Nop => {}
        }
        cmd
    }

    /// The statistics up to `end` with the integrals closed there and the energy
    /// charged (`reads`, `writes` held and `active` banks since the last calls).
    pub fn stats_at(mut self, end: u64, reads: usize, writes: usize, active: bool) -> ChannelStats {
        self.occupancy(end, reads, writes);
        self.background(end, active);
        let mut s = self.stats;
        s.until = end;
        s.energy = super::energy::energy_of(&s, &self.em);
        s
    }
}
