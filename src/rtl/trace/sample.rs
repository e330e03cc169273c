//! Sampling during a run: at each edge of a traced unit's clock, its ports
//! and registers, the values derived from them (fields, fire), and the clocks
//! up to that time. Only changes are written.

use super::super::bits::Bits;
use super::super::decl::PortDir;
use super::super::link::LinkDyn;
use super::super::link::LinkId;
use super::super::sim::Time;
use super::super::unit::{Ready, Unit};
use super::sink::Sink;
use super::{Derive, NONE, TracedUnit, Tracer};

/// What the simulator did at a step, for the tracer to sample only what
/// may have changed.
#[derive(Clone, Copy)]
pub(crate) struct Activity<'a> {
    /// The units evaluated (simulator indices, and whether they were due).
    pub due: &'a [(u32, bool)],
    /// The links pushed or popped.
    pub touched: &'a [LinkId],
    /// When each link's head is visible (`Time::MAX`: none).
    pub heads: &'a [Time],
}

impl Tracer {
    /// The first time at or after `after`, inside the window, at which a
    /// traced unit is to be sampled: an edge of an active unit's clock or a
    /// wake-up (every edge of every traced clock with `every_edge`).
    pub(crate) fn next_sample_time(&self, after: Time) -> Option<Time> {
        let after = after.max(self.spec.from);
        let edge = |p: Time| after.div_ceil(p) * p;
        let t = if self.spec.every_edge {
            self.periods.iter().map(|p| edge(*p)).min()?
        } else {
            let mut t = Time::MAX;
            for p in &self.periods {
                if self
                    .active
                    .iter()
                    .any(|&u| self.units[u as usize].period == *p)
                {
                    t = t.min(edge(*p));
                }
            }
            if let Some(std::cmp::Reverse((e, _))) = self.wakes.peek() {
                t = t.min((*e).max(after));
            }
            t
        };
        (t <= self.spec.to).then_some(t)
    }

