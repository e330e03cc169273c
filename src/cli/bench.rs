//! `dualstream bench`: measure the simulator. One subcommand a benchmark, each
//! with only its own flags; the time-sampling plan's (`--window-*`,
//! `--shade-*`) belong to `bench speed-error` alone.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use dualstream::config::Config;
use dualstream::render::header::{HeadedList, RunHeader, RunParams};
use dualstream::rtl::Threads;
use dualstream::sampling::{self, WindowPlan, speed_error};

use super::progress::Meter;
use super::{CliError, parse_res, write_file};

#[derive(Subcommand)]
pub enum BenchCmd {
    /// Pipelines of 128 TMs at several activities.
    Kernel(ScaleArgs),
    /// The memory model's replay speed.
    Dram(ScaleArgs),
    /// Every faster mode's wall time and error against the full cycle model on a scene.
    // Boxed: its two dozen flags would size every variant (clippy::large_enum_variant).
    SpeedError(Box<SpeedErrorArgs>),
    /// One lane, one per core and auto, idle and beside a busy process, on --scene.
    Threads(ThreadsArgs),
    /// What a waveform costs: a cycle frame untraced, then traced whole and
    /// as scheduler,tm0 over a window, as VCD and FST.
    Trace(TraceArgs),
    /// The competing process of `bench threads` (spins until killed).
    #[command(hide = true)]
    Busy,
    // Any other name: refused with the list of benchmarks (clap would not list them).
    #[command(external_subcommand)]
    Unknown(Vec<String>),
}

#[derive(Args)]
pub struct ScaleArgs {
    /// Scale the simulated cycles (1.0 = the full benchmark).
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
}

impl ScaleArgs {
    fn checked(&self) -> Result<f64, CliError> {
        if self.scale.is_nan() || self.scale <= 0.0 {
            return Err(CliError::Usage("--scale must be positive".into()));
        }
        Ok(self.scale)
    }
}

