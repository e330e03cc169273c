//! A unit configuration that cannot be built: a value out of range, a memory
//! model that does not exist, a controller policy the unit does not run.

use std::fmt;

#[derive(Debug)]
pub enum UnitError {
    /// A unit's configuration value out of range (the key and the fix named).
    Invalid(String),
    /// `chip.memory.model` / `--memory` names no memory model.
    UnknownMemoryModel { given: String },
    /// The `mem_ctrl` unit does not run this controller policy.
    Unsupported(String),
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitError::Invalid(m) | UnitError::Unsupported(m) => f.write_str(m),
            UnitError::UnknownMemoryModel { given } => write!(
                f,
                "unknown memory model '{given}'; give gddr5 (the paper's GDDR5, the default) or fixed (a fixed latency)"
            ),
        }
    }
}

impl std::error::Error for UnitError {}
