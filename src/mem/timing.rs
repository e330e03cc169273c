//! The scheduler's view of DRAM timing: for one channel, the earliest cycle at
//! which each command may issue to each bank. Every issued command pushes the
//! earliest times of the commands it constrains forward (bank, bank group and
//! channel level, and the four- and 32-activate windows), so asking "when can this
//! command go?" is a handful of `max`es and the controller can sleep until then.
//!
//! The independent check of the same rules over a command log is `checker.rs`,
//! written as pairwise rules so that a mistake here is not repeated there.

use super::config::{GeometryCfg, TimingCfg};

crate::fsm_states! {
    /// A DRAM command (the controller's command-bus output; `Nop` when idle).
    pub enum DramCmd { Nop, Act, Rd, Wr, Pre, Ref }
}

/// One issued command, as the timing checker and the statistics see it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Command {
    pub cycle: u64,
    pub kind: DramCmd,
    pub bank_group: u32,
    /// Flat bank index within the channel.
    pub bank: u32,
    pub row: u32,
    /// Burst index within the row (column commands).
    pub column: u32,
}

#[derive(Clone, Debug, Default)]
struct Bank {
    open: Option<u32>,
    next_act: u64,
    next_rd: u64,
    next_wr: u64,
    next_pre: u64,
}

/// Timing state of one channel (a single rank).
#[derive(Clone, Debug)]
pub struct ChannelTiming {
    t: TimingCfg,
    burst: u64,
    banks_per_group: u32,
    /// log2(banks_per_group): the bank group of a flat bank is a shift away.
    group_shift: u32,
    banks: Vec<Bank>,
    bg_act: Vec<u64>,
    bg_rd: Vec<u64>,
    bg_wr: Vec<u64>,
    ch_act: u64,
    ch_rd: u64,
    ch_wr: u64,
    ch_pre: u64,
    ch_ref: u64,
    /// Cycles of the last 32 ACTs (ring), for tFAW and t32AW.
    acts: [u64; 32],
    n_acts: u64,
    open_banks: u32,
}

impl ChannelTiming {
    pub fn new(t: &TimingCfg, g: &GeometryCfg) -> Self {
        let nb = g.banks() as usize;
        let ng = g.bank_groups as usize;
        ChannelTiming {
            t: t.clone(),
            burst: g.burst_cycles() as u64,
            banks_per_group: g.banks_per_group,
            group_shift: g.banks_per_group.trailing_zeros(),
            banks: vec![Bank::default(); nb],
            bg_act: vec![0; ng],
            bg_rd: vec![0; ng],
            bg_wr: vec![0; ng],
            ch_act: 0,
            ch_rd: 0,
            ch_wr: 0,
            ch_pre: 0,
            ch_ref: 0,
            acts: [0; 32],
            n_acts: 0,
            open_banks: 0,
        }
    }

    pub fn open_row(&self, bank: u32) -> Option<u32> {
        self.banks[bank as usize].open
    }
    pub fn open_banks(&self) -> u32 {
        self.open_banks
    }
    #[inline]
    fn group(&self, bank: u32) -> usize {
        (bank >> self.group_shift) as usize
    }
    pub fn banks_per_group(&self) -> u32 {
        self.banks_per_group
    }

