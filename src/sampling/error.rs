//! Time sampling's error: the frame or the chip it runs, a plan or study
//! option out of range, windows that do not cover the frame, a worker thread
//! lost, and the reference run a study compares with.

use std::fmt;

use crate::machine::ChipError;
use crate::mem::MemError;
use crate::render::RenderError;
use crate::util::FileError;

#[derive(Debug)]
pub enum SamplingError {
    /// The functional frame failed.
    Render(RenderError),
    /// A window's chip could not be built or run.
    Chip(ChipError),
    /// The DRAM energy model (its preset) could not be built.
    Mem(MemError),
    /// A window plan, a tile sample or a study option out of range.
    Invalid(String),
    /// The windows do not cover what the estimate needs (the option to change named).
    Uncovered(String),
    /// A time-sampling worker thread could not start or stopped without a result.
    Worker(String),
    /// A reference file (statistics, image, pass log) that cannot be read, or
    /// a study table that cannot be written.
    File(FileError),
    /// A reference that does not parse or is of another run.
    Reference(String),
}

impl fmt::Display for SamplingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SamplingError::Render(e) => write!(f, "{e}"),
            SamplingError::Chip(e) => write!(f, "{e}"),
            SamplingError::Mem(e) => write!(f, "{e}"),
            SamplingError::Invalid(m)
            | SamplingError::Uncovered(m)
            | SamplingError::Worker(m)
            | SamplingError::Reference(m) => f.write_str(m),
            SamplingError::File(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for SamplingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SamplingError::Render(e) => Some(e),
            SamplingError::Chip(e) => Some(e),
            SamplingError::Mem(e) => Some(e),
            SamplingError::File(e) => Some(e),
            _ => None,
        }
    }
}

/// The frame's error; one a time-sampling hook failed it with comes back as
/// that error (not wrapped twice).
impl From<RenderError> for SamplingError {
    fn from(e: RenderError) -> SamplingError {
        match e {
            RenderError::Hook(h) => match h.downcast::<SamplingError>() {
                Ok(s) => *s,
                Err(h) => SamplingError::Render(RenderError::Hook(h)),
            },
            e => SamplingError::Render(e),
        }
    }
}
impl From<ChipError> for SamplingError {
    fn from(e: ChipError) -> SamplingError {
        SamplingError::Chip(e)
    }
}
impl From<MemError> for SamplingError {
    fn from(e: MemError) -> SamplingError {
        SamplingError::Mem(e)
    }
}

/// The error a hook hands the frame (`render::FunctionalHooks`).
pub(super) fn hook(e: SamplingError) -> RenderError {
    RenderError::Hook(Box::new(e))
}
