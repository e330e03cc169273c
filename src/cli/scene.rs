//! `dualstream scene`: scene tools.

use clap::Subcommand;

use dualstream::config::Config;
use dualstream::rtl::Threads;

use super::{CliError, bvh_fallback_warning, render_cfg};

#[derive(Subcommand)]
pub enum SceneCmd {
    /// Triangles, BVH nodes and depth, segments, bytes, children per segment, build time.
    Info {
        /// Builtin scene name, scene description (.toml) or Wavefront .obj.
        scene: String,
        #[command(flatten)]
        threads: super::ThreadsArg,
    },
}

pub fn scene(config: &Config, cmd: SceneCmd) -> Result<(), CliError> {
    match cmd {
        SceneCmd::Info { scene, threads } => info(config, threads.get()?, &scene),
    }
}

/// `dualstream scene info SCENE`: the BVH and segments the chip would get.
fn info(config: &Config, threads: Threads, scene: &str) -> Result<(), CliError> {
    let sc = dualstream::scene::load(scene)?;
    for w in &sc.warnings {
        eprintln!("warning: {w}");
    }
    let p = dualstream::render::prepare(&sc, &render_cfg(config, threads))?;
    let i = &p.info;
    if let Some(why) = &i.bvh_fallback {
        eprintln!("warning: {}", bvh_fallback_warning(why));
    }
    println!("scene {}", sc.name);
    println!("  triangles            {}", i.triangles);
    println!(
        "  BVH nodes            {} inner, depth {}",
        i.bvh_nodes, i.bvh_depth
    );
    println!("  BVH build            {:.3} s", i.bvh_build_s);
    println!(
        "  segments             {} (budget {} B)",
        i.segments, config.accel.segment_bytes
    );
    println!("  segment build        {:.3} s", i.segment_build_s);
    println!(
        "  scene bytes          {} ({:.1} KB mean per segment)",
        i.scene_bytes,
        i.segment_bytes_mean / 1024.0
    );
    println!(
        "  children per segment min {} mean {:.2} max {}",
        i.children_min, i.children_mean, i.children_max
    );
    println!(
        "  DRAM map             scene at {:#x}, buckets at {:#x}, end {:#x}",
        p.map.scene, p.map.buckets, p.map.end
    );
    Ok(())
}
