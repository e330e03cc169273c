//! A frame's error: the layers it runs on (scene, BVH, DRAM image, chip,
//! waveform), its own settings, the check against the reference, the files it
//! writes, and the error a hook (time sampling) failed it with.

use std::fmt;
use std::path::PathBuf;

use crate::accel::AccelError;
use crate::contract::MapError;
use crate::machine::ChipError;
use crate::rtl::{SimError, TraceError};
use crate::scene::SceneError;
use crate::util::FileError;

#[derive(Debug)]
pub enum RenderError {
    Scene(SceneError),
    Accel(AccelError),
    Map(MapError),
    Chip(ChipError),
    /// The waveform could not be attached to the chip.
    Sim(SimError),
    /// The waveform file could not be started.
    Trace(TraceError),
    /// The waveform could not be finished.
    Vcd(std::io::Error),
    /// A setting the frame cannot run with (the pixel sample, a mode that does
    /// not apply).
    Invalid(String),
    /// The ray-bucket pool ran dry (`memory.bucket_pool_bytes`).
    BucketPool(String),
    /// A traced ray disagrees with the reference traversal (`verify`).
    Mismatch(String),
    /// An output file or folder that cannot be written.
    File(FileError),
    /// The image could not be written.
    Png {
        path: PathBuf,
        source: image::ImageError,
    },
    /// A followed ray (`ChipRun::follow`) that the frame does not have: its
    /// wavefront, id, and why (the valid range, or that it was never traced).
    NoSuchRay {
        wave: u32,
        ray_id: u32,
        why: String,
    },
    /// A hook ([`super::FunctionalHooks`]) failed the frame with its own error.
    Hook(Box<dyn std::error::Error + Send + Sync>),
}

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RenderError::Scene(e) => write!(f, "{e}"),
            RenderError::Accel(e) => write!(f, "{e}"),
            RenderError::Map(e) => write!(f, "{e}"),
            RenderError::Chip(e) => write!(f, "{e}"),
            RenderError::Sim(e) => write!(f, "{e}"),
            RenderError::Trace(e) => write!(f, "{e}"),
            RenderError::Vcd(e) => write!(f, "writing the VCD file failed: {e}"),
            RenderError::Invalid(m) | RenderError::BucketPool(m) | RenderError::Mismatch(m) => {
                f.write_str(m)
            }
            RenderError::File(e) => write!(f, "{e}"),
            RenderError::Png { path, source } => write!(
                f,
                "cannot write the image '{}': {source}; choose a writable --out",
                path.display()
            ),
            RenderError::NoSuchRay { wave, ray_id, why } => {
                write!(f, "no ray {ray_id:#x} in wavefront {wave} to follow: {why}")
            }
            RenderError::Hook(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RenderError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RenderError::Scene(e) => Some(e),
            RenderError::Accel(e) => Some(e),
            RenderError::Map(e) => Some(e),
            RenderError::Chip(e) => Some(e),
            RenderError::Sim(e) => Some(e),
            RenderError::Trace(e) => Some(e),
            RenderError::Vcd(e) => Some(e),
            RenderError::File(e) => Some(e),
            RenderError::Png { source, .. } => Some(source),
            RenderError::Hook(e) => Some(e.as_ref()),
            RenderError::Invalid(_)
            | RenderError::BucketPool(_)
            | RenderError::Mismatch(_)
            | RenderError::NoSuchRay { .. } => None,
        }
    }
}

macro_rules! wraps {
    ($($t:ty => $v:ident),* $(,)?) => {$(
        impl From<$t> for RenderError {
            fn from(e: $t) -> RenderError {
                RenderError::$v(e)
            }
        }
    )*};
}
wraps!(SceneError => Scene, AccelError => Accel, MapError => Map, ChipError => Chip,
       SimError => Sim, TraceError => Trace);
