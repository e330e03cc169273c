//! When units run: every unit's scheduling record (`Sched`), the rounding of a
//! wake-up time up to the unit's next clock edge without a divide (`EdgeOf`),
//! wake-ups from outside a run and the time of the next step, taken from the
//! calendars (`rtl::calendar`) of the caller's thread and of the worker lanes.

use super::{Sim, Time, UnitId};
use crate::rtl::calendar::Calendar;
use crate::rtl::unit::Next;

/// What the step loop needs of a unit, apart from the `Slot` that its evaluation
/// changes: compact, and written only by the thread that runs the step loop.
#[derive(Clone, Copy)]
pub(super) struct Sched {
    /// The unit's clock period, and how a wake-up rounds up to its edge
    /// without a divide.
    pub(super) edge: EdgeOf,
    /// Last wake-up time put in the calendar (skips immediate duplicates).
    pub(super) last_wake: Time,
    pub(super) clock: u16,
}

/// `t.div_ceil(period)` by a multiply with the period's reciprocal: a 64-bit
/// `div` is about 30 cycles of latency on this machine (13 ns per division in a
/// dependent chain, 2 ns per multiply), and every wake-up a push sends is
/// rounded up to its consumer's clock edge.
#[derive(Clone, Copy, Debug)]
pub(super) struct EdgeOf {
    pub(super) period: Time,
    /// `ceil(2^64 / period)` (0 for a period of 1).
    m: u64,
    /// The largest time the multiply divides exactly: below `2^64 / period`
    /// the error of `m` stays under one period's fraction.
    exact_to: Time,
}

impl EdgeOf {
    pub(super) fn new(period: Time) -> Self {
        assert!(period >= 1, "a clock period is at least 1 ps");
        if period == 1 {
            return EdgeOf {
                period,
                m: 0,
                exact_to: Time::MAX,
            };
        }
        EdgeOf {
            period,
            m: u64::MAX / period + 1,
            exact_to: u64::MAX / period,
        }
    }
    /// The cycle of the first edge at or after `t`.
    #[inline]
    fn cycle_at_or_after(&self, t: Time) -> u64 {
        if self.period == 1 {
            return t;
        }
        if t > self.exact_to {
            return t.div_ceil(self.period);
        }
        let q = ((t as u128 * self.m as u128) >> 64) as u64;
        q + (q * self.period != t) as u64
    }
}

impl Sim {
    /// Wakes a unit at its next clock edge (for testbenches that poke a unit's queue
    /// between runs).
    pub fn wake(&mut self, u: UnitId) {
        let t = if self.stepped { self.now + 1 } else { self.now };
        self.sched[u.0 as usize].at_time(&mut self.cal, u.0, t);
    }

    /// Time of the next step, if any unit is scheduled.
    pub(super) fn next_time(&mut self) -> Option<Time> {
        let mut t = self.lane_cals.iter().map(|c| c.next_time()).fold(
            self.cal.next_time(),
            |a, b| match (a, b) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            },
        )?;
        let after = if self.stepped { self.now + 1 } else { self.now };
        let edge_after = |p: Time| after.div_ceil(p) * p;
        if !self.opts.sleep {
            for c in &self.clocks {
                t = t.min(edge_after(c.period_ps));
            }
        }
        for tr in self.tracer.iter().chain(&self.capture) {
            if let Some(te) = tr.next_sample_time(after) {
                t = t.min(te);
            }
        }
        Some(t)
    }
}

/// Scheduling unit `u`, this record's unit, in a calendar. Every wake-up is kept
/// (a unit may be woken by a link before the time it asked for, and must still
/// run at that time); duplicates of one time are skipped.
impl Sched {
    /// At cycle `c` of the unit's clock.
    #[inline]
    fn at_cycle(&mut self, cal: &mut Calendar, u: u32, c: u64) {
        let t = c * self.edge.period;
        if t != self.last_wake {
            self.last_wake = t;
            cal.push_cycle(self.clock as usize, u, c, t);
        }
    }

    /// At the unit's first clock edge at or after `t`.
    #[inline]
    pub(super) fn at_time(&mut self, cal: &mut Calendar, u: u32, t: Time) {
        let c = self.edge.cycle_at_or_after(t);
        self.at_cycle(cal, u, c);
    }

    /// Where the unit (`path`), evaluated in `cycle` of its clock, asked to run
    /// next (`n`).
    #[inline]
    pub(super) fn next(&mut self, cal: &mut Calendar, u: u32, n: Next, cycle: u64, path: &str) {
        let c = match n {
            Next::Cycle => cycle + 1,
            Next::AtCycle(c) => {
                assert!(
                    c > cycle,
                    "unit '{path}' asked to wake at cycle {c}, which is not in the future"
                );
                c
            }
            Next::Idle => return,
        };
        self.at_cycle(cal, u, c);
    }
}

#[cfg(test)]
mod tests {
    use super::EdgeOf;

    #[test]
    fn edge_of_is_div_ceil() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for p in [
            1u64,
            2,
            3,
            7,
            64,
            667,
            1000,
            1250,
            1_000_003,
            (1 << 20) + 1,
            1 << 40,
        ] {
            let e = EdgeOf::new(p);
            let mut ts = vec![
                0,
                1,
                p - 1,
                p,
                p + 1,
                e.exact_to,
                e.exact_to.saturating_add(1),
            ];
            ts.extend([u64::MAX - 1, u64::MAX]);
            for k in [1u64, 2, 3, 1 << 20, 66_000_000, 1 << 40] {
                if let Some(m) = k.checked_mul(p) {
                    ts.extend([m - 1, m, m.saturating_add(1)]);
                }
            }
            for _ in 0..10_000 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                ts.push(x);
                ts.push(x >> 20);
                ts.push((x >> 24) / p * p);
            }
            for t in ts {
                assert_eq!(e.cycle_at_or_after(t), t.div_ceil(p), "t = {t}, period {p}");
            }
        }
    }
}
