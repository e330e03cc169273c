//! The memory system's error: a memory-model configuration that cannot work,
//! an unknown preset, a bad address, a trace that does not parse or cannot be
//! read.

use std::fmt;

use crate::rtl::SimError;
use crate::util::FileError;

#[derive(Debug)]
pub enum MemError {
    /// A `mem.*` value out of range or inconsistent (the key and the fix named).
    Config(String),
    /// A controller link (`mem.ctrl.req_link`, `resp_link`) that cannot work.
    Link(SimError),
    /// A memory or energy preset, or a trace generator, that does not exist
    /// (the ones that do listed).
    Unknown(String),
    /// An address the map cannot place (beyond the capacity).
    Address(String),
    /// A trace that does not parse, or asks for what cannot be (line named).
    Trace(String),
    /// A trace file that cannot be read.
    File(FileError),
}

impl fmt::Display for MemError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MemError::Config(m)
            | MemError::Unknown(m)
            | MemError::Address(m)
            | MemError::Trace(m) => f.write_str(m),
            MemError::Link(e) => write!(f, "{e}"),
            MemError::File(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for MemError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MemError::Link(e) => Some(e),
            MemError::File(e) => Some(e),
            _ => None,
        }
    }
}

impl From<SimError> for MemError {
    fn from(e: SimError) -> MemError {
        MemError::Link(e)
    }
}
