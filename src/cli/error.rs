//! The command line's error: a flag or argument it refuses itself, a file it
//! writes itself, a check a command ran that failed, or a library error. Each
//! is printed as `error: ...` with a failing exit code (`main`).

use std::fmt;

use dualstream::bench::threads::BenchError;
use dualstream::config::ConfigError;
use dualstream::machine::ChipError;
use dualstream::mem::MemError;
use dualstream::render::RenderError;
use dualstream::rtl::TraceError;
use dualstream::sampling::SamplingError;
use dualstream::scene::SceneError;
use dualstream::testbench::TbError;
use dualstream::units::UnitError;
use dualstream::util::FileError;

#[derive(Debug)]
pub enum CliError {
    /// A flag, an argument or a combination the command refuses (the flag and
    /// the fix named).
    Usage(String),
    /// A file the command writes itself that cannot be written.
    File(FileError),
    /// A check the command ran found errors (a scoreboard, the timing checker).
    Failed(String),
    Config(ConfigError),
    Scene(SceneError),
    Mem(MemError),
    Unit(UnitError),
    Trace(TraceError),
    Chip(ChipError),
    Render(RenderError),
    Sampling(SamplingError),
    Tb(TbError),
    Bench(BenchError),
    /// An error and what to do about it, on the next line.
    Hinted {
        error: Box<CliError>,
        hint: &'static str,
    },
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::Usage(m) | CliError::Failed(m) => f.write_str(m),
            CliError::File(e) => write!(f, "{e}"),
            CliError::Config(e) => write!(f, "{e}"),
            CliError::Scene(e) => write!(f, "{e}"),
            CliError::Mem(e) => write!(f, "{e}"),
            CliError::Unit(e) => write!(f, "{e}"),
            CliError::Trace(e) => write!(f, "{e}"),
            CliError::Chip(e) => write!(f, "{e}"),
            CliError::Render(e) => write!(f, "{e}"),
            CliError::Sampling(e) => write!(f, "{e}"),
            CliError::Tb(e) => write!(f, "{e}"),
            CliError::Bench(e) => write!(f, "{e}"),
            CliError::Hinted { error, hint } => write!(f, "{error}\n{hint}"),
        }
    }
}

impl std::error::Error for CliError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CliError::Usage(_) | CliError::Failed(_) => None,
            CliError::File(e) => Some(e),
            CliError::Config(e) => Some(e),
            CliError::Scene(e) => Some(e),
            CliError::Mem(e) => Some(e),
            CliError::Unit(e) => Some(e),
            CliError::Trace(e) => Some(e),
            CliError::Chip(e) => Some(e),
            CliError::Render(e) => Some(e),
            CliError::Sampling(e) => Some(e),
            CliError::Tb(e) => Some(e),
            CliError::Bench(e) => Some(e),
            CliError::Hinted { error, .. } => Some(error.as_ref()),
        }
    }
}

macro_rules! wraps {
    ($($t:ty => $v:ident),* $(,)?) => {$(
        impl From<$t> for CliError {
            fn from(e: $t) -> CliError {
                CliError::$v(e)
            }
        }
    )*};
}
wraps!(ConfigError => Config, SceneError => Scene, MemError => Mem, UnitError => Unit,
       TraceError => Trace, ChipError => Chip, RenderError => Render,
       SamplingError => Sampling, TbError => Tb, BenchError => Bench);

/// A file the command writes itself: `cannot write '<path>': <why>` and the
/// flag to change, if any.
pub fn unwritable(p: &std::path::Path, e: std::io::Error, fix: &str) -> CliError {
    let msg = format!("cannot write '{}': {e}{fix}", p.display());
    CliError::File(FileError::new(p, e, msg))
}
