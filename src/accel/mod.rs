//! Acceleration structure: the BVH, its treelets (scene segments) and their byte
//! layout in the DRAM image (the scene stream of the data contract).
pub mod bvh;
pub mod layout;
mod ploc;
mod sah;
pub mod treelet;

use serde::{Deserialize, Serialize};

pub use bvh::{Bvh, BvhBuilder, BvhCfg, Child};
pub use layout::SceneImage;
pub use treelet::{Segment, Segmentation};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelCfg {
    /// The BVH build (obvhs's PLOC; a binned-SAH fallback where it stalls).
    pub bvh: BvhCfg,
    /// Segment (treelet) budget: 64 KB [DS17 §5.1], a multiple of the DRAM row.
    pub segment_bytes: u32,
}

impl Default for AccelCfg {
    fn default() -> Self {
        AccelCfg {
            bvh: BvhCfg::default(),
            segment_bytes: 64 << 10,
        }
    }
}

impl AccelCfg {
    pub fn validate(&self, row_bytes: u64) -> Result<(), AccelError> {
        self.bvh.validate()?;
        if !(self.segment_bytes as u64).is_multiple_of(row_bytes) || self.segment_bytes == 0 {
            return Err(AccelError::Invalid(format!(
                "accel.segment_bytes = {} is not a multiple of the DRAM row ({row_bytes} B); segments must stream as whole rows",
                self.segment_bytes
            )));
        }
        Ok(())
    }
}

/// Why a BVH or its segmentation cannot be built.
#[derive(Debug)]
pub enum AccelError {
    /// A configuration value out of range (`accel.*`, `bvh.*`).
    Invalid(String),
    /// There are no triangles to build over.
    NoTriangles,
    /// The segment size cannot hold a header, one node and one leaf.
    SegmentTooSmall { budget: u32, min: u32 },
}

impl std::fmt::Display for AccelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AccelError::Invalid(m) => f.write_str(m),
            AccelError::NoTriangles => {
                f.write_str("cannot build a BVH of zero triangles; the scene has no geometry")
            }
            AccelError::SegmentTooSmall { budget, min } => write!(
                f,
                "segment size {budget} B cannot hold a header, one node and one leaf ({min} B); raise accel.segment_bytes"
            ),
        }
    }
}

impl std::error::Error for AccelError {}