#[derive(Args)]
pub struct ThreadsArgs {
    /// The scene (builtin name, .toml or .obj).
    #[arg(long, default_value = "cornell")]
    scene: String,
    /// The cases, comma-separated (cycle64, cycle256, windows1024). Default: all.
    #[arg(long)]
    modes: Option<String>,
    /// Write the runs as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Args)]
pub struct TraceArgs {
    /// The scene (builtin name, .toml or .obj; default: the render default).
    #[arg(long, default_value = dualstream::scene::DEFAULT_SCENE)]
    scene: String,
    /// Resolution WxH.
    #[arg(long, default_value = "32x32")]
    res: String,
    /// First core cycle traced.
    #[arg(long, default_value_t = 20000)]
    from: u64,
    /// The core cycle the window ends before.
    #[arg(long, default_value_t = 40000)]
    to: u64,
    /// Write the runs as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(Args)]
pub struct SpeedErrorArgs {
    #[command(flatten)]
    threads: super::ThreadsArg,
    /// The scene (builtin name, .toml or .obj).
    #[arg(long, default_value = "cornell")]
    scene: String,
    /// Resolution WxH.
    #[arg(long, default_value = "64x64")]
    res: String,
    /// TMs of the small-chip mode.
    #[arg(long, default_value_t = 8)]
    small_tms: u32,
    /// The modes to run besides the reference, comma-separated (cycle-fixed,
    /// functional+estimate, small-chip, small-chips-fit, quarter-pixels,
    /// sampled, windows). Default: all.
    #[arg(long)]
    modes: Option<String>,
    /// sampled: keep one tile in this many per sample.
    #[arg(long, default_value_t = 16)]
    sample_every: u32,
    /// sampled: tile side in pixels.
    #[arg(long, default_value_t = 16)]
    tile: u32,
    /// sampled: disjoint samples, each a cycle run (2 or more estimate the
    /// sampling error).
    #[arg(long, default_value_t = 2)]
    subsets: u32,
    /// Compare with this finished reference instead of rendering one: the
    /// --stats JSON of `render --mode cycle` with GDDR5 on the same scene,
    /// resolution and config.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// With --reference: that run's PNG, to check the modes' images (as 8-bit
    /// sRGB).
    #[arg(long, requires = "reference")]
    reference_image: Option<PathBuf>,
    /// With --reference: that run's --pass-log CSV, to check the windows
    /// mode's estimate part by part (a reference the bench renders itself is
    /// checked so without it).
    #[arg(long, requires = "reference")]
    reference_passes: Option<PathBuf>,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the speedup-against-error plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    // Last: clap lists what follows a flattened struct under its heading.
    #[command(flatten)]
    windows: WindowArgs,
}

/// The time-sampling plan of the windows mode (docs/speed-error.md), one flag
/// a field of [`WindowPlan`]; the defaults are `default_windows()`, what
/// `render --mode windows` and `report --mode windows` use.
#[derive(Args)]
#[command(next_help_heading = "Windows mode (time sampling)")]
pub struct WindowArgs {
    /// A window's measurement starts every this many segment passes of a
    /// wavefront (after its head).
    #[arg(long, default_value_t = sampling::default_windows().every)]
    window_every: u64,
    /// Admissions measured from each wavefront's start: the root pass (by its
    /// root window), then the next ones simulated whole.
    #[arg(long, default_value_t = sampling::default_windows().head)]
    window_head: u64,
    /// Rays of each wavefront's root window (a shorter root pass whole, a
    /// longer one over one run of 8 rays in k of its queue, packed).
    #[arg(long, default_value_t = sampling::default_windows().root_rays)]
    window_root_rays: u64,
    /// The same for the later wavefronts' root windows (the primary rays'
    /// root pass needs a longer sample).
    #[arg(long, default_value_t = sampling::default_windows().bounce_root_rays)]
    window_bounce_root_rays: u64,
    /// Rays of a short wavefront's sample (one with too few passes for a
    /// window): a longer one is traced from its root pass to its end over one
    /// run of up to 1024 rays in k of its root queue, hashed, hit records in
    /// place (0: simulated whole after its root window).
    #[arg(long, default_value_t = sampling::default_windows().wave_rays)]
    window_wave_rays: u64,
    /// Sampled short wavefronts from the second to this one also simulated
    /// whole; the ratio of whole to sample corrects the other sampled ones
    /// (0: none).
    #[arg(long, default_value_t = sampling::default_windows().wave_whole)]
    window_wave_whole: u64,
    /// A short wavefront's sample runs on this share of the L2 (its rays come
    /// back to their hit records k times sooner).
    #[arg(long, default_value_t = sampling::default_windows().wave_l2_share)]
    window_wave_l2: u32,
    /// A short wavefront is sampled only if its sample's ray lines per pass
    /// reach this share of a segment's (else its passes are bound by the
    /// scene stream; it is simulated whole).
    #[arg(long, default_value_t = sampling::default_windows().wave_ray_share)]
    window_wave_ray_share: f64,
    /// Each wavefront's tail, from the first boundary with at most this many
    /// queues holding rays, simulated to its end (0: none, the tail scaled
    /// like the rest).
    #[arg(long, default_value_t = sampling::default_windows().tail_pending)]
    window_tail: u64,
    /// Admissions the tail window runs unmeasured first (counted in the rest).
    #[arg(long, default_value_t = sampling::default_windows().tail_warm)]
    window_tail_warm: u64,
    /// Wavefronts traced in windows: the first, the last and every N-th from
    /// the second on (1: all); the others take their trace's cycles, lines
    /// and energy from their functional work times the ratios of the nearest
    /// measured ones (their shading passes keep their windows). Above 1, a
    /// wavefront too short for windows and traced over a sample borrows from
    /// the fourth on, from the sampled ones from the third on, while its rays
    /// are alike the last measured one's.
    #[arg(long, default_value_t = sampling::default_windows().wave_every)]
    window_waves: u64,
    /// Segment passes the chip runs before a window's measurement,
    /// unmeasured, to fill its buffers, caches and queues and stagger its 64
    /// scene-buffer slots (docs/speed-error.md: too short a warm-up leaves
    /// every window fast).
    #[arg(long, default_value_t = sampling::default_windows().warm)]
    window_warm: u64,
    /// Segment passes measured per window.
    #[arg(long, default_value_t = sampling::default_windows().measure)]
    window_measure: u64,
    /// Shading windows per shading pass (and of the ray generation: one).
    #[arg(long, default_value_t = sampling::default_windows().shade_windows)]
    shade_windows: u32,
    /// Shading items (pixels) a shading window runs before its measurement.
    #[arg(long, default_value_t = sampling::default_windows().shade_warm)]
    shade_warm: u64,
    /// Cycles a shading window runs at least before its measurement (with
    /// --shade-warm items).
    #[arg(long, default_value_t = sampling::default_windows().shade_warm_cycles)]
    shade_warm_cycles: u64,
    /// Shading items measured per shading window.
    #[arg(long, default_value_t = sampling::default_windows().shade_measure)]
    shade_measure: u64,
    /// Items of each shading pass simulated from its start as they are (the
    /// start-up phase, which windows do not see).
    #[arg(long, default_value_t = sampling::default_windows().shade_head)]
    shade_head: u64,
    /// Write every window (kind, position, warm-up and measured counts, the
    /// segment passes it retired) and the functional model's segment passes
    /// as JSON here.
    #[arg(long)]
    window_log: Option<PathBuf>,
}

impl WindowArgs {
    fn plan(&self) -> WindowPlan {
        WindowPlan {
            every: self.window_every,
            head: self.window_head,
            root_rays: self.window_root_rays,
            bounce_root_rays: self.window_bounce_root_rays,
            wave_rays: self.window_wave_rays,
            wave_whole: self.window_wave_whole,
            wave_l2_share: self.window_wave_l2,
            wave_ray_share: self.window_wave_ray_share,
            tail_pending: self.window_tail,
            tail_warm: self.window_tail_warm,
            wave_every: self.window_waves,
            warm: self.window_warm,
            measure: self.window_measure,
            shade_windows: self.shade_windows,
            shade_warm: self.shade_warm,
            shade_warm_cycles: self.shade_warm_cycles,
            shade_measure: self.shade_measure,
            shade_head: self.shade_head,
        }
    }
}

pub fn bench(config: Config, cmd: BenchCmd) -> Result<(), CliError> {
    match cmd {
        BenchCmd::Kernel(s) => print!("{}", dualstream::bench::kernel_report(s.checked()?)),
        BenchCmd::Dram(s) => print!("{}", dualstream::mem::bench::report(s.checked()?)?),
        BenchCmd::SpeedError(a) => speed_error(&config, a.threads.get()?, *a)?,
        BenchCmd::Threads(a) => threads_bench(&config, a)?,
        BenchCmd::Trace(a) => trace_bench(&config, a)?,
        BenchCmd::Busy => dualstream::bench::threads::busy(),
        BenchCmd::Unknown(args) => {
            return Err(CliError::Usage(format!(
                "unknown benchmark '{}'; available: kernel, dram, speed-error, threads, trace",
                args.first().map_or("", String::as_str)
            )));
        }
    }
    Ok(())
}

/// `dualstream bench threads`: every case on one lane, on one per core and on
/// auto, idle and beside a busy process.
fn threads_bench(config: &Config, a: ThreadsArgs) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    use dualstream::bench::threads as bt;
    let cases = bt::cases(a.modes.as_deref())?;
    let mut bar: Option<Meter> = None;
    let runs = bt::run(&a.scene, config, &cases, &mut |k, n, what| {
        bar.get_or_insert_with(|| Meter::new("bench threads", n as u64))
            .set(k as u64, || format!("run {}/{n}: {what}", k + 1));
    })?;
    if let Some(b) = bar {
        b.finish("done");
    }
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
        let run = RunParams {
            scene: Some(a.scene.clone()),
            ..RunParams::default()
        };
        write_json(config, run, started, &runs, &p)?;
    }
    Ok(())
}

