//! Behavioural state: a unit's state kept as ordinary Rust data (queues, tables)
//! instead of one `Reg` per field, for the control-heavy global units. The owner
//! declares what the hardware holds (`Behavioural::declare`: registers traced in
//! the VCD, arrays for the Verilog skeleton) and what is sampled.
//!
//! Contract (the same as `Reg`'s, enforced by shadow mode): `eval` must call
//! [`Model::m`] only when it really changes the state; that marks the unit dirty
//! for this cycle. Changes are applied at once (not at the edge): units still see
//! each other only through links, so this is exact as long as the unit reads its
//! own state consistently within one `eval`.

use super::decl::{Samples, StateList};
use super::state::State;

/// What a behavioural state shows to the declaration and the tracer.
pub trait Behavioural {
    /// Registers (traced) and arrays (Verilog only) of the hardware it stands for.
    fn declare(&self, out: &mut StateList);
    /// Packs the declared registers, in `declare` order.
    fn sample(&self, out: &mut Samples);
    /// The state after reset.
    fn reset(&mut self);
}

#[derive(Clone, Debug)]
pub struct Model<T: Behavioural> {
    v: T,
    dirty: bool,
}

impl<T: Behavioural> Model<T> {
    pub fn new(v: T) -> Self {
        Model { v, dirty: false }
    }
    /// Read access.
    #[inline]
    pub fn r(&self) -> &T {
        &self.v
    }
    /// Write access: marks the state as changed this cycle.
    #[inline]
    pub fn m(&mut self) -> &mut T {
        self.dirty = true;
        &mut self.v
    }
}

/// A behavioural state is declared with its value as built
/// (`st: Model<HruState> = HruState::default()`).
impl<T: Behavioural + Clone> State for Model<T> {
    type Init = T;
    fn from_init(init: T) -> Self {
        Model::new(init)
    }
    fn declare(&self, _name: &str, out: &mut StateList) {
        self.v.declare(out);
    }
    fn sample(&self, _cycle: u64, out: &mut Samples) {
        self.v.sample(out);
    }
    fn sample_reset(&self, out: &mut Samples) {
        let mut r = self.v.clone();
        r.reset();
        r.sample(out);
    }
    fn commit(&mut self) {
        self.dirty = false;
    }
    fn reset(&mut self) {
        self.v.reset();
        self.dirty = false;
    }
    fn pending_change(&self) -> bool {
        self.dirty
    }
}
