//! Trace replay: DRAMsim3's trace-CPU semantics on our channel controllers.
//! Requests issue in file order, at most one per DRAM cycle, none before its
//! cycle; one that its channel cannot accept blocks those behind it. The loop
//! jumps from event to event (a channel's next legal command, a response, the
//! next request), calling the same `ChannelCtrl` code as the `mem_ctrl` unit in
//! the same order (deliver responses, schedule, accept).

use super::checker;
use super::config::MemCfg;
use super::ctrl::ChannelCtrl;
use super::map::AddrMap;
use super::stats::MemReport;
use super::trace::TraceReq;
use super::{MemReq, StreamTag};

/// Options of a replay.
#[derive(Clone, Debug, Default)]
pub struct ReplayOptions {
    /// Record the command log and run the timing checker on it.
    pub check: bool,
    /// Name of the memory preset, for the report.
    pub preset: String,
}

/// The result of a replay: the report and, if recorded, each channel's commands.
pub struct Replayed {
    pub report: MemReport,
    pub commands: Vec<Vec<super::Command>>,
    /// With `check`: (request index, cycle its data ended), in completion order.
    pub completions: Vec<(u32, u64)>,
}

/// Replays `reqs` on the memory of `cfg` (validated) with DRAM clock `tck_ps`.
pub fn replay(
    cfg: &MemCfg,
    tck_ps: u64,
    reqs: &[TraceReq],
    opts: &ReplayOptions,
) -> Result<Replayed, String> {
    cfg.validate()?;
    let map = AddrMap::new(&cfg.geometry, &cfg.mapping)?;
    let n = cfg.geometry.channels;
    let mut chans: Vec<ChannelCtrl> = (0..n).map(|c| ChannelCtrl::new(cfg, tck_ps, c)).collect();
    for ch in &mut chans {
        ch.record_commands(opts.check);
    }
    // Channel of each request, decoded once (and checked: no panic on bad input).
    let mut chan_of = Vec::with_capacity(reqs.len());
    for (i, r) in reqs.iter().enumerate() {
        let l = map
            .decode(r.addr)
            .map_err(|e| format!("request {} of the trace: {e}", i + 1))?;
        chan_of.push(l.channel as usize);
    }
    let mut c = 0u64;
    let mut i = 0usize;
    let mut last = 0u64;
    let mut completions = Vec::new();
    // Per channel: the next cycle it needs attention (its next command or
    // response while it holds something, else never). A channel not due and not
    // targeted would do nothing this cycle, so it is not visited.
    let mut due = vec![u64::MAX; chans.len()];
    loop {
        let target = (i < reqs.len() && reqs[i].cycle <= c).then(|| chan_of[i]);
        for (k, ch) in chans.iter_mut().enumerate() {
            if due[k] > c && target != Some(k) {
                continue;
            }
            while let Some(r) = ch.pop_response(c, c) {
                if opts.check {
                    completions.push((r.id, c));
                }
            }
            if !ch.is_idle() || target == Some(k) {
                ch.advance_to(c);
                ch.step(c);
            }
        }
        let mut blocked = false;
        if let Some(k) = target {
            let r = &reqs[i];
            if chans[k].can_accept(r.write) {
                chans[k].accept(
                    c,
                    MemReq {
                        addr: r.addr,
                        write: r.write,
                        tag: StreamTag::Other,
                        id: i as u32,
                    },
                );
                i += 1;
            } else {
                blocked = true;
            }
        }
        let mut next = u64::MAX;
        for (k, ch) in chans.iter().enumerate() {
            if due[k] <= c || target == Some(k) {
                due[k] = u64::MAX;
                if !ch.is_idle() {
                    due[k] = ch.next_event();
                    if let Some(r) = ch.next_response() {
                        due[k] = due[k].min(r);
                        last = last.max(r);
                    }
                }
            }
            next = next.min(due[k]);
        }
        if i < reqs.len() && !blocked {
            next = next.min(reqs[i].cycle.max(c + 1));
        }
        if next == u64::MAX {
            break;
        }
        debug_assert!(next > c, "replay time must advance");
        c = next;
    }
    let end = last.max(c);
    let stats: Vec<_> = chans.iter().map(|ch| ch.stats_at(end)).collect();
    let g = &cfg.geometry;
    let mut report = MemReport::new(
        &opts.preset,
        &cfg.energy.preset,
        tck_ps,
        g.line_bytes,
        g.peak_bytes_per_cycle() * g.channels as f64,
        end,
        stats,
    );
    let mut commands = Vec::new();
    if opts.check {
        let mut v = Vec::new();
        for (k, ch) in chans.iter().enumerate() {
            let log = ch.commands_until(end);
            for x in checker::check(&log, &cfg.timing, g, end) {
                v.push(format!("channel {k}: {x}"));
            }
            commands.push(log);
        }
        report.violations = Some(v);
    }
    Ok(Replayed {
        report,
        commands,
        completions,
    })
}
