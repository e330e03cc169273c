//! The chip's error: a configuration or netlist it cannot be built from, a run
//! that stops (the watchdog, a deadlock, an overflowed stack, lost work), a
//! waveform selection naming no unit, and the Verilog it cannot write.

use std::fmt;

use crate::config::ConfigError;
use crate::contract::MapError;
use crate::mem::MemError;
use crate::rtl::SimError;
use crate::units::UnitError;
use crate::util::FileError;

#[derive(Debug)]
pub enum ChipError {
    /// The configuration is impossible.
    Config(ConfigError),
    /// The kernel stopped: a netlist error, a link protocol violation, the
    /// waveform's size guard.
    Sim(SimError),
    /// A unit cannot be built from this configuration.
    Unit(UnitError),
    /// The memory system cannot be built from this configuration.
    Mem(MemError),
    /// The DRAM image cannot be laid out.
    Map(MapError),
    /// The stream scheduler stopped (e.g. its destination table is full).
    Scheduler(String),
    /// No progress for `chip.watchdog_cycles`, or a sampling window that did
    /// not reach its marks (the units holding work listed).
    Watchdog(String),
    /// Every unit sleeps but work is left (the units holding work listed).
    Deadlock(String),
    /// A TP's traversal stack overflowed (the chip then starves: this is the cause).
    StackOverflow(String),
    /// A wavefront's books do not balance at its end: rays, buckets, memory
    /// requests or link contents left over.
    Lost(String),
    /// The DRAM command logs break the timing (`chip.memory.check_timing`).
    DramTiming(String),
    /// `--trace-units` names a unit the chip does not have (valid names listed).
    UnknownUnit { name: String, valid: String },
    /// `--trace-units` names a unit that matches no instance of this chip.
    NoSuchUnit {
        name: String,
        hint: &'static str,
        valid: String,
    },
    /// `--trace-window` that does not parse.
    BadWindow(String),
    /// `--capture` names no unit of this chip.
    Capture(String),
    /// The chip's netlist is not one the Verilog emitter can express.
    Hdl(String),
    /// A Verilog file or folder that cannot be written.
    File(FileError),
}

impl fmt::Display for ChipError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ChipError::Config(e) => write!(f, "{e}"),
            ChipError::Sim(e) => write!(f, "{e}"),
            ChipError::Unit(e) => write!(f, "{e}"),
            ChipError::Mem(e) => write!(f, "{e}"),
            ChipError::Map(e) => write!(f, "{e}"),
            ChipError::Scheduler(m)
            | ChipError::Watchdog(m)
            | ChipError::Deadlock(m)
            | ChipError::StackOverflow(m)
            | ChipError::Lost(m)
            | ChipError::DramTiming(m)
            | ChipError::BadWindow(m)
            | ChipError::Hdl(m) => f.write_str(m),
            ChipError::UnknownUnit { name, valid } => write!(
                f,
                "--trace-units: unknown unit '{name}'; valid names: {valid}"
            ),
            ChipError::NoSuchUnit { name, hint, valid } => write!(
                f,
                "--trace-units: '{name}' matches no unit of this chip{hint}; valid names: {valid}"
            ),
            ChipError::File(e) => write!(f, "{e}"),
            ChipError::Capture(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for ChipError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ChipError::Config(e) => Some(e),
            ChipError::Sim(e) => Some(e),
            ChipError::Unit(e) => Some(e),
            ChipError::Mem(e) => Some(e),
            ChipError::Map(e) => Some(e),
            ChipError::File(e) => Some(e),
            _ => None,
        }
    }
}

impl From<ConfigError> for ChipError {
    fn from(e: ConfigError) -> ChipError {
        ChipError::Config(e)
    }
}
impl From<SimError> for ChipError {
    fn from(e: SimError) -> ChipError {
        ChipError::Sim(e)
    }
}
impl From<UnitError> for ChipError {
    fn from(e: UnitError) -> ChipError {
        ChipError::Unit(e)
    }
}
impl From<MemError> for ChipError {
    fn from(e: MemError) -> ChipError {
        ChipError::Mem(e)
    }
}
impl From<MapError> for ChipError {
    fn from(e: MapError) -> ChipError {
        ChipError::Map(e)
    }
}