    /// Samples at time `t`, after the evaluations of `due` (simulator unit
    /// indices) and before the edge; `touched` lists the links they pushed or
    /// popped, `heads` is when each link's head is visible. `unit_at` gives a
    /// unit and, if it was evaluated at `t`, its readiness on each input
    /// from before (`Logic::can_accept`). Called at every step of the run, so
    /// the activity outside the window is seen too.
    pub(crate) fn sample<'u>(
        &mut self,
        t: Time,
        unit_at: &dyn Fn(usize) -> (&'u dyn Unit, Option<&'u [bool]>),
        links: &[Box<dyn LinkDyn>],
        activity: Activity,
    ) {
        self.note_activity(t, activity);
        if t < self.spec.from || t > self.spec.to || self.error.is_some() || self.stopped.is_some()
        {
            return;
        }
        let first = self.clock_t.is_none();
        if let Err(e) = self.clocks_until(t) {
            self.error = Some(e);
            return;
        }
        let mut due = std::mem::take(&mut self.due);
        self.due_at(t, first, &mut due);
        for &ui in &due {
            let ui = ui as usize;
            let (period, index) = (self.units[ui].period, self.units[ui].index);
            let (unit, ready) = unit_at(index);
            self.sample_unit(ui, t, (unit, ready), links);
            self.units[ui].moving = unit.state_moves(t / period);
            if let Err(e) = self.write_unit(ui, t) {
                self.error = Some(e);
                break;
            }
        }
        self.due = due;
        // An active unit stays while it moves on its own or is busy past `t`.
        let units = &mut self.units;
        let every = self.spec.every_edge;
        self.active.retain(|&u| {
            let u = &mut units[u as usize];
            u.queued = every || u.moving || (u.busy_until != Time::MAX && u.busy_until > t);
            u.queued
        });
        if self.error.is_none() {
            self.guard(t);
        }
    }

    /// The traced units to sample at `t`, in unit order: the active ones
    /// whose clock has an edge at `t` (all of them at the window's `first`
    /// sample), and those woken for `t`.
    fn due_at(&mut self, t: Time, first: bool, due: &mut Vec<u32>) {
        due.clear();
        while let Some(&std::cmp::Reverse((e, u))) = self.wakes.peek() {
            if e > t {
                break;
            }
            self.wakes.pop();
            let p = self.units[u as usize].period;
            if t.is_multiple_of(p) {
                due.push(u);
            } else {
                // Not an edge of its clock (a wake-up from before the
                // window): its next one.
                self.wakes.push(std::cmp::Reverse((t.div_ceil(p) * p, u)));
            }
        }
        // The window's first sample (`first`) takes every unit, at an edge
        // of its clock or between two: no signal is unknown from then on.
        for &u in &self.active {
            let unit = &self.units[u as usize];
            if t.is_multiple_of(unit.period) || (first && unit.fresh) {
                due.push(u);
            }
        }
        due.sort_unstable();
        due.dedup();
    }

    /// Marks what of the traced units may change from what the activity at
    /// `t` did. A port whose link was pushed or popped (by either end, maybe
    /// in another clock domain) is sampled for a period; a link's head, known
    /// after the edge, wakes its consumer's port when it becomes visible. A
    /// unit that ran has its registers sampled after the edge. Anything else
    /// is the same as at the last sample, unless the unit's state moves on
    /// its own (`Unit::state_moves`).
    fn note_activity(&mut self, t: Time, a: Activity) {
        let (from, to) = (self.spec.from, self.spec.to);
        for l in std::mem::take(&mut self.pending) {
            let [_, _, c, cp] = self.link_ends[l as usize];
            let h = a.heads[l as usize];
            if c != NONE && h != Time::MAX {
                let u = &mut self.units[c as usize];
                let e = h.div_ceil(u.period) * u.period;
                // Before the window every unit is sampled at its first edge.
                if e >= from && e <= to {
                    let w = &mut u.port_wake[cp as usize];
                    *w = (*w).min(e);
                    self.wakes.push(std::cmp::Reverse((e, c)));
                }
            }
        }
        let (units, active) = (&mut self.units, &mut self.active);
        let mut queue = |u: &mut TracedUnit, k: u32| {
            let until = t + u.period;
            if u.busy_until == Time::MAX || u.busy_until < until {
                u.busy_until = until;
            }
            if !u.queued {
                u.queued = true;
                active.push(k);
            }
        };
        for &l in a.touched {
            let [p, pp, c, cp] = self.link_ends[l.0 as usize];
            for (k, port) in [(p, pp), (c, cp)] {
                if k != NONE {
                    let u = &mut units[k as usize];
                    u.port_busy[port as usize] = t + u.period;
                    queue(u, k);
                }
            }
        }
        for &(s, _) in a.due {
            let k = self.traced_of.get(s as usize).copied().unwrap_or(NONE);
            if k != NONE {
                let u = &mut units[k as usize];
                u.ran_at = t;
                queue(u, k);
            }
        }
        self.pending.extend(a.touched.iter().map(|l| l.0));
    }

    /// Samples what of unit `ui` may have changed (see `note_activity`): the
    /// ports in `sampled`, and the registers if `regs_sampled`. An input's
    /// ready while nothing is valid is the unit's readiness, which changes
    /// with its registers (after the unit ran, or while its state moves on
    /// its own) and its outputs' room (after an output's link moved): then it
    /// is sampled on every input (alone where the port is not otherwise).
    fn sample_unit(
        &mut self,
        ui: usize,
        t: Time,
        (unit, ready_pre): (&dyn Unit, Option<&[bool]>),
        links: &[Box<dyn LinkDyn>],
    ) {
        let every = self.spec.every_edge;
        let u = &mut self.units[ui];
        let all = every || u.fresh;
        u.fresh = false;
        let nsigs = u.sigs.len();
        let samples = &mut self.samples;
        self.sampled.clear();
        if samples.vals.len() < nsigs {
            samples.vals.resize_with(nsigs, Bits::new);
        }
        // Registers change only at the edge after the unit ran.
        let ran = u.ran_at != Time::MAX && (u.regs_at == Time::MAX || u.ran_at >= u.regs_at);
        let busy_at = |k: usize| u.port_busy[k] != Time::MAX && t <= u.port_busy[k];
        let readiness_moved = all
            || ran
            || u.moving
            || (0..u.ports.len()).any(|k| u.ports[k].1 == PortDir::Out && busy_at(k));
        let out_ready = |l: LinkId| links[l.0 as usize].space_at_start();
        let at = Ready::new(t / u.period, &out_ready);
        let mut input = 0;
        for k in 0..u.ports.len() {
            let (l, dir) = u.ports[k];
            let base = 3 * k;
            let [a, b, c] = <&mut [Bits; 3]>::try_from(&mut samples.vals[base..base + 3])
                .expect("three slots")
                .each_mut();
            let woken = u.port_wake[k] <= t;
            let busy = u.port_busy[k] != Time::MAX && t <= u.port_busy[k];
            if woken {
                u.port_wake[k] = Time::MAX;
            }
            let link = &links[l.0 as usize];
            let sampled = all || woken || busy;
            let ready = (dir == PortDir::In && (sampled || readiness_moved))
                .then(|| ready_pre.map_or_else(|| unit.can_accept(l, &at), |r| r[input]));
            input += (dir == PortDir::In) as usize;
            if !sampled {
                if let Some(r) = ready {
                    // Valid and data as before (an empty sample holds).
                    self.sampled.push(k as u32);
                    a.clear();
                    c.clear();
                    b.clear();
                    b.push((r && link.head_time() > t) as u64, 1);
                }
                continue;
            }
            self.sampled.push(k as u32);
            a.clear();
            b.clear();
            c.clear();
            match ready {
                Some(r) => link.sample_consumer(t, r, [a, b, c]),
                None => link.sample_producer([a, b, c]),
            }
            if c.is_empty() && !u.sigs[base + 2].written {
                // No payload at the window's first sample: the data it holds
                // (as an RTL simulator's $dumpvars writes every value).
                link.sample_held(dir == PortDir::In, c);
            }
        }
        let regs = 3 * u.ports.len();
        self.regs_sampled = all || u.moving || ran;
        if self.regs_sampled {
            u.regs_at = t;
            samples.n = regs;
            unit.sample_state(t / u.period, samples);
            debug_assert_eq!(samples.n, nsigs, "sampled signals match the declaration");
        }
    }

    /// Writes what changed of unit `ui`'s sampled and derived signals.
    fn write_unit(&mut self, ui: usize, t: Time) -> std::io::Result<()> {
        let unit = &mut self.units[ui];
        let (sink, scratch, diff) = (&mut *self.sink, &mut self.scratch, &mut self.diff);
        let mut changes = 0;
        // An empty sample holds the last value.
        for &k in &self.sampled {
            let k = k as usize;
            let mut m = [false; 3];
            for (j, m) in m.iter_mut().enumerate() {
                let (sig, v) = (&mut unit.sigs[3 * k + j], &self.samples.vals[3 * k + j]);
                *m = !v.is_empty() && sig.update(v, &mut unit.wide, (j == 2).then_some(&mut *diff));
                if *m && sig.shown {
                    sink.bits(t, sig.h, v, sig.width)?;
                    changes += 1;
                }
            }
            // A derived signal can only change with what it is derived from:
            // fire with valid or ready, a field with its bits of the data.
            let (fire, fields, end) = unit.port_derived[k];
            if (m[0] || m[1]) && fire < fields {
                changes += derive(unit, fire, t, sink, scratch)? as u64;
            }
            if m[2] {
                changes += derive_changed(unit, fields..end, diff, t, sink, scratch)?;
            }
        }
        if self.regs_sampled {
            let regs = 3 * unit.ports.len();
            // Struct registers (with fields) in register order.
            let mut next_struct = 0;
            for i in regs..unit.sigs.len() {
                let v = &self.samples.vals[i];
                let fields = unit.reg_derived.get(next_struct).copied();
                let fields = fields.filter(|&(of, _, _)| of == i);
                next_struct += fields.is_some() as usize;
                let sig = &mut unit.sigs[i];
                let d = fields.is_some().then_some(&mut *diff);
                let m = !v.is_empty() && sig.update(v, &mut unit.wide, d);
                if m && sig.shown {
                    sink.bits(t, sig.h, v, sig.width)?;
                    changes += 1;
                }
                if let (true, Some((_, start, end))) = (m, fields) {
                    changes += derive_changed(unit, start..end, diff, t, sink, scratch)?;
                }
            }
        }
        self.changes += changes;
        Ok(())
    }

    /// Writes every clock's edges up to `t` (and, the first time, each
    /// clock's level and the reset at `t`).
    pub(super) fn clocks_until(&mut self, t: Time) -> std::io::Result<()> {
        if self.clock_t.is_none() {
            for c in &mut self.clocks {
                let (p, half) = (c.period, c.period / 2);
                let phase = t % p;
                c.level = phase < half;
                c.next = t - phase + if c.level { half } else { p };
                self.sink.bits(t, c.h, bit(c.level), 1)?;
                self.changes += 1;
            }
            if let Some(h) = self.rst {
                self.sink.bits(t, h, bit(false), 1)?;
                self.changes += 1;
            }
            self.clock_t = Some(t);
        }
        loop {
            let Some(tn) = self.clocks.iter().map(|c| c.next).min() else {
                return Ok(());
            };
            if tn > t {
                self.clock_t = Some(t);
                return Ok(());
            }
            for c in self.clocks.iter_mut().filter(|c| c.next == tn) {
                c.level = !c.level;
                let half = c.period / 2;
                c.next = tn + if c.level { half } else { c.period - half };
                self.sink.bits(tn, c.h, bit(c.level), 1)?;
                self.changes += 1;
            }
        }
    }
}

