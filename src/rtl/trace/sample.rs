//! Sampling during a run: at each edge of a traced unit's clock, its ports
//! and registers, the values derived from them (fields, fire), and the clocks
//! up to that time. Only changes are written.

use super::super::bits::Bits;
use super::super::decl::PortDir;
use super::super::link::LinkDyn;
use super::super::sim::Time;
use super::super::unit::Unit;
use super::{Derive, Sig, Tracer};

impl Tracer {
    /// The first traced edge at or after `after`, inside the window.
    pub(crate) fn next_sample_time(&self, after: Time) -> Option<Time> {
        let after = after.max(self.spec.from);
        let t = self.periods.iter().map(|p| after.div_ceil(*p) * p).min()?;
        (t <= self.spec.to).then_some(t)
    }

    pub(crate) fn sample<'u>(
        &mut self,
        t: Time,
        unit_at: &dyn Fn(usize) -> &'u dyn Unit,
        links: &[Box<dyn LinkDyn>],
    ) {
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
            if !t.is_multiple_of(period) {
                continue;
            }
            self.sample_unit(ui, t, unit_at(index), links);
            if let Err(e) = self.write_unit(ui, t) {
                self.error = Some(e);
                return;
            }
        }
        self.guard(t);
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
            let v = &self.samples.vals[k];
            // An empty sample holds the last value.
            let m = !v.is_empty() && changed(sig, v);
            if m {
                self.sink.bits(t, sig.h, v, sig.width)?;
                self.changes += 1;
            }
            moved.push(m);
        }
        // A derived signal can only change with what it is derived from.
        for d in &mut unit.derived {
            let s = &mut self.scratch;
            let float = match d.how {
                Derive::Fire { port } => {
                    if !moved[3 * port] && !moved[3 * port + 1] {
                        continue;
                    }
                    let v = &self.samples.vals;
                    s.clear();
                    s.push((v[3 * port].bit(0) && v[3 * port + 1].bit(0)) as u64, 1);
                    false
                }
                Derive::Field { of, offset, float } => {
                    if !moved[of] {
                        continue;
                    }
                    self.samples.vals[of].slice_into(offset, d.sig.width, s);
                    float
                }
            };
            if changed(&mut d.sig, s) {
                if float {
                    let x = f32::from_bits(s.get(0, 32) as u32);
                    self.sink.real(t, d.sig.h, x as f64)?;
                } else {
                    self.sink.bits(t, d.sig.h, s, d.sig.width)?;
                }
                self.changes += 1;
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
                self.sink.bits(t, c.h, &bit(c.level), 1)?;
                self.changes += 1;
            }
            if let Some(h) = self.rst {
                self.sink.bits(t, h, &bit(false), 1)?;
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
                self.sink.bits(tn, c.h, &bit(c.level), 1)?;
                self.changes += 1;
            }
        }
    }
}

fn bit(b: bool) -> Bits {
    let mut v = Bits::new();
    v.push(b as u64, 1);
    v
}

/// Whether `v` differs from what `sig` last wrote (and remembers it).
fn changed(sig: &mut Sig, v: &Bits) -> bool {
    if sig.last.as_ref() == Some(v) {
        return false;
    }
    match &mut sig.last {
        Some(l) => l.clone_from(v),
        None => sig.last = Some(v.clone()),
    }
    true
}
