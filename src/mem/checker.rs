//! An independent DRAM timing checker. It reads only a recorded command log and
//! the configuration, and shares no code with the scheduler (`timing.rs` keeps
//! "earliest next time" registers; this file states each constraint as a rule on
//! a pair of commands, plus the bank state machine, the activate windows, data-bus
//! overlap and the refresh rate), so a mistake in one is unlikely to hide in both.

use std::collections::VecDeque;

use super::config::{GeometryCfg, TimingCfg};
use super::timing::{Command, DramCmd};

/// Minimum distance from `a` (earlier) to `b` required by one rule, with its name.
fn pair_rule(a: &Command, b: &Command, t: &TimingCfg, burst: u64) -> Option<(u64, &'static str)> {
    use DramCmd::*;
    let same_bank = a.bank == b.bank;
    let same_bg = a.bank_group == b.bank_group;
    let u = |x: u32| x as u64;
    let r = match (a.kind, b.kind) {
        (Act, Act) if same_bank => (u(t.rc), "tRC"),
        (Act, Act) if same_bg => (u(t.rrd_l), "tRRD_L"),
        (Act, Act) => (u(t.rrd_s), "tRRD_S"),
        (Act, Rd) if same_bank => (u(t.rcd_rd), "tRCDRD"),
        (Act, Wr) if same_bank => (u(t.rcd_wr), "tRCDWR"),
        (Act, Pre) if same_bank => (u(t.ras), "tRAS"),
        (Pre, Act) if same_bank => (u(t.rp), "tRP"),
        (Pre, Pre) if t.ppd > 0 => (u(t.ppd), "tPPD"),
        (Pre, Ref) => (u(t.rp), "tRP before REF"),
        (Rd, Rd) | (Wr, Wr) if same_bg => (u(t.ccd_l).max(burst), "tCCD_L"),
        (Rd, Rd) | (Wr, Wr) => (u(t.ccd_s).max(burst), "tCCD_S"),
        (Rd, Wr) => (
            (u(t.cl) + burst + u(t.rtrs)).saturating_sub(u(t.cwl)),
            "read-to-write turnaround",
        ),
        (Wr, Rd) if same_bg => (u(t.cwl) + burst + u(t.wtr_l), "tWTR_L"),
        (Wr, Rd) => (u(t.cwl) + burst + u(t.wtr_s), "tWTR_S"),
        (Rd, Pre) if same_bank => (u(t.rtp), "tRTP"),
        (Wr, Pre) if same_bank => (u(t.cwl) + burst + u(t.wr), "tWR"),
        (Ref, Act) | (Ref, Ref) => (u(t.rfc), "tRFC"),
        _ => return None,
    };
    Some(r)
}

/// Data-bus interval of a column command: [start, end).
fn data_window(c: &Command, t: &TimingCfg, burst: u64) -> Option<(u64, u64)> {
    let lat = match c.kind {
        DramCmd::Rd => t.cl,
        DramCmd::Wr => t.cwl,
        _ => return None,
    } as u64;
    Some((c.cycle + lat, c.cycle + lat + burst))
}

/// Records a violation by command `c` (the first 1000).
fn say(out: &mut Vec<String>, c: &Command, what: String) {
    if out.len() < 1000 {
        out.push(format!(
            "cycle {} {:?} bank {} (group {}) row {}: {what}",
            c.cycle, c.kind, c.bank, c.bank_group, c.row
        ));
    }
}

/// What the checker remembers while it reads a log.
struct Checker<'a> {
    t: &'a TimingCfg,
    g: &'a GeometryCfg,
    burst: u64,
    /// How far back a pairwise rule can reach (cycles).
    window: u64,
    out: Vec<String>,
    /// The commands within `window` of the current one.
    recent: VecDeque<Command>,
    /// Per bank: the open row.
    open: Vec<Option<u32>>,
    /// The last 33 ACTs' cycles, and every REF's.
    acts: VecDeque<u64>,
    refs: Vec<u64>,
    last_cycle: Option<u64>,
}

impl<'a> Checker<'a> {
    fn new(t: &'a TimingCfg, g: &'a GeometryCfg) -> Self {
        let burst = (g.burst_length / g.transfers_per_ck) as u64;
        let window = [
            t.rc, t.rfc, t.ras, t.faw, t.t32aw, t.cl, t.cwl, t.rcd_rd, t.rcd_wr,
        ]
        .iter()
        .map(|&x| x as u64)
        .max()
        .unwrap_or(0)
            + t.wr as u64
            + t.wtr_l as u64
            + burst
            + t.cl as u64
            + 8;
        Checker {
            t,
            g,
            burst,
            window,
            out: Vec::new(),
            recent: VecDeque::new(),
            open: vec![None; g.banks() as usize],
            acts: VecDeque::new(),
            refs: Vec::new(),
            last_cycle: None,
        }
    }

