//! The memory map of the simulated DRAM: where each region starts. Every region
//! starts on a DRAM row boundary; segments and buckets are row-aligned too.

use serde::{Deserialize, Serialize};

use super::{HIT_BYTES, PATH_BYTES, QUEUE_REC_BYTES, SEG_ENTRY_BYTES};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MemoryMapCfg {
    /// DRAM capacity: 4 GB GDDR5 [DS17 Table 1].
    pub capacity_bytes: u64,
    /// DRAM row (system view): 8 KB [DS17 §5.1].
    pub row_bytes: u64,
    /// Ray bucket: 2 KB, four per row [DS17 §4.1, §5.1].
    pub bucket_bytes: u64,
    /// Bytes reserved for the ray-bucket pool. Rays in flight at once are at most
    /// about 2 per pixel times the duplication; 512 MB holds 16 M ray slots.
    pub bucket_pool_bytes: u64,
}

impl Default for MemoryMapCfg {
    fn default() -> Self {
        MemoryMapCfg {
            capacity_bytes: 4 << 30,
            row_bytes: 8192,
            bucket_bytes: 2048,
            bucket_pool_bytes: 512 << 20,
        }
    }
}

/// Why the DRAM image cannot be laid out.
#[derive(Debug)]
pub enum MapError {
    /// A `memory.*` value out of range.
    Invalid(String),
    /// The image needs more than the configured DRAM (sizes and the fix named).
    OverCapacity(String),
}

impl std::fmt::Display for MapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MapError::Invalid(m) | MapError::OverCapacity(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for MapError {}

impl MemoryMapCfg {
    pub fn validate(&self) -> Result<(), MapError> {
        if self.row_bytes == 0 || !self.row_bytes.is_power_of_two() {
            return Err(MapError::Invalid(format!(
                "memory.row_bytes = {} must be a power of two",
                self.row_bytes
            )));
        }
        if self.bucket_bytes < 64 || !self.row_bytes.is_multiple_of(self.bucket_bytes) {
            return Err(MapError::Invalid(format!(
                "memory.bucket_bytes = {} must be at least 64 and divide the row ({} B) so buckets share rows",
                self.bucket_bytes, self.row_bytes
            )));
        }
        if self.bucket_pool_bytes < self.row_bytes {
            return Err(MapError::Invalid(
                "memory.bucket_pool_bytes must hold at least one row of buckets".into(),
            ));
        }
        Ok(())
    }
    pub fn rays_per_bucket(&self) -> u32 {
        ((self.bucket_bytes - super::BUCKET_HEADER_BYTES as u64) / super::RAY_BYTES as u64) as u32
    }
}

/// Region addresses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryMap {
    pub row_bytes: u64,
    pub bucket_bytes: u64,
    /// Segment table: one 32 B entry per segment.
    pub seg_table: u64,
    /// Child list: u32 segment ids, indexed by `SegEntry::first_child`.
    pub child_list: u64,
    /// Triangle index: for each scene triangle id, a u32 holding
    /// (address of its record - `scene`) / 16, so shading can find a hit triangle.
    pub tri_index: u64,
    /// Material table: 16 B per material (albedo as three f32, then zero).
    pub materials: u64,
    /// Segments, each at a row boundary.
    pub scene: u64,
    pub scene_bytes: u64,
    /// Ray-bucket pool.
    pub buckets: u64,
    pub bucket_count: u64,
    /// Hit records: two per pixel (bounce, shadow).
    pub hits: u64,
    /// Path state: one per pixel.
    pub path: u64,
    /// Queue records: 16 B per segment (a closed queue waiting for admission).
    pub queue_recs: u64,
    pub end: u64,
    pub capacity: u64,
}

fn align(x: u64, a: u64) -> u64 {
    x.div_ceil(a) * a
}

