//! Clocked state primitives: registers and RAMs. Both follow the two-phase rule:
//! `eval` reads the current value and schedules the next; `commit` (the clock edge)
//! makes it current. A RAM applies only the written words at the edge, so a large
//! memory is never copied per cycle.

use std::cell::Cell;

use super::bits::Payload;
use super::decl::{Samples, StateDecl, StateList};

thread_local! {
    /// The unit registers written (`Reg::set`) on this thread since the last
    /// [`take_written`], one bit per register of the unit being evaluated
    /// ([`State::number`]). The simulator commits only those right after an
    /// evaluation: walking every register of a unit (a TP has 29) touched most of
    /// its 1.5-2 KB of state at every edge, though a cycle writes a few.
    static WRITTEN: Cell<u64> = const { Cell::new(0) };
}

/// The registers written on this thread since the last call (see `WRITTEN`).
#[inline]
pub fn take_written() -> u64 {
    WRITTEN.with(|w| w.replace(0))
}

/// Behaviour shared by every piece of declared unit state.
pub trait State {
    /// What a `unit!` declaration writes after a field's `=`: a register's
    /// reset value (`ray_index: Reg<u32> = 0`); any other state, the state as
    /// built (`stack: Ram<StackEntry> = Ram::new(..)`).
    type Init;
    fn from_init(init: Self::Init) -> Self
    where
        Self: Sized;
    /// Adds this state's declarations, named after the field.
    fn declare(&self, name: &str, out: &mut StateList);
    /// Packs the traced signals, in the order `declare` listed them, as they are
    /// during the current cycle `cycle` (of the unit's clock).
    fn sample(&self, cycle: u64, out: &mut Samples);
    /// [`State::sample`] as the state stands at reset (what [`State::reset`]
    /// returns to): the values the Verilog's reset block gives.
    fn sample_reset(&self, out: &mut Samples);
    /// Clock edge.
    fn commit(&mut self);
    /// Back to the reset value.
    fn reset(&mut self);
    /// Whether the pending edge would change anything (used by shadow evaluation).
    fn pending_change(&self) -> bool;
    /// Whether [`State::sample`] at a later cycle may differ from the one at
    /// `cycle` with no evaluation and no edge in between: state whose view
    /// advances with time alone (a pipeline's stages, a delayed FIFO's head).
    /// The tracer samples a unit that neither ran nor saw its links move only
    /// while this holds.
    fn moves(&self, _cycle: u64) -> bool {
        false
    }
    /// Whether [`State::commit`] may be skipped when the unit's written mask
    /// lacks this state's bit: true for a register, which marks its bit when
    /// set; anything else (RAMs, pipelines, behavioural models) is committed at
    /// every edge.
    const MARKS_WRITES: bool = false;
    /// Gives this state its bit in the written mask (registers; `bit` is all
    /// ones past the 64th field, so that such a register marks every bit).
    fn number(&mut self, _bit: u64) {}
}

/// A register: `get` is the value this cycle, `set` takes effect at the edge.
#[derive(Clone, Debug)]
pub struct Reg<T: Payload> {
    cur: T,
    next: Option<T>,
    /// This register's bit in the unit's written mask ([`State::number`]); all
    /// ones until numbered, so an unnumbered register marks every bit.
    bit: u64,
    init: T,
}

impl<T: Payload> Reg<T> {
    pub fn new(init: T) -> Self {
        Reg {
            cur: init.clone(),
            next: None,
            bit: u64::MAX,
            init,
        }
    }
    #[inline]
    pub fn get(&self) -> &T {
        &self.cur
    }
    #[inline]
    pub fn set(&mut self, v: T) {
        self.next = Some(v);
        let bit = self.bit;
        WRITTEN.with(|w| w.set(w.get() | bit));
    }
    /// The value that will be current after the edge (the last `set`, else current).
    pub fn next(&self) -> &T {
        self.next.as_ref().unwrap_or(&self.cur)
    }
    /// Whether `set` was called since the last edge.
    #[inline]
    pub fn written(&self) -> bool {
        self.next.is_some()
    }
}

impl<T: Payload + Copy> Reg<T> {
    #[inline]
    pub fn val(&self) -> T {
        self.cur
    }
}

