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

/// Checks a channel's command log (in issue order). Returns one message per
/// violation; `end` is the cycle the run ended (for the refresh-rate rule).
pub fn check(cmds: &[Command], t: &TimingCfg, g: &GeometryCfg, end: u64) -> Vec<String> {
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
    let mut out = Vec::new();
    let mut recent: VecDeque<Command> = VecDeque::new();
    let mut open: Vec<Option<u32>> = vec![None; g.banks() as usize];
    let mut acts: VecDeque<u64> = VecDeque::new();
    let mut refs: Vec<u64> = Vec::new();
    let mut last_cycle: Option<u64> = None;
    let say = |out: &mut Vec<String>, c: &Command, what: String| {
        if out.len() < 1000 {
            out.push(format!(
                "cycle {} {:?} bank {} (group {}) row {}: {what}",
                c.cycle, c.kind, c.bank, c.bank_group, c.row
            ));
        }
    };
    for c in cmds {
        if let Some(l) = last_cycle {
            if c.cycle == l {
                say(
                    &mut out,
                    c,
                    "two commands in one cycle (one command bus)".into(),
                );
            } else if c.cycle < l {
                say(&mut out, c, "log is not in time order".into());
            }
        }
        last_cycle = Some(c.cycle);
        if c.bank >= g.banks()
            || c.bank_group != c.bank / g.banks_per_group
            || c.row >= g.rows
            || c.column >= g.columns
        {
            say(
                &mut out,
                c,
                "bank, group, row or column out of range".into(),
            );
        }
        // Bank state machine.
        let b = (c.bank as usize).min(open.len() - 1);
        match c.kind {
            DramCmd::Act => {
                if open[b].is_some() {
                    say(&mut out, c, "ACT to a bank that is already open".into());
                }
                open[b] = Some(c.row);
            }
            DramCmd::Rd | DramCmd::Wr => {
                if open[b] != Some(c.row) {
                    say(
                        &mut out,
                        c,
                        format!("column command but the bank has row {:?} open", open[b]),
                    );
                }
            }
            DramCmd::Pre => {
                if open[b].is_none() {
                    say(&mut out, c, "PRE to a closed bank".into());
                }
                open[b] = None;
            }
            DramCmd::Ref => {
                if open.iter().any(|o| o.is_some()) {
                    say(&mut out, c, "REF while a bank is open".into());
                }
                refs.push(c.cycle);
            }
            DramCmd::Nop => {}
        }
        // Pairwise rules and data-bus overlap against recent commands.
        while recent.front().is_some_and(|p| p.cycle + window < c.cycle) {
            recent.pop_front();
        }
        for p in &recent {
            if let Some((gap, name)) = pair_rule(p, c, t, burst)
                && c.cycle < p.cycle + gap
            {
                say(
                    &mut out,
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
                    &mut out,
                    c,
                    format!("data bus overlap with {:?} at {}", p.kind, p.cycle),
                );
            }
        }
        recent.push_back(*c);
        // Activate windows.
        if c.kind == DramCmd::Act {
            acts.push_back(c.cycle);
            if t.faw > 0 && acts.len() >= 5 {
                let w = acts[acts.len() - 5];
                if c.cycle < w + t.faw as u64 {
                    say(
                        &mut out,
                        c,
                        format!("fifth ACT within tFAW of the ACT at {w}"),
                    );
                }
            }
            if t.t32aw > 0 && acts.len() >= 33 {
                let w = acts[acts.len() - 33];
                if c.cycle < w + t.t32aw as u64 {
                    say(
                        &mut out,
                        c,
                        format!("33rd ACT within t32AW of the ACT at {w}"),
                    );
                }
            }
            if acts.len() > 33 {
                acts.pop_front();
            }
        }
    }
    // Refresh rate: JEDEC lets a controller postpone up to 8 refreshes.
    let refi = t.refi as u64;
    let owed = (end / refi).saturating_sub(8);
    if (refs.len() as u64) < owed {
        out.push(format!(
            "only {} REF commands in {end} cycles; at least {owed} are needed (tREFI {refi}, 8 may be postponed)",
            refs.len()
        ));
    }
    let mut prev = 0;
    for &r in &refs {
        if r - prev > 9 * refi {
            out.push(format!(
                "REF at {r} is {} cycles after the previous one (more than 9 x tREFI)",
                r - prev
            ));
        }
        prev = r;
    }
    out
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
}