    /// One command bus: one command per cycle, in time order.
    fn bus_order(&mut self, c: &Command) {
        if let Some(l) = self.last_cycle {
            if c.cycle == l {
                say(
                    &mut self.out,
                    c,
                    "two commands in one cycle (one command bus)".into(),
                );
            } else if c.cycle < l {
                say(&mut self.out, c, "log is not in time order".into());
            }
        }
        self.last_cycle = Some(c.cycle);
    }

    /// Bank, bank group, row and column within the geometry.
    fn in_range(&mut self, c: &Command) {
        let g = self.g;
        if c.bank >= g.banks()
            || c.bank_group != c.bank / g.banks_per_group
            || c.row >= g.rows
            || c.column >= g.columns
        {
            say(
                &mut self.out,
                c,
                "bank, group, row or column out of range".into(),
            );
        }
    }

    /// The bank state machine: ACT to a closed bank, column commands to the
    /// open row, PRE to an open bank, REF with every bank closed.
    fn bank_state(&mut self, c: &Command) {
        let (out, open) = (&mut self.out, &mut self.open);
        let b = (c.bank as usize).min(open.len() - 1);
        match c.kind {
            DramCmd::Act => {
                if open[b].is_some() {
                    say(out, c, "ACT to a bank that is already open".into());
                }
                open[b] = Some(c.row);
            }
            DramCmd::Rd | DramCmd::Wr => {
                if open[b] != Some(c.row) {
                    say(
                        out,
                        c,
                        format!("column command but the bank has row {:?} open", open[b]),
                    );
                }
            }
            DramCmd::Pre => {
                if open[b].is_none() {
                    say(out, c, "PRE to a closed bank".into());
                }
                open[b] = None;
            }
            DramCmd::Ref => {
                if open.iter().any(|o| o.is_some()) {
                    say(out, c, "REF while a bank is open".into());
                }
                self.refs.push(c.cycle);
            }
            DramCmd::Nop => {}
        }
    }

    /// Pairwise rules and data-bus overlap against the recent commands.
    fn pair_rules(&mut self, c: &Command) {
        let (t, burst) = (self.t, self.burst);
        while self
            .recent
            .front()
            .is_some_and(|p| p.cycle + self.window < c.cycle)
        {
            self.recent.pop_front();
        }
        for p in &self.recent {
            if let Some((gap, name)) = pair_rule(p, c, t, burst)
                && c.cycle < p.cycle + gap
            {
                say(
                    &mut self.out,
                    c,
                    format!(
                        "{name}: {} cycles after {:?} at {} (bank {}), needs {gap}",
                        c.cycle - p.cycle,
                        p.kind,
                        p.cycle,
                        p.bank
                    ),
                );
            }
            if let (Some((s0, e0)), Some((s1, e1))) =
                (data_window(p, t, burst), data_window(c, t, burst))
                && s0 < e1
                && s1 < e0
            {
                say(
                    &mut self.out,
                    c,
                    format!("data bus overlap with {:?} at {}", p.kind, p.cycle),
                );
            }
        }
        self.recent.push_back(*c);
    }

    /// The activate windows: at most four ACTs in tFAW, 32 in t32AW.
    fn activate_windows(&mut self, c: &Command) {
        if c.kind != DramCmd::Act {
            return;
        }
        let (t, acts) = (self.t, &mut self.acts);
        acts.push_back(c.cycle);
        if t.faw > 0 && acts.len() >= 5 {
            let w = acts[acts.len() - 5];
            if c.cycle < w + t.faw as u64 {
                say(
                    &mut self.out,
                    c,
                    format!("fifth ACT within tFAW of the ACT at {w}"),
                );
            }
        }
        if t.t32aw > 0 && acts.len() >= 33 {
            let w = acts[acts.len() - 33];
            if c.cycle < w + t.t32aw as u64 {
                say(
                    &mut self.out,
                    c,
                    format!("33rd ACT within t32AW of the ACT at {w}"),
                );
            }
        }
        if acts.len() > 33 {
            acts.pop_front();
        }
    }

    /// Refresh rate over a run ending at `end`: JEDEC lets a controller
    /// postpone up to 8 refreshes.
    fn refresh_rate(&mut self, end: u64) {
        let (refs, out) = (&self.refs, &mut self.out);
        let refi = self.t.refi as u64;
        let owed = (end / refi).saturating_sub(8);
        if (refs.len() as u64) < owed {
            out.push(format!(
                "only {} REF commands in {end} cycles; at least {owed} are needed (tREFI {refi}, 8 may be postponed)",
                refs.len()
            ));
        }
        let mut prev = 0;
        for &r in refs {
            if r - prev > 9 * refi {
                out.push(format!(
                    "REF at {r} is {} cycles after the previous one (more than 9 x tREFI)",
                    r - prev
                ));
            }
            prev = r;
        }
    }
}