impl MemoryMap {
    /// Lays out the regions for segments of the given byte sizes, `children` child
    /// list entries in all, and `pixels` pixels.
    pub fn new(
        cfg: &MemoryMapCfg,
        segment_bytes: &[u32],
        children: u64,
        triangles: u64,
        materials: u64,
        pixels: u64,
    ) -> Result<MemoryMap, MapError> {
        cfg.validate()?;
        let row = cfg.row_bytes;
        let seg_table = 0;
        let child_list = align(segment_bytes.len() as u64 * SEG_ENTRY_BYTES as u64, 64);
        let tri_index = align(child_list + children * 4, 64);
        let mats = align(tri_index + triangles * 4, 64);
        let scene = align(mats + materials * 16, row);
        let scene_bytes: u64 = segment_bytes.iter().map(|&b| align(b as u64, row)).sum();
        let buckets = align(scene + scene_bytes, row);
        let bucket_count = cfg.bucket_pool_bytes / cfg.bucket_bytes;
        let hits = align(buckets + bucket_count * cfg.bucket_bytes, row);
        let path = align(hits + pixels * 2 * HIT_BYTES as u64, row);
        let queue_recs = align(path + pixels * PATH_BYTES as u64, row);
        let end = align(
            queue_recs + segment_bytes.len() as u64 * QUEUE_REC_BYTES as u64,
            row,
        );
        if end > cfg.capacity_bytes {
            return Err(MapError::OverCapacity(format!(
                "the scene ({} MB of segments), the ray-bucket pool ({} MB) and {pixels} pixels of hit records and path state need {} MB, more than the configured DRAM ({} MB); raise memory.capacity_bytes or lower memory.bucket_pool_bytes or the resolution",
                scene_bytes >> 20,
                cfg.bucket_pool_bytes >> 20,
                end >> 20,
                cfg.capacity_bytes >> 20
            )));
        }
        Ok(MemoryMap {
            row_bytes: row,
            bucket_bytes: cfg.bucket_bytes,
            seg_table,
            child_list,
            tri_index,
            materials: mats,
            scene,
            scene_bytes,
            buckets,
            bucket_count,
            hits,
            path,
            queue_recs,
            end,
            capacity: cfg.capacity_bytes,
        })
    }

    pub fn hit_addr(&self, hit_index: u64) -> u64 {
        self.hits + hit_index * HIT_BYTES as u64
    }
    pub fn path_addr(&self, pixel: u64) -> u64 {
        self.path + pixel * PATH_BYTES as u64
    }
    pub fn bucket_addr(&self, bucket: u64) -> u64 {
        self.buckets + bucket * self.bucket_bytes
    }
    pub fn seg_entry_addr(&self, seg: u32) -> u64 {
        self.seg_table + seg as u64 * SEG_ENTRY_BYTES as u64
    }
    pub fn queue_rec_addr(&self, seg: u32) -> u64 {
        self.queue_recs + seg as u64 * QUEUE_REC_BYTES as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_are_row_aligned_and_ordered() {
        let m = MemoryMap::new(
            &MemoryMapCfg::default(),
            &[65536, 100, 8193],
            2,
            10,
            3,
            64 * 64,
        )
        .unwrap();
        for a in [m.scene, m.buckets, m.hits, m.path, m.queue_recs, m.end] {
            assert_eq!(a % 8192, 0);
        }
        assert_eq!(m.scene_bytes, 65536 + 8192 + 16384);
        assert!(m.seg_table < m.child_list && m.child_list < m.scene && m.scene < m.buckets);
        assert_eq!(m.bucket_count, (512 << 20) / 2048);
        assert!(m.path < m.queue_recs && m.queue_recs + 3 * 16 <= m.end);
        assert_eq!(MemoryMapCfg::default().rays_per_bucket(), 63);
    }

    #[test]
    fn too_big_is_a_clear_error() {
        let cfg = MemoryMapCfg {
            capacity_bytes: 1 << 20,
            ..MemoryMapCfg::default()
        };
        let e = MemoryMap::new(&cfg, &[65536], 0, 1, 1, 16).unwrap_err();
        assert!(matches!(e, MapError::OverCapacity(_)), "{e:?}");
        assert!(
            e.to_string().contains("more than the configured DRAM"),
            "{e}"
        );
    }
}
