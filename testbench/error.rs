//! A testbench's error: no bench by that name, a knob out of range, the
//! layers a bench runs on (config, scene, frame layout, kernel, waveform), and
//! a run that went wrong (a TP's stack overflowed). A scoreboard's findings are
//! not errors: they are the report's `errors`.

use std::fmt;

use crate::config::ConfigError;
use crate::mem::MemError;
use crate::render::RenderError;
use crate::rtl::{SimError, TraceError};
use crate::scene::SceneError;
use crate::units::UnitError;
use crate::util::FileError;

#[derive(Debug)]
pub enum TbError {
    /// `dualstream tb NAME`: no bench for that unit (the benches listed).
    UnknownUnit {
        name: String,
    },
    /// A knob out of range, or a bench asked for what it does not run.
    Invalid(String),
    Config(ConfigError),
    Scene(SceneError),
    Render(RenderError),
    Mem(MemError),
    Unit(UnitError),
    /// The kernel stopped (netlist, protocol, the waveform's size guard).
    Sim(SimError),
    /// The waveform could not be started.
    Trace(TraceError),
    /// The waveform could not be finished.
    Vcd {
        what: &'static str,
        source: std::io::Error,
    },
    /// The waveform file cannot be created.
    File(FileError),
    /// A TP's traversal stack overflowed (the treelet is deeper than the scratchpad).
    StackOverflow(String),
}

impl fmt::Display for TbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TbError::UnknownUnit { name } => write!(
                f,
                "unknown unit '{name}'; testbenches exist for: {}",
                super::bench_names()
            ),
            TbError::Invalid(m) | TbError::StackOverflow(m) => f.write_str(m),
            TbError::Config(e) => write!(f, "{e}"),
            TbError::Scene(e) => write!(f, "{e}"),
            TbError::Render(e) => write!(f, "{e}"),
            TbError::Mem(e) => write!(f, "{e}"),
            TbError::Unit(e) => write!(f, "{e}"),
            TbError::Sim(e) => write!(f, "{e}"),
            TbError::Trace(e) => write!(f, "{e}"),
            TbError::Vcd { what, source } => write!(f, "{what}: {source}"),
            TbError::File(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for TbError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TbError::Config(e) => Some(e),
            TbError::Scene(e) => Some(e),
            TbError::Render(e) => Some(e),
            TbError::Mem(e) => Some(e),
            TbError::Unit(e) => Some(e),
            TbError::Sim(e) => Some(e),
            TbError::Trace(e) => Some(e),
            TbError::Vcd { source, .. } => Some(source),
            TbError::File(e) => Some(e),
            TbError::UnknownUnit { .. } | TbError::Invalid(_) | TbError::StackOverflow(_) => None,
        }
    }
}

macro_rules! wraps {
    ($($t:ty => $v:ident),* $(,)?) => {$(
        impl From<$t> for TbError {
            fn from(e: $t) -> TbError {
                TbError::$v(e)
            }
        }
    )*};
}
wraps!(ConfigError => Config, SceneError => Scene, RenderError => Render, MemError => Mem,
       UnitError => Unit, SimError => Sim, TraceError => Trace);