impl<T: Payload> State for Reg<T> {
    type Init = T;
    fn from_init(init: T) -> Self {
        Reg::new(init)
    }
    fn declare(&self, name: &str, out: &mut StateList) {
        let mut d = StateDecl::reg(name, T::BITS);
        d.enum_names = T::enum_names();
        d.fields = T::field_list();
        d.ty = Some(T::sv_type());
        out.items.push(d);
    }
    fn sample(&self, _cycle: u64, out: &mut Samples) {
        self.cur.pack(out.slot());
    }
    fn sample_reset(&self, out: &mut Samples) {
        self.init.pack(out.slot());
    }
    #[inline]
    fn commit(&mut self) {
        if let Some(v) = self.next.take() {
            self.cur = v;
        }
    }
    fn reset(&mut self) {
        self.cur = self.init.clone();
        self.next = None;
    }
    fn pending_change(&self) -> bool {
        self.next.as_ref().is_some_and(|n| !n.same_bits(&self.cur))
    }
    const MARKS_WRITES: bool = true;
    fn number(&mut self, bit: u64) {
        self.bit = bit;
    }
}

/// A RAM (register file, buffer, cache data array) of `depth` words with at most
/// `write_ports` writes per cycle, applied at the edge. Reads see the current contents.
#[derive(Clone, Debug)]
pub struct Ram<T: Payload> {
    data: Vec<T>,
    init: T,
    writes: Vec<(u32, T)>,
    write_ports: u32,
    /// The depth as an expression of the unit's parameters (`"STACK_ENTRIES"`,
    /// `"2 * HALF_RAYS"`), for the Verilog's array bound.
    sized_by: Option<&'static str>,
}

impl<T: Payload> Ram<T> {
    /// Names the parameter expression the depth is (`"BYTES / LINE_BYTES"`):
    /// the skeleton sizes its array with it, and `rtl::decl` checks that it
    /// evaluates to the depth.
    pub fn sized_by(mut self, expr: &'static str) -> Self {
        self.sized_by = Some(expr);
        self
    }
    pub fn new(depth: u32, write_ports: u32, init: T) -> Self {
        assert!(
            depth > 0 && write_ports > 0,
            "RAM needs depth and write ports"
        );
        Ram {
            data: vec![init.clone(); depth as usize],
            init,
            writes: Vec::with_capacity(write_ports as usize),
            write_ports,
            sized_by: None,
        }
    }
    pub fn depth(&self) -> u32 {
        self.data.len() as u32
    }
    #[inline]
    pub fn read(&self, addr: u32) -> &T {
        &self.data[addr as usize]
    }
    /// Schedules a write for the edge. Exceeding the write ports or the depth is a
    /// modelling error, not an input error, so it panics with the reason.
    pub fn write(&mut self, addr: u32, v: T) {
        assert!(
            addr < self.depth(),
            "RAM write to {addr} beyond depth {}",
            self.depth()
        );
        assert!(
            (self.writes.len() as u32) < self.write_ports,
            "RAM has {} write ports; a unit wrote more in one cycle",
            self.write_ports
        );
        self.writes.push((addr, v));
    }
}

impl<T: Payload> State for Ram<T> {
    type Init = Self;
    fn from_init(init: Self) -> Self {
        init
    }
    fn declare(&self, name: &str, out: &mut StateList) {
        let mut d = StateDecl::array(name, T::BITS, self.depth());
        d.reset = super::bits::packed(&self.init);
        d.depth_expr = self.sized_by;
        out.items.push(d);
    }
    fn sample(&self, _cycle: u64, _out: &mut Samples) {}
    fn sample_reset(&self, _out: &mut Samples) {}
    fn commit(&mut self) {
        for (a, v) in self.writes.drain(..) {
            self.data[a as usize] = v;
        }
    }
    fn reset(&mut self) {
        self.data.iter_mut().for_each(|d| *d = self.init.clone());
        self.writes.clear();
    }
    fn pending_change(&self) -> bool {
        self.writes
            .iter()
            .any(|(a, v)| !self.data[*a as usize].same_bits(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reg_changes_only_at_the_edge() {
        let mut r = Reg::new(3u8);
        r.set(5);
        assert_eq!(r.val(), 3);
        assert!(r.pending_change());
        r.commit();
        assert_eq!(r.val(), 5);
        assert!(!r.pending_change());
        r.set(5);
        assert!(
            !r.pending_change(),
            "writing the same value changes nothing"
        );
        r.reset();
        assert_eq!(r.val(), 3);
    }

    #[test]
    fn ram_writes_apply_at_the_edge() {
        let mut m = Ram::new(4, 1, 0u32);
        m.write(2, 9);
        assert_eq!(*m.read(2), 0);
        m.commit();
        assert_eq!(*m.read(2), 9);
    }

    #[test]
    #[should_panic(expected = "write ports")]
    fn ram_rejects_too_many_writes_per_cycle() {
        let mut m = Ram::new(4, 1, 0u32);
        m.write(0, 1);
        m.write(1, 1);
    }
}
