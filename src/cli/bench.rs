//! `dualstream bench`: measure the simulator (kernel, dram, speed-error,
//! threads).

use std::path::PathBuf;

use clap::Args;

use dualstream::config::Config;
use dualstream::render::WindowPlan;
use dualstream::rtl::Threads;

use super::{parse_res, sampling, write_file};

#[derive(Args)]
pub struct BenchArgs {
    /// What to measure: kernel, dram, speed-error or threads.
    what: String,
    /// Scale the simulated cycles (1.0 = the full benchmark; kernel and dram).
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// speed-error: the scene (builtin name, .toml or .obj).
    #[arg(long, default_value = "cornell")]
    scene: String,
    /// speed-error: resolution WxH.
    #[arg(long, default_value = "64x64")]
    res: String,
    /// speed-error: TMs of the small-chip mode.
    #[arg(long, default_value_t = 8)]
    small_tms: u32,
    /// speed-error: the modes to run besides the reference, comma-separated
    /// (cycle-fixed, functional+estimate, small-chip, small-chips-fit,
    /// quarter-pixels, sampled, windows). Default: all. threads: the cases
    /// (cycle64, cycle256, windows1024; default: all).
    #[arg(long)]
    modes: Option<String>,
    /// speed-error, sampled: keep one tile in this many per sample.
    #[arg(long, default_value_t = 16)]
    sample_every: u32,
    /// speed-error, sampled: tile side in pixels.
    #[arg(long, default_value_t = 16)]
    tile: u32,
    /// speed-error, sampled: disjoint samples, each a cycle run (2 or more
    /// estimate the sampling error).
    #[arg(long, default_value_t = 2)]
    subsets: u32,
    /// speed-error, windows (time sampling): a window's measurement starts
    /// every this many segment passes of a wavefront (after its head).
    #[arg(long, default_value_t = sampling::default_windows().every)]
    window_every: u64,
    /// speed-error, windows: admissions measured from each wavefront's start:
    /// the root pass (by its root window), then the next ones simulated whole.
    #[arg(long, default_value_t = sampling::default_windows().head)]
    window_head: u64,
    /// speed-error, windows: rays of each wavefront's root window (a shorter
    /// root pass whole, a longer one over one run of 8 rays in k of its
    /// queue, packed).
    #[arg(long, default_value_t = sampling::default_windows().root_rays)]
    window_root_rays: u64,
    /// speed-error, windows: the same for the later wavefronts' root
    /// windows (the primary rays' root pass needs a longer sample).
    #[arg(long, default_value_t = sampling::default_windows().bounce_root_rays)]
    window_bounce_root_rays: u64,
    /// speed-error, windows: rays of a short wavefront's sample (one with
    /// too few passes for a window): a longer one is traced from its root
    /// pass to its end over one run of up to 1024 rays in k of its root
    /// queue, hashed, hit records in place (0: simulated whole after its
    /// root window).
    #[arg(long, default_value_t = sampling::default_windows().wave_rays)]
    window_wave_rays: u64,
    /// speed-error, windows: sampled short wavefronts from the second to
    /// this one also simulated whole; the ratio of whole to sample corrects
    /// the other sampled ones (0: none).
    #[arg(long, default_value_t = sampling::default_windows().wave_whole)]
    window_wave_whole: u64,
    /// speed-error, windows: a short wavefront's sample runs on this share
    /// of the L2 (its rays come back to their hit records k times sooner).
    #[arg(long, default_value_t = sampling::default_windows().wave_l2_share)]
    window_wave_l2: u32,
    /// speed-error, windows: a short wavefront is sampled only if its
    /// sample's ray lines per pass reach this share of a segment's (else
    /// its passes are bound by the scene stream; it is simulated whole).
    #[arg(long, default_value_t = sampling::default_windows().wave_ray_share)]
    window_wave_ray_share: f64,
    /// speed-error, windows: each wavefront's tail, from the first boundary
    /// with at most this many queues holding rays, simulated to its end (0:
    /// none, the tail scaled like the rest).
    #[arg(long, default_value_t = sampling::default_windows().tail_pending)]
    window_tail: u64,
    /// speed-error, windows: admissions the tail window runs unmeasured
    /// first (counted in the rest).
    #[arg(long, default_value_t = sampling::default_windows().tail_warm)]
    window_tail_warm: u64,
    /// speed-error, windows: wavefronts traced in windows: the first, the
    /// last and every N-th from the second on (1: all); the others take their
    /// trace's cycles, lines and energy from their functional work times the
    /// ratios of the nearest measured ones (their shading passes keep their
    /// windows). Above 1, a wavefront too short for windows and traced over a
    /// sample borrows from the fourth on, from the sampled ones from the third
    /// on, while its rays are alike the last measured one's.
    #[arg(long, default_value_t = sampling::default_windows().wave_every)]
    window_waves: u64,
    /// speed-error, windows: segment passes the chip runs before a window's
    /// measurement, unmeasured, to fill its buffers, caches and queues and
    /// stagger its 64 scene-buffer slots (docs/speed-error.md: 64 leaves
    /// every window 12-19% fast at the paper's size, 96 does not).
    #[arg(long, default_value_t = sampling::default_windows().warm)]
    window_warm: u64,
    /// speed-error, windows: segment passes measured per window.
    #[arg(long, default_value_t = sampling::default_windows().measure)]
    window_measure: u64,
    /// speed-error, windows: shading windows per shading pass (and of the
    /// ray generation: one).
    #[arg(long, default_value_t = sampling::default_windows().shade_windows)]
    shade_windows: u32,
    /// speed-error, windows: shading items (pixels) a shading window runs
    /// before its measurement.
    #[arg(long, default_value_t = sampling::default_windows().shade_warm)]
    shade_warm: u64,
    /// speed-error, windows: cycles a shading window runs at least before
    /// its measurement (with --shade-warm items).
    #[arg(long, default_value_t = sampling::default_windows().shade_warm_cycles)]
    shade_warm_cycles: u64,
    /// speed-error, windows: shading items measured per shading window.
    #[arg(long, default_value_t = sampling::default_windows().shade_measure)]
    shade_measure: u64,
    /// speed-error, windows: items of each shading pass simulated from its
    /// start as they are (the start-up phase, which windows do not see).
    #[arg(long, default_value_t = sampling::default_windows().shade_head)]
    shade_head: u64,
    /// speed-error, windows: write every window (kind, position, warm-up and
    /// measured counts, the segment passes it retired) and the functional
    /// model's segment passes as JSON here.
    #[arg(long)]
    window_log: Option<PathBuf>,
    /// speed-error: compare with this finished reference instead of rendering
    /// one: the --stats JSON of `render --mode cycle` with GDDR5 on the same
    /// scene, resolution and config.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// speed-error, with --reference: that run's PNG, to check the modes' images
    /// (as 8-bit sRGB).
    #[arg(long, requires = "reference")]
    reference_image: Option<PathBuf>,
    /// speed-error, with --reference: that run's --pass-log CSV, to check
    /// the windows mode's estimate part by part (a reference the bench
    /// renders itself is checked so without it).
    #[arg(long, requires = "reference")]
    reference_passes: Option<PathBuf>,
    /// speed-error: write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// speed-error: write the speedup-against-error plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
}

