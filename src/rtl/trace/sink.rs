//! What a waveform format must do: declare scopes and variables once, then
//! take value changes in time order. The tracer decides *what* to write; a
//! sink (VCD text, FST blocks) decides *how*.

use std::io;

use super::super::bits::Bits;
use super::super::sim::Time;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ScopeKind {
    /// A unit instance.
    Module,
    /// A payload's fields (Verilator's `--trace-structs`).
    Struct,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum VarKind {
    /// Driven combinationally: a port's valid, ready, data or fire.
    Wire,
    /// A clocked register.
    Reg,
    /// An IEEE-754 value shown as a number (a float field).
    Real,
}

pub(crate) struct VarDef<'a> {
    pub name: &'a str,
    pub kind: VarKind,
    pub width: u32,
    /// FSM encodings: index k is state `names[k]`.
    pub enum_names: Option<&'static [&'static str]>,
}

pub(crate) trait Sink {
    fn begin_scope(&mut self, name: &str, kind: ScopeKind);
    fn end_scope(&mut self);
    fn comment(&mut self, text: &str);
    /// Declares a variable in the open scope; returns its handle (0, 1, ...).
    fn var(&mut self, v: &VarDef) -> u32;
    /// Bytes the format spends naming a variable in a value change (the size
    /// estimate's share per change).
    fn id_len(&self, h: u32) -> usize;
    /// Ends the declarations; returns the header's size in bytes.
    fn end_header(&mut self) -> io::Result<u64>;
    fn bits(&mut self, t: Time, h: u32, v: &Bits, width: u32) -> io::Result<()>;
    fn real(&mut self, t: Time, h: u32, v: f64) -> io::Result<()>;
    /// Closes the trace at `end` (so viewers show the final values) and flushes.
    fn finish(&mut self, end: Time) -> io::Result<()>;
    /// Bytes written so far (the size guard's measure).
    fn bytes(&self) -> u64;
}
