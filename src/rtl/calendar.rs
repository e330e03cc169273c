//! The wake-up calendar: which units run at which time.
//!
//! Almost every wake-up is a few cycles ahead (the next cycle, a link delay, a
//! pipeline latency), so each clock domain has a wheel of 64 cycle slots with a
//! bitmask of the non-empty ones; the rare wake-up further ahead goes to a heap.
//! Finding the next time is a rotate and a trailing-zero count per domain instead
//! of a heap pop per evaluation.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::sim::Time;

const SLOTS: u64 = 64;

struct Wheel {
    period: Time,
    slots: Vec<Vec<u32>>,
    /// Bit `c % 64` set when the slot of cycle `c` (in `base..base + 64`) holds units.
    mask: u64,
    /// First cycle not yet in the past.
    base: u64,
}

pub(crate) struct Calendar {
    wheels: Vec<Wheel>,
    far: BinaryHeap<Reverse<(Time, u32)>>,
}

impl Calendar {
    pub fn new() -> Self {
        Calendar {
            wheels: Vec::new(),
            far: BinaryHeap::new(),
        }
    }

    pub fn add_domain(&mut self, period: Time) {
        self.wheels.push(Wheel {
            period,
            slots: (0..SLOTS).map(|_| Vec::new()).collect(),
            mask: 0,
            base: 0,
        });
    }

    pub fn clear(&mut self) {
        for w in &mut self.wheels {
            w.slots.iter_mut().for_each(Vec::clear);
            w.mask = 0;
            w.base = 0;
        }
        self.far.clear();
    }

    /// Schedules unit `u` of clock domain `d` at time `t`, an edge of that domain
    /// that is not in the past.
    #[inline]
    pub fn push(&mut self, d: usize, u: u32, t: Time) {
        let c = t / self.wheels[d].period;
        self.push_cycle(d, u, c, t);
    }

    /// [`Calendar::push`] for the caller that has the cycle `c` of time `t`
    /// already (`t = c * period`): a 64-bit division fewer per wake-up.
    #[inline]
    pub fn push_cycle(&mut self, d: usize, u: u32, c: u64, t: Time) {
        let w = &mut self.wheels[d];
        debug_assert_eq!(c * w.period, t, "not an edge of the domain");
        debug_assert!(c >= w.base, "wake-up in the past");
        if c < w.base + SLOTS {
            let i = (c % SLOTS) as usize;
            w.slots[i].push(u);
            w.mask |= 1 << i;
        } else {
            self.far.push(Reverse((t, u)));
        }
    }

    /// The earliest scheduled time.
    pub fn next_time(&self) -> Option<Time> {
        let mut best = self.far.peek().map(|Reverse((t, _))| *t);
        for w in &self.wheels {
            if w.mask != 0 {
                let r = w.mask.rotate_right((w.base % SLOTS) as u32);
                let c = w.base + r.trailing_zeros() as u64;
                let t = c * w.period;
                best = Some(best.map_or(t, |b| b.min(t)));
            }
        }
        best
    }

    /// Moves every unit scheduled at `t` into `out` (possibly with duplicates) and
    /// marks all earlier cycles as past.
    pub fn take(&mut self, t: Time, out: &mut Vec<u32>) {
        for w in &mut self.wheels {
            let c = t / w.period;
            if t.is_multiple_of(w.period) && c >= w.base && c < w.base + SLOTS {
                let i = (c % SLOTS) as usize;
                if w.mask & (1 << i) != 0 {
                    out.append(&mut w.slots[i]);
                    w.mask &= !(1 << i);
                }
            }
            // Cycles up to the one containing t are past now (they were empty, or
            // t would not be the earliest time).
            w.base = w.base.max(c + 1);
        }
        while let Some(Reverse((ft, u))) = self.far.peek().copied() {
            if ft != t {
                break;
            }
            self.far.pop();
            out.push(u);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_and_far_wakeups_come_out_in_time_order() {
        let mut c = Calendar::new();
        c.add_domain(1000);
        c.add_domain(500);
        c.push(0, 1, 3000);
        c.push(1, 2, 1500);
        c.push(0, 3, 200_000); // far
        c.push(1, 4, 1500);
        let mut out = Vec::new();
        assert_eq!(c.next_time(), Some(1500));
        c.take(1500, &mut out);
        assert_eq!(out, vec![2, 4]);
        out.clear();
        assert_eq!(c.next_time(), Some(3000));
        c.take(3000, &mut out);
        assert_eq!(out, vec![1]);
        out.clear();
        // A slot reused after wrapping around.
        c.push(0, 5, 3000 + 64_000);
        assert_eq!(c.next_time(), Some(67_000));
        c.take(67_000, &mut out);
        assert_eq!(out, vec![5]);
        out.clear();
        assert_eq!(c.next_time(), Some(200_000));
        c.take(200_000, &mut out);
        assert_eq!(out, vec![3]);
        assert_eq!(c.next_time(), None);
    }
}