/// Checks a channel's command log (in issue order). Returns one message per
/// violation; `end` is the cycle the run ended (for the refresh-rate rule).
pub fn check(cmds: &[Command], t: &TimingCfg, g: &GeometryCfg, end: u64) -> Vec<String> {
    let mut k = Checker::new(t, g);
    for c in cmds {
        k.bus_order(c);
        k.in_range(c);
        k.bank_state(c);
        k.pair_rules(c);
        k.activate_windows(c);
    }
    k.refresh_rate(end);
    k.out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mem::config::MemCfg;

    fn cmd(cycle: u64, kind: DramCmd, bank: u32, row: u32) -> Command {
        Command {
            cycle,
            kind,
            bank_group: bank / 4,
            bank,
            row,
            column: 0,
        }
    }

    #[test]
    fn catches_each_kind_of_violation() {
        let m = MemCfg::paper();
        let (t, g) = (&m.timing, &m.geometry);
        use DramCmd::*;
        // Legal: ACT, RD after tRCD, PRE after tRAS, ACT after tRP.
        let ok = [
            cmd(0, Act, 0, 5),
            cmd(24, Rd, 0, 5),
            cmd(56, Pre, 0, 5),
            cmd(80, Act, 0, 6),
        ];
        assert!(
            check(&ok, t, g, 100).is_empty(),
            "{:?}",
            check(&ok, t, g, 100)
        );
        let bad = [cmd(0, Act, 0, 5), cmd(23, Rd, 0, 5)];
        assert!(check(&bad, t, g, 100)[0].contains("tRCDRD"));
        let bad = [cmd(0, Act, 0, 5), cmd(30, Rd, 0, 6)];
        assert!(check(&bad, t, g, 100)[0].contains("row Some(5) open"));
        let bad = [cmd(0, Act, 0, 5), cmd(40, Pre, 0, 5)];
        assert!(check(&bad, t, g, 100)[0].contains("tRAS"));
        // Four ACTs 10 apart (tRRD), the fifth 39 after the first: tFAW is 40.
        let mut faw: Vec<_> = (0..4).map(|i| cmd(i * 10, Act, i as u32 * 3, 1)).collect();
        faw.push(cmd(39, Act, 12, 1));
        let v = check(&faw, t, g, 100);
        assert!(v.iter().any(|x| x.contains("tFAW")), "{v:?}");
        let bad = [cmd(0, Act, 0, 5), cmd(30, Ref, 0, 0)];
        assert!(check(&bad, t, g, 100)[0].contains("REF while a bank is open"));
        // No refresh over a long run.
        let v = check(&[], t, g, 100 * t.refi as u64);
        assert!(v[0].contains("REF commands"));
    }

    #[test]
    fn catches_bus_order_range_bank_state_data_bus_t32aw_and_refresh_gaps() {
        let m = MemCfg::paper();
        let (t, g) = (&m.timing, &m.geometry);
        use DramCmd::*;
        let first = |cmds: &[Command]| check(cmds, t, g, 100).first().cloned();
        let has = |cmds: &[Command], what: &str| first(cmds).is_some_and(|v| v.contains(what));
        assert!(has(
            &[cmd(0, Act, 0, 5), cmd(0, Act, 4, 5)],
            "two commands in one cycle"
        ));
        assert!(has(
            &[cmd(100, Act, 0, 5), cmd(5, Pre, 8, 5)],
            "log is not in time order"
        ));
        assert!(has(&[cmd(0, Act, 16, 5)], "out of range"));
        assert!(has(&[cmd(0, Pre, 0, 5)], "PRE to a closed bank"));
        let v = check(&[cmd(0, Act, 0, 5), cmd(100, Act, 0, 6)], t, g, 100);
        assert!(v.iter().any(|x| x.contains("already open")), "{v:?}");
        // Two reads in different bank groups one cycle apart: their bursts overlap.
        let rd = [
            cmd(0, Act, 0, 5),
            cmd(10, Act, 4, 5),
            cmd(40, Rd, 0, 5),
            cmd(41, Rd, 4, 5),
        ];
        let v = check(&rd, t, g, 100);
        assert!(v.iter().any(|x| x.contains("data bus overlap")), "{v:?}");
        // 33 ACTs 10 apart (tRRD and tFAW kept), each bank precharged 85 cycles
        // after its ACT: only t32AW is broken, by the 33rd.
        let mut acts: Vec<Command> = (0..33u64)
            .map(|i| cmd(10 * i, Act, (i % 16) as u32, 1))
            .collect();
        acts.extend((0..25u64).map(|j| cmd(10 * j + 85, Pre, (j % 16) as u32, 1)));
        acts.sort_by_key(|c| c.cycle);
        let v = check(&acts, t, g, 100);
        assert!(
            v.len() == 1 && v[0].contains("33rd ACT within t32AW"),
            "{v:?}"
        );
        let refi = t.refi as u64;
        let v = check(
            &[cmd(10, Ref, 0, 0), cmd(10 + 10 * refi, Ref, 0, 0)],
            t,
            g,
            100,
        );
        assert!(
            v.len() == 1 && v[0].contains("more than 9 x tREFI"),
            "{v:?}"
        );
    }
}
