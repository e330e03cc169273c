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
    pub fn validate(&self, row_bytes: u64) -> Result<(), String> {
        self.bvh.validate()?;
        if !(self.segment_bytes as u64).is_multiple_of(row_bytes) || self.segment_bytes == 0 {
            return Err(format!(
                "accel.segment_bytes = {} is not a multiple of the DRAM row ({row_bytes} B); segments must stream as whole rows",
                self.segment_bytes
            ));
        }
        Ok(())
    }
}
