//! Sampling during a run: at each edge of a traced unit's clock, its ports
//! and registers, the values derived from them (fields, fire), and the clocks
//! up to that time. Only changes are written.

use super::super::bits::Bits;
use super::super::decl::PortDir;
use super::super::link::LinkDyn;
use super::super::link::LinkId;
use super::super::sim::Time;
use super::super::unit::Unit;
use super::{Derive, NONE, Tracer};

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
    /// The first traced edge at or after `after`, inside the window.
    pub(crate) fn next_sample_time(&self, after: Time) -> Option<Time> {
        let after = after.max(self.spec.from);
        let t = self.periods.iter().map(|p| after.div_ceil(*p) * p).min()?;
        (t <= self.spec.to).then_some(t)
    }

    /// Samples at time `t`, after the evaluations of `due` (simulator unit
    /// indices) and before the edge; `touched` lists the links they pushed or
    /// popped, `heads` is when each link's head is visible. Called at every
    /// step of the run, so the activity outside the window is seen too.
    pub(crate) fn sample<'u>(
        &mut self,
        t: Time,
        unit_at: &dyn Fn(usize) -> &'u dyn Unit,
        links: &[Box<dyn LinkDyn>],
        activity: Activity,
    ) {
        self.note_activity(t, activity);
        if t < self.spec.from || t > self.spec.to || self.error.is_some() || self.stopped.is_some()
        {
            return;
        }
        if let Err(e) = self.clocks_until(t) {
            self.error = Some(e);
            return;
        }
        for ui in 0..self.units.len() {
            let (period, index) = (self.units[ui].period, self.units[ui].index);
            let u = &self.units[ui];
            if !t.is_multiple_of(period) {
                continue;
            }
            // Sample only what may differ from the last sample: see `note_activity`.
            let due = self.spec.every_edge
                || u.moving
                || (u.busy_until != Time::MAX && t <= u.busy_until)
                || t >= u.wake_at;
            if !due {
                continue;
            }
            self.units[ui].wake_at = Time::MAX;
            let unit = unit_at(index);
            self.sample_unit(ui, t, unit, links);
            self.units[ui].moving = unit.state_moves(t / period);
            if let Err(e) = self.write_unit(ui, t) {
                self.error = Some(e);
                return;
            }
        }
        self.guard(t);
    }

    /// Marks the traced units whose signals may change from what the
    /// activity at `t` did: a unit that ran (its ports now, its registers
    /// after the edge) and the units at both ends of a link pushed or popped
    /// (by the other end, maybe in another clock domain) are sampled for a
    /// period; a link's head, known after the edge, wakes its consumer when
    /// it becomes visible. Anything else is the same as at the unit's last
    /// sample, unless its state moves on its own (`Unit::state_moves`).
    fn note_activity(&mut self, t: Time, a: Activity) {
        for l in std::mem::take(&mut self.pending) {
            let c = self.link_ends[l as usize].1;
            let h = a.heads[l as usize];
            if c != NONE && h != Time::MAX {
                let u = &mut self.units[c as usize];
                u.wake_at = u.wake_at.min(h);
            }
        }
        let mut busy = |k: u32| {
            if k != NONE {
                let u = &mut self.units[k as usize];
                let until = t + u.period;
                if u.busy_until == Time::MAX || u.busy_until < until {
                    u.busy_until = until;
                }
            }
        };
        for &l in a.touched {
            let (p, c) = self.link_ends[l.0 as usize];
            busy(p);
            busy(c);
        }
        for &(u, _) in a.due {
            busy(self.traced_of.get(u as usize).copied().unwrap_or(NONE));
        }
        self.pending.extend(a.touched.iter().map(|l| l.0));
    }

    fn sample_unit(&mut self, ui: usize, t: Time, unit: &dyn Unit, links: &[Box<dyn LinkDyn>]) {
        self.samples.begin();
        for k in 0..self.units[ui].ports.len() {
            let (l, dir) = self.units[ui].ports[k];
            let link = &links[l.0 as usize];
            let base = self.samples.n;
            self.samples.slot();
            self.samples.slot();
            self.samples.slot();
            let [a, b, c] = <&mut [Bits; 3]>::try_from(&mut self.samples.vals[base..base + 3])
                .expect("three slots")
                .each_mut();
            match dir {
                PortDir::In => link.sample_consumer(t, [a, b, c]),
                PortDir::Out => link.sample_producer([a, b, c]),
            }
        }
        unit.sample_state(t / self.units[ui].period, &mut self.samples);
        debug_assert_eq!(
            self.samples.n,
            self.units[ui].sigs.len(),
            "sampled signals match the declaration"
        );
    }

    /// Writes what changed of unit `ui`'s sampled and derived signals.
    fn write_unit(&mut self, ui: usize, t: Time) -> std::io::Result<()> {
        let unit = &mut self.units[ui];
        let moved = &mut self.moved;
        moved.clear();
        for (k, sig) in unit.sigs.iter_mut().enumerate() {
            let v = &mut self.samples.vals[k];
            // An empty sample holds the last value.
            let m = !v.is_empty() && sig.update(v);
            if m && sig.shown {
                self.sink.bits(t, sig.h, v, sig.width)?;
                self.changes += 1;
            }
            moved.push(m);
        }
        // A derived signal can only change with what it is derived from: per
        // port, fire with valid or ready, the fields with the data.
        let ranges = &mut self.ranges;
        ranges.clear();
        for (k, &(fire, fields, end)) in unit.port_derived.iter().enumerate() {
            let (handshake, data) = (moved[3 * k] || moved[3 * k + 1], moved[3 * k + 2]);
            ranges.push(match (handshake, data) {
                (false, false) => continue,
                (true, false) => fire..fields,
                (false, true) => fields..end,
                (true, true) => fire..end,
            });
        }
        // A struct register's fields, with the register.
        for &(of, start, end) in &unit.reg_derived {
            if moved[of] {
                ranges.push(start..end);
            }
        }
        for range in ranges.drain(..) {
            for d in &mut unit.derived[range] {
                let s = &mut self.scratch;
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
                            src.last.slice_into(offset, d.sig.width, s);
                        }
                        float
                    }
                };
                if d.sig.update(s) {
                    if float {
                        let x = f32::from_bits(s.get(0, 32) as u32);
                        self.sink.real(t, d.sig.h, x as f64)?;
                    } else {
                        self.sink.bits(t, d.sig.h, s, d.sig.width)?;
                    }
                    self.changes += 1;
                }
            }
        }
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