/// `dualstream bench trace`: the tracer's cost on a cycle frame.
fn trace_bench(config: &Config, a: TraceArgs) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    use dualstream::bench::trace as bt;
    if a.to <= a.from {
        return Err(CliError::Usage(format!(
            "--to ({}) must be after --from ({}): give the window's first and last core cycle",
            a.to, a.from
        )));
    }
    let mut sc = dualstream::scene::load(&a.scene)?;
    (sc.settings.width, sc.settings.height) = parse_res(&a.res)?;
    sc.settings.validate()?;
    let mut bar: Option<Meter> = None;
    let runs = bt::run(&sc, config, a.from, a.to, &mut |k, n, what| {
        bar.get_or_insert_with(|| Meter::new("bench trace", n as u64))
            .set(k as u64, || format!("run {}/{n}: {what}", k + 1));
    })?;
    if let Some(b) = bar {
        b.finish("done");
    }
    println!(
        "bench trace: {} {} on {} TMs, core cycles {}..{} traced; ratio: wall time over the untraced frame's; changes/s: over the tracing's own time (traced minus untraced)",
        a.scene, a.res, config.chip.tms, a.from, a.to
    );
    print!("{}", bt::table(&runs));
    if let Some(p) = a.json {
        let run = RunParams {
            scene: Some(a.scene.clone()),
            resolution: Some([sc.settings.width, sc.settings.height]),
            mode: Some("cycle".into()),
            threads: Some("1".into()),
            ..RunParams::default()
        };
        write_json(config, run, started, &runs, &p)?;
    }
    Ok(())
}

