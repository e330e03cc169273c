//! Trace replay: DRAMsim3's trace-CPU semantics on our channel controllers.
//! Requests issue in file order, at most one per DRAM cycle, none before its
//! cycle; one that its channel cannot accept blocks those behind it. The loop
//! jumps from event to event (a channel's next legal command, a response, the
//! next request), calling the same `ChannelCtrl` code as the `mem_ctrl` unit in
//! the same order (deliver responses, schedule, accept). With `mem.ctrl.policy =
//! "dramsim3"` the channels are `Dramsim3Ctrl`s instead.

use super::MemError;
use super::checker;
use super::config::{CtrlPolicy, MemCfg};
use super::ctrl::ChannelCtrl;
use super::dramsim3::Dramsim3Ctrl;
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
    /// `dramsim3` policy: evaluate every cycle instead of sleeping until the
    /// next event (a check; the outcome must be the same).
    pub every_cycle: bool,
}

/// What the replay asks of a channel controller.
trait Channel: Clone {
    fn create(cfg: &MemCfg, tck_ps: u64, channel: u32, opts: &ReplayOptions) -> Self;
    fn pop_response(&mut self, now: u64, ready_by: u64) -> Option<super::MemResp>;
    fn is_idle(&self) -> bool;
    fn advance_to(&mut self, c: u64);
    fn step(&mut self, c: u64);
    fn can_accept(&self, write: bool) -> bool;
    fn accept(&mut self, c: u64, req: MemReq);
    fn next_event(&self) -> u64;
    fn next_response(&self) -> Option<u64>;
    fn stats_at(&self, end: u64) -> super::stats::ChannelStats;
    fn commands_until(&self, end: u64) -> Vec<super::Command>;
}

macro_rules! channel_impl {
    ($t:ty, $this:ident, $opts:ident, $setup:block) => {
        impl Channel for $t {
            fn create(cfg: &MemCfg, tck_ps: u64, channel: u32, $opts: &ReplayOptions) -> Self {
                let mut $this = <$t>::new(cfg, tck_ps, channel);
                $this.record_commands($opts.check);
                $setup
                $this
            }
            fn pop_response(&mut self, now: u64, ready_by: u64) -> Option<super::MemResp> {
                <$t>::pop_response(self, now, ready_by)
            }
            fn is_idle(&self) -> bool {
                <$t>::is_idle(self)
            }
            fn advance_to(&mut self, c: u64) {
                <$t>::advance_to(self, c)
            }
            fn step(&mut self, c: u64) {
                <$t>::step(self, c)
            }
            fn can_accept(&self, write: bool) -> bool {
                <$t>::can_accept(self, write)
            }
            fn accept(&mut self, c: u64, req: MemReq) {
                <$t>::accept(self, c, req)
            }
            fn next_event(&self) -> u64 {
                <$t>::next_event(self)
            }
            fn next_response(&self) -> Option<u64> {
                <$t>::next_response(self)
            }
            fn stats_at(&self, end: u64) -> super::stats::ChannelStats {
                <$t>::stats_at(self, end)
            }
            fn commands_until(&self, end: u64) -> Vec<super::Command> {
                <$t>::commands_until(self, end)
            }
        }
    };
}

channel_impl!(ChannelCtrl, me, _opts, {});
channel_impl!(Dramsim3Ctrl, me, opts, {
    me.set_every_cycle(opts.every_cycle);
});

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
) -> Result<Replayed, MemError> {
    cfg.validate()?;
    match cfg.ctrl.policy {
        CtrlPolicy::Frfcfs => run::<ChannelCtrl>(cfg, tck_ps, reqs, opts),
        CtrlPolicy::Dramsim3 => run::<Dramsim3Ctrl>(cfg, tck_ps, reqs, opts),
    }
}

fn run<C: Channel>(
    cfg: &MemCfg,
    tck_ps: u64,
    reqs: &[TraceReq],
    opts: &ReplayOptions,
) -> Result<Replayed, MemError> {
    let map = AddrMap::new(&cfg.geometry, &cfg.mapping)?;
    let n = cfg.geometry.channels;
    let mut chans: Vec<C> = (0..n).map(|c| C::create(cfg, tck_ps, c, opts)).collect();
    // Channel of each request, decoded once (and checked: no panic on bad input).
    let mut chan_of = Vec::with_capacity(reqs.len());
    for (i, r) in reqs.iter().enumerate() {
        let l = map
            .decode(r.addr)
            .map_err(|e| MemError::Address(format!("request {} of the trace: {e}", i + 1)))?;
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