/// Recomputes the fields in `range` of `unit.derived` that overlap the bits
/// set in `diff` (what changed in the signal they come from), writing those
/// whose value changed; returns how many were written.
fn derive_changed(
    unit: &mut TracedUnit,
    range: std::ops::Range<usize>,
    diff: &[u64],
    t: Time,
    sink: &mut dyn Sink,
    scratch: &mut Bits,
) -> std::io::Result<u64> {
    let mut n = 0;
    for i in range {
        let (offset, width) = unit.spans[i];
        if touches(diff, offset, width) {
            n += derive(unit, i, t, sink, scratch)? as u64;
        }
    }
    Ok(n)
}

/// Whether any of bits `offset..offset + width` is set in `diff`.
#[inline]
fn touches(diff: &[u64], offset: u32, width: u32) -> bool {
    let (first, last) = (offset / 64, (offset + width - 1) / 64);
    (first..=last).any(|w| {
        let Some(&d) = diff.get(w as usize) else {
            return false;
        };
        let lo = if w == first { offset % 64 } else { 0 };
        let hi = if w == last {
            (offset + width - 1) % 64
        } else {
            63
        };
        let mask = (u64::MAX >> (63 - hi)) & (u64::MAX << lo);
        d & mask != 0
    })
}

/// Recomputes derived signal `i` of `unit` from its sampled source and
/// writes it if it changed; returns whether it did.
fn derive(
    unit: &mut TracedUnit,
    i: usize,
    t: Time,
    sink: &mut dyn Sink,
    s: &mut Bits,
) -> std::io::Result<bool> {
    let d = &mut unit.derived[i];
    let float = match d.how {
        Derive::Fire { port } => {
            let v = &unit.sigs;
            s.clear();
            s.push(v[3 * port].small & v[3 * port + 1].small & 1, 1);
            false
        }
        Derive::Field { of, offset, float } => {
            let src = &unit.sigs[of];
            if src.width <= 64 {
                s.clear();
                s.push(src.small >> offset, d.sig.width);
            } else {
                let n = src.width.div_ceil(64) as usize;
                Bits::slice_words(&unit.wide[src.at as usize..][..n], offset, d.sig.width, s);
            }
            float
        }
    };
    if !d.sig.update(s, &mut unit.wide, None) {
        return Ok(false);
    }
    if float {
        // A float field is 32 bits, in the first word.
        let x = f32::from_bits(s.words()[0] as u32);
        sink.real(t, d.sig.h, x as f64)?;
    } else {
        sink.bits(t, d.sig.h, s, d.sig.width)?;
    }
    Ok(true)
}

/// A one-bit value, packed (the clocks toggle every half period: no
/// allocation per edge).
fn bit(b: bool) -> &'static Bits {
    static LEVELS: std::sync::OnceLock<[Bits; 2]> = std::sync::OnceLock::new();
    let l = LEVELS.get_or_init(|| {
        [false, true].map(|b| {
            let mut v = Bits::new();
            v.push(b as u64, 1);
            v
        })
    });
    &l[b as usize]
}