    /// Earliest cycle for an ACT to a (closed) bank.
    #[inline]
    pub fn earliest_act(&self, bank: u32) -> u64 {
        self.earliest_act_after(bank, self.act_floor())
    }
    /// The channel-level part of `earliest_act` (tRRD_S, tFAW, t32AW), the same
    /// for every bank: ask once per decision.
    #[inline]
    pub fn act_floor(&self) -> u64 {
        let mut e = self.ch_act;
        if self.t.faw > 0 && self.n_acts >= 4 {
            e = e.max(self.acts[((self.n_acts - 4) % 32) as usize] + self.t.faw as u64);
        }
        if self.t.t32aw > 0 && self.n_acts >= 32 {
            e = e.max(self.acts[(self.n_acts % 32) as usize] + self.t.t32aw as u64);
        }
        e
    }
    /// `earliest_act` given `floor = act_floor()`.
    #[inline]
    pub fn earliest_act_after(&self, bank: u32, floor: u64) -> u64 {
        self.banks[bank as usize]
            .next_act
            .max(self.bg_act[self.group(bank)])
            .max(floor)
    }
    /// Earliest cycle for a RD (`write` false) or WR to the open row of a bank.
    #[inline]
    pub fn earliest_col(&self, bank: u32, write: bool) -> u64 {
        let b = &self.banks[bank as usize];
        let g = self.group(bank);
        if write {
            b.next_wr.max(self.bg_wr[g]).max(self.ch_wr)
        } else {
            b.next_rd.max(self.bg_rd[g]).max(self.ch_rd)
        }
    }
    #[inline]
    pub fn earliest_pre(&self, bank: u32) -> u64 {
        self.banks[bank as usize].next_pre.max(self.ch_pre)
    }
    /// Earliest cycle for an all-bank REF (every bank must be closed).
    pub fn earliest_ref(&self) -> u64 {
        self.banks
            .iter()
            .map(|b| b.next_act)
            .max()
            .unwrap_or(0)
            .max(self.ch_ref)
    }

    /// Records a command issued at cycle `c` and moves every constraint it sets.
    pub fn issue(&mut self, c: u64, kind: DramCmd, bank: u32, row: u32) {
        let t = &self.t;
        let g = self.group(bank);
        let burst = self.burst;
        let up = |x: &mut u64, v: u64| *x = (*x).max(v);
        match kind {
            DramCmd::Act => {
                let b = &mut self.banks[bank as usize];
                debug_assert!(b.open.is_none(), "ACT to an open bank");
                b.open = Some(row);
                up(&mut b.next_rd, c + t.rcd_rd as u64);
                up(&mut b.next_wr, c + t.rcd_wr as u64);
                up(&mut b.next_pre, c + t.ras as u64);
                up(&mut b.next_act, c + t.rc as u64);
                up(&mut self.bg_act[g], c + t.rrd_l as u64);
                up(&mut self.ch_act, c + t.rrd_s as u64);
                self.acts[(self.n_acts % 32) as usize] = c;
                self.n_acts += 1;
                self.open_banks += 1;
            }
            DramCmd::Rd => {
                up(&mut self.banks[bank as usize].next_pre, c + t.rtp as u64);
                up(&mut self.bg_rd[g], c + (t.ccd_l as u64).max(burst));
                up(&mut self.ch_rd, c + (t.ccd_s as u64).max(burst));
                // Read data must leave the bus before write data arrives.
                let rtw = (c + t.cl as u64 + burst + t.rtrs as u64).saturating_sub(t.cwl as u64);
                up(&mut self.ch_wr, rtw);
            }
            DramCmd::Wr => {
                let data_end = c + t.cwl as u64 + burst;
                up(
                    &mut self.banks[bank as usize].next_pre,
                    data_end + t.wr as u64,
                );
                up(&mut self.bg_wr[g], c + (t.ccd_l as u64).max(burst));
                up(&mut self.ch_wr, c + (t.ccd_s as u64).max(burst));
                up(&mut self.bg_rd[g], data_end + t.wtr_l as u64);
                up(&mut self.ch_rd, data_end + t.wtr_s as u64);
            }
            DramCmd::Pre => {
                let b = &mut self.banks[bank as usize];
                debug_assert!(b.open.is_some(), "PRE to a closed bank");
                b.open = None;
                up(&mut b.next_act, c + t.rp as u64);
                up(&mut self.ch_pre, c + t.ppd as u64);
                up(&mut self.ch_ref, c + t.rp as u64);
                self.open_banks -= 1;
            }
            DramCmd::Ref => {
                debug_assert_eq!(self.open_banks, 0, "REF with a bank open");
                let done = c + t.rfc as u64;
                for b in &mut self.banks {
                    up(&mut b.next_act, done);
                }
                up(&mut self.ch_ref, done);
            }
            DramCmd::Nop => {}
        }
    }
}
