//! Laying a scene out for the chip: its BVH, its segments and the DRAM image.

use std::time::Instant;

use super::{AccelInfo, RenderCfg, RenderError};
use crate::accel::{Bvh, SceneImage, Segmentation};
use crate::contract::{MemoryMap, SparseMem};
use crate::scene::Scene;

/// The scene built for the chip: BVH, segments and the DRAM image.
pub struct Prepared {
    pub bvh: Bvh,
    pub seg: Segmentation,
    pub map: MemoryMap,
    pub mem: SparseMem,
    pub image: SceneImage,
    pub info: AccelInfo,
}

/// Builds the BVH and the segments and writes the scene stream into a fresh image.
pub fn prepare(scene: &Scene, cfg: &RenderCfg) -> Result<Prepared, RenderError> {
    cfg.memory.validate()?;
    cfg.accel.validate(cfg.memory.row_bytes)?;
    let bvh = Bvh::build(&scene.triangles, &cfg.accel.bvh)?;
    let t0 = Instant::now();
    let seg = Segmentation::build(&bvh, cfg.accel.segment_bytes)?;
    let segment_build_s = t0.elapsed().as_secs_f64();
    let bytes: Vec<u32> = seg.segments.iter().map(|s| s.bytes).collect();
    // A path record and two hit records per path (`spp` per pixel).
    let paths =
        scene.settings.width as u64 * scene.settings.height as u64 * scene.settings.spp as u64;
    let map = MemoryMap::new(
        &cfg.memory,
        &bytes,
        SceneImage::children_total(&seg),
        scene.triangles.len() as u64,
        scene.materials.len() as u64,
        paths,
    )?;
    let mut mem = SparseMem::new(map.capacity);
    let image = SceneImage::write(
        &mut mem,
        &map,
        &scene.triangles,
        &scene.tri_material,
        &bvh,
        &seg,
    );
    for (i, m) in scene.materials.iter().enumerate() {
        let a = map.materials + i as u64 * 16;
        mem.write_f32(a, m.albedo.x);
        mem.write_f32(a + 4, m.albedo.y);
        mem.write_f32(a + 8, m.albedo.z);
    }
    let kids: Vec<u64> = seg
        .segments
        .iter()
        .map(|s| s.children.len() as u64)
        .collect();
    let info = AccelInfo {
        triangles: scene.triangles.len() as u64,
        bvh_nodes: bvh.nodes.len() as u64,
        bvh_depth: bvh.depth,
        segments: seg.segments.len() as u64,
        scene_bytes: bytes.iter().map(|&b| b as u64).sum(),
        children_min: kids.iter().copied().min().unwrap_or(0),
        children_mean: kids.iter().sum::<u64>() as f64 / kids.len().max(1) as f64,
        children_max: kids.iter().copied().max().unwrap_or(0),
        segment_bytes_mean: bytes.iter().map(|&b| b as f64).sum::<f64>()
            / bytes.len().max(1) as f64,
        bvh_build_s: bvh.build_time.as_secs_f64(),
        segment_build_s,
        bvh_fallback: match &bvh.builder {
            crate::accel::BvhBuilder::Ploc => None,
            crate::accel::BvhBuilder::BinnedSah { reason } => Some(reason.clone()),
        },
    };
    Ok(Prepared {
        bvh,
        seg,
        map,
        mem,
        image,
        info,
    })
}