/// `dualstream bench speed-error`: the faster modes against the cycle model
/// (rendered here, or a finished one given with --reference).
fn speed_error(config: &Config, threads: Threads, a: SpeedErrorArgs) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    let mut sc = dualstream::scene::load(&a.scene)?;
    (sc.settings.width, sc.settings.height) = parse_res(&a.res)?;
    sc.settings.validate()?;
    let reference = match &a.reference {
        Some(p) => {
            let mut r = speed_error::Reference::load(p, a.reference_image.as_deref(), &sc, config)?;
            if let Some(csv) = &a.reference_passes {
                r.read_passes(csv)?;
            }
            Some(r)
        }
        None => None,
    };
    let opts = speed_error::SpeedErrorOpts {
        reference,
        small_tms: a.small_tms,
        sample_every: a.sample_every,
        tile: a.tile,
        subsets: a.subsets,
        modes: a
            .modes
            .map(|m| m.split(',').map(|x| x.trim().to_string()).collect()),
        threads,
        windows: a.windows.plan(),
        window_log: a.windows.window_log,
    };
    let mut bar: Option<Meter> = None;
    let rows = speed_error::run_progress(&sc, config, &opts, &mut |k, n, what| {
        bar.get_or_insert_with(|| Meter::new("bench speed-error", n as u64))
            .set(k as u64, || format!("run {}/{n}: {what}", k + 1));
    })?;
    if let Some(b) = bar {
        b.finish("done");
    }
    println!(
        "speed against error: {} {}x{} on {} x {} TPs (reference: cycle mode, GDDR5)",
        sc.name, sc.settings.width, sc.settings.height, config.chip.tms, config.tm.tps
    );
    print!("{}", speed_error::table(&rows));
    for r in rows.iter().filter(|r| !r.by_part.is_empty()) {
        print!("{}", speed_error::part_table(&r.by_part));
    }
    if let Some(p) = a.json {
        let run = RunParams {
            scene: Some(a.scene.clone()),
            resolution: Some([sc.settings.width, sc.settings.height]),
            seed: Some(sc.settings.seed),
            bounces: Some(sc.settings.bounces),
            threads: Some(a.threads.threads.clone()),
            ..RunParams::default()
        };
        write_json(config, run, started, &rows, &p)?;
    }
    if let Some(p) = a.plot {
        write_file(&p, speed_error::plot(&rows))?;
    }
    Ok(())
}

/// A benchmark's rows as JSON under `runs`, after the run's header.
fn write_json(
    config: &Config,
    run: RunParams,
    started: std::time::Instant,
    rows: &impl serde::Serialize,
    path: &std::path::Path,
) -> Result<(), CliError> {
    let header = RunHeader::new(config, run, started.elapsed().as_secs_f64());
    let v = HeadedList {
        header: &header,
        key: "runs",
        body: rows,
    };
    let text = serde_json::to_string_pretty(&v).map_err(|e| CliError::Failed(e.to_string()))?;
    write_file(path, text)
}