pub fn bench(config: Config, threads: Threads, a: BenchArgs) -> Result<(), String> {
    if a.scale.is_nan() || a.scale <= 0.0 {
        return Err("--scale must be positive".into());
    }
    match a.what.as_str() {
        "kernel" => print!("{}", dualstream::bench::kernel_report(a.scale)),
        // The competing process of `bench threads` (spins until killed).
        "busy" => dualstream::bench::threads::busy(),
        "threads" => threads_bench(&config, a)?,
        "dram" => print!("{}", dualstream::mem::bench::report(a.scale)?),
        "speed-error" => speed_error(&config, threads, a)?,
        what => {
            return Err(format!(
                "unknown benchmark '{what}'; available: kernel, dram, speed-error, threads"
            ));
        }
    }
    Ok(())
}

/// `dualstream bench threads`: every case on one lane, on one per core and on
/// auto, idle and beside a busy process.
fn threads_bench(config: &Config, a: BenchArgs) -> Result<(), String> {
    use dualstream::bench::threads as bt;
    let cases = bt::cases(a.modes.as_deref())?;
    let runs = bt::run(&a.scene, config, &cases, &mut |what| {
        eprintln!("bench threads: {what}")
    })?;
    println!(
        "bench threads: {} on {} x {} TPs, memory {}, {} core(s); wall time of each frame",
        a.scene,
        config.chip.tms,
        config.tm.tps,
        config.chip.memory.model.name(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    print!("{}", bt::table(&runs));
    if let Some(p) = a.json {
        let text = serde_json::to_string_pretty(&runs).map_err(|e| e.to_string())?;
        write_file(&p, text)?;
    }
    Ok(())
}

/// The time-sampling plan the `--window-*` and `--shade-*` flags give.
fn window_plan(a: &BenchArgs) -> WindowPlan {
    WindowPlan {
        every: a.window_every,
        head: a.window_head,
        root_rays: a.window_root_rays,
        bounce_root_rays: a.window_bounce_root_rays,
        wave_rays: a.window_wave_rays,
        wave_whole: a.window_wave_whole,
        wave_l2_share: a.window_wave_l2,
        wave_ray_share: a.window_wave_ray_share,
        tail_pending: a.window_tail,
        tail_warm: a.window_tail_warm,
        wave_every: a.window_waves,
        warm: a.window_warm,
        measure: a.window_measure,
        shade_windows: a.shade_windows,
        shade_warm: a.shade_warm,
        shade_warm_cycles: a.shade_warm_cycles,
        shade_measure: a.shade_measure,
        shade_head: a.shade_head,
    }
}

/// `dualstream bench speed-error`: the faster modes against the cycle model
/// (rendered here, or a finished one given with --reference).
fn speed_error(config: &Config, threads: Threads, a: BenchArgs) -> Result<(), String> {
    let mut sc = dualstream::scene::load(&a.scene)?;
    (sc.settings.width, sc.settings.height) = parse_res(&a.res)?;
    sc.settings.validate()?;
    let reference = match &a.reference {
        Some(p) => {
            let mut r = sampling::Reference::load(p, a.reference_image.as_deref(), &sc, config)?;
            if let Some(csv) = &a.reference_passes {
                r.read_passes(csv)?;
            }
            Some(r)
        }
        None => None,
    };
    let windows = window_plan(&a);
    let opts = sampling::SpeedErrorOpts {
        reference,
        small_tms: a.small_tms,
        sample_every: a.sample_every,
        tile: a.tile,
        subsets: a.subsets,
        modes: a
            .modes
            .map(|m| m.split(',').map(|x| x.trim().to_string()).collect()),
        threads,
        windows,
        window_log: a.window_log,
    };
    let rows = sampling::run(&sc, config, &opts)?;
    println!(
        "speed against error: {} {}x{} on {} x {} TPs (reference: cycle mode, GDDR5)",
        sc.name, sc.settings.width, sc.settings.height, config.chip.tms, config.tm.tps
    );
    print!("{}", sampling::table(&rows));
    for r in rows.iter().filter(|r| !r.by_part.is_empty()) {
        print!("{}", sampling::part_table(&r.by_part));
    }
    if let Some(p) = a.json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
        write_file(&p, text)?;
    }
    if let Some(p) = a.plot {
        write_file(&p, sampling::plot(&rows))?;
    }
    Ok(())
}
