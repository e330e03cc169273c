//! The dualstream command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use dualstream::config::Config;
use dualstream::rtl::{SimOptions, Threads, TraceSpec};
use dualstream::testbench::{self, TbOptions};

#[derive(Parser)]
#[command(
    name = "dualstream",
    version,
    about = "Cycle-level model of the Dual Streaming ray-tracing hardware (HPG 2017)"
)]
struct Cli {
    /// Configuration file (TOML); missing keys take the paper's values.
    #[arg(long, global = true)]
    config: Option<PathBuf>,
    /// Simulator threads: `auto` (the default) or 1 up to the machine's cores.
    /// Cycle mode spreads the TMs over N lanes (auto measures the run and uses
    /// one lane while more do not pay); time sampling runs N windows side by
    /// side (auto: one per core). Results are bit-identical for every choice.
    #[arg(long, global = true, default_value = "auto", value_name = "auto|N")]
    threads: String,
    /// The chip's memory in cycle mode: gddr5 (the paper's 16-channel GDDR5,
    /// the default) or fixed (a fixed latency and bandwidth: faster to think
    /// about, not the paper's figures). Overrides `[chip.memory] model`.
    #[arg(long, global = true, value_parser = ["gddr5", "fixed"])]
    memory: Option<String>,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a unit testbench: random stimulus, scoreboard against the reference, optional VCD.
    Tb {
        /// Unit to test: box_pipe, tri_pipe, divider or tm.
        unit: String,
        /// Cycles of stimulus (the bench then drains).
        #[arg(long, default_value_t = 10_000)]
        cycles: u64,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Probability that the consumer is ready in a cycle (back-pressure below 1).
        #[arg(long, default_value_t = 0.8)]
        ready: f64,
        /// Probability of a new request per cycle.
        #[arg(long, default_value_t = 0.5)]
        load: f64,
        /// Write a VCD waveform here.
        #[arg(long)]
        vcd: Option<PathBuf>,
        /// Units to trace (comma-separated instance patterns, `*` wildcard).
        #[arg(long, default_value = "")]
        trace: String,
        /// First core cycle to trace.
        #[arg(long, default_value_t = 0)]
        trace_from: u64,
        /// Last core cycle to trace.
        #[arg(long)]
        trace_to: Option<u64>,
        /// The most the waveform may take (bytes, or with K, M, G; 0: no
        /// limit): a larger one is refused or stopped, and its file removed.
        #[arg(long, default_value = "1G")]
        trace_max_bytes: String,
        /// Evaluate every unit every cycle (no sleeping): slower, same results.
        #[arg(long)]
        no_sleep: bool,
        /// Also evaluate sleeping units and fail if that would change anything.
        #[arg(long)]
        shadow: bool,
        /// tm: scene (builtin name, `builtin:NAME`, .toml or .obj).
        #[arg(long, default_value = dualstream::scene::DEFAULT_SCENE)]
        scene: String,
        /// tm: the treelet (segment id) whose primary rays the TM traverses.
        #[arg(long, default_value_t = 0)]
        treelet: u32,
        /// tm: ideal memory latency behind the L1 miss port (cycles).
        #[arg(long, default_value_t = 20)]
        mem_latency: u32,
        /// tm: use only the first N rays of the treelet.
        #[arg(long)]
        rays: Option<usize>,
        /// tm: resolution WIDTHxHEIGHT (default: the scene's).
        #[arg(long)]
        res: Option<String>,
    },
    /// Render a frame: dual streaming (functional) or the reference traversal.
    Render {
        /// Builtin scene name, scene description (.toml) or Wavefront .obj.
        #[arg(long, default_value = dualstream::scene::DEFAULT_SCENE)]
        scene: String,
        /// Resolution WIDTHxHEIGHT (default: the scene's).
        #[arg(long)]
        res: Option<String>,
        /// functional (dual streaming, no clock), reference (the plain
        /// traversal), cycle (the chip, clocked; GDDR5 with `[chip.memory] model
        /// = "gddr5"`) or windows (time sampling: the functional frame, and the
        /// chip with GDDR5 simulated in windows whose figures estimate the cycle
        /// model's; within 3% of it on the paper scenes, docs/speed-error.md).
        #[arg(long, default_value = "functional")]
        mode: String,
        /// Hit points per path (default: the scene's, 5 as in the paper).
        #[arg(long)]
        bounces: Option<u32>,
        #[arg(long)]
        seed: Option<u64>,
        /// Output image (PNG).
        #[arg(long, default_value = "render.png")]
        out: PathBuf,
        /// Write the statistics as JSON here.
        #[arg(long)]
        stats: Option<PathBuf>,
        /// Check every ray against the reference traversal.
        #[arg(long)]
        verify: bool,
        /// Write each wavefront's rays and hit records into this directory.
        #[arg(long)]
        dump_rays: Option<PathBuf>,
        /// cycle: write every segment pass (chip run, segment, rays, admission
        /// and retirement cycle) as CSV here.
        #[arg(long)]
        pass_log: Option<PathBuf>,
        /// cycle: write a VCD waveform of the chip here (open with gtkwave).
        #[arg(long)]
        vcd: Option<PathBuf>,
        /// cycle: units to trace, comma-separated: scheduler, scene_buffer,
        /// hit_updater, memory, mem_ctrl (every channel) or mem_ctrl<c>, tm<k> (a
        /// whole TM), tms, host, l2, or instance patterns (`chip.tm*.l1`, `*`
        /// wildcard). Default: every unit.
        #[arg(long, alias = "trace", default_value = "")]
        trace_units: String,
        /// cycle: core cycles to trace: A..B (B excluded), A..=B or A.. (to the end).
        #[arg(long, conflicts_with_all = ["trace_from", "trace_to"])]
        trace_window: Option<String>,
        /// cycle: first core cycle to trace (same as --trace-window A..).
        #[arg(long)]
        trace_from: Option<u64>,
        /// cycle: last core cycle to trace, included.
        #[arg(long)]
        trace_to: Option<u64>,
        /// The most a waveform may take (bytes, or with K, M, G; 0: no limit):
        /// a larger one is refused before it starts or stopped when it gets
        /// there, and its file removed.
        #[arg(long, default_value = "1G")]
        trace_max_bytes: String,
    },
    /// Our figures next to the paper's (Table 2) for Dragon, Dragon Box and Sponza.
    Report {
        /// What to report: paper.
        what: String,
        /// Resolution (the paper's is 1024x1024).
        #[arg(long, default_value = "1024x1024")]
        res: String,
        /// Directory of the scene files (dragon.toml, dragon_box.toml, dabrovic_sponza.toml).
        #[arg(long, default_value = "scenes")]
        scenes_dir: PathBuf,
        /// Write the comparison as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write paper-style figures (SVG) into this directory.
        #[arg(long)]
        plots: Option<PathBuf>,
        /// functional (counts only, fast), cycle (the chip with GDDR5: also
        /// render time, rays/s, bandwidth and DRAM energy; about an hour for the
        /// three scenes at 1024x1024) or windows (time sampling: the cycle
        /// model's figures estimated from windows of the chip, within 3% of it
        /// on these scenes (docs/speed-error.md), in minutes; same image).
        #[arg(long, default_value = "functional")]
        mode: String,
    },
    /// Scene tools.
    Scene {
        #[command(subcommand)]
        cmd: SceneCmd,
    },
    /// Write the Verilog skeleton of every unit.
    Hdl {
        #[arg(long, default_value = "hdl")]
        out: PathBuf,
    },
    /// Measure the simulator: kernel (pipelines of 128 TMs at several activities),
    /// dram (the memory model's replay speed), speed-error (every faster mode's wall
    /// time and error against the full cycle model on a scene), threads (one lane,
    /// one per core and auto, idle and beside a busy process, on --scene).
    Bench {
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
        #[arg(long, default_value_t = dualstream::sampling::default_windows().every)]
        window_every: u64,
        /// speed-error, windows: admissions measured from each wavefront's start:
        /// the root pass (by its root window), then the next ones simulated whole.
        #[arg(long, default_value_t = dualstream::sampling::default_windows().head)]
        window_head: u64,
        /// speed-error, windows: rays of each wavefront's root window (a shorter
        /// root pass whole, a longer one over one run of 8 rays in k of its
        /// queue, packed).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().root_rays)]
        window_root_rays: u64,
        /// speed-error, windows: the same for the later wavefronts' root
        /// windows (the primary rays' root pass needs a longer sample).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().bounce_root_rays)]
        window_bounce_root_rays: u64,
        /// speed-error, windows: rays of a short wavefront's sample (one with
        /// too few passes for a window): a longer one is traced from its root
        /// pass to its end over one run of up to 1024 rays in k of its root
        /// queue, hashed, hit records in place (0: simulated whole after its
        /// root window).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().wave_rays)]
        window_wave_rays: u64,
        /// speed-error, windows: sampled short wavefronts from the second to
        /// this one also simulated whole; the ratio of whole to sample corrects
        /// the other sampled ones (0: none).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().wave_whole)]
        window_wave_whole: u64,
        /// speed-error, windows: a short wavefront's sample runs on this share
        /// of the L2 (its rays come back to their hit records k times sooner).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().wave_l2_share)]
        window_wave_l2: u32,
        /// speed-error, windows: a short wavefront is sampled only if its
        /// sample's ray lines per pass reach this share of a segment's (else
        /// its passes are bound by the scene stream; it is simulated whole).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().wave_ray_share)]
        window_wave_ray_share: f64,
        /// speed-error, windows: each wavefront's tail, from the first boundary
        /// with at most this many queues holding rays, simulated to its end (0:
        /// none, the tail scaled like the rest).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().tail_pending)]
        window_tail: u64,
        /// speed-error, windows: admissions the tail window runs unmeasured
        /// first (counted in the rest).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().tail_warm)]
        window_tail_warm: u64,
        /// speed-error, windows: wavefronts traced in windows: the first, the
        /// last and every N-th from the second on (1: all); the others take their
        /// trace's cycles, lines and energy from their functional work times the
        /// ratios of the nearest measured ones (their shading passes keep their
        /// windows). Above 1, a wavefront too short for windows and traced over a
        /// sample borrows from the fourth on, from the sampled ones from the third
        /// on, while its rays are alike the last measured one's.
        #[arg(long, default_value_t = dualstream::sampling::default_windows().wave_every)]
        window_waves: u64,
        /// speed-error, windows: segment passes the chip runs before a window's
        /// measurement, unmeasured, to fill its buffers, caches and queues and
        /// stagger its 64 scene-buffer slots (docs/speed-error.md: 64 leaves
        /// every window 12-19% fast at the paper's size, 96 does not).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().warm)]
        window_warm: u64,
        /// speed-error, windows: segment passes measured per window.
        #[arg(long, default_value_t = dualstream::sampling::default_windows().measure)]
        window_measure: u64,
        /// speed-error, windows: shading windows per shading pass (and of the
        /// ray generation: one).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().shade_windows)]
        shade_windows: u32,
        /// speed-error, windows: shading items (pixels) a shading window runs
        /// before its measurement.
        #[arg(long, default_value_t = dualstream::sampling::default_windows().shade_warm)]
        shade_warm: u64,
        /// speed-error, windows: cycles a shading window runs at least before
        /// its measurement (with --shade-warm items).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().shade_warm_cycles)]
        shade_warm_cycles: u64,
        /// speed-error, windows: shading items measured per shading window.
        #[arg(long, default_value_t = dualstream::sampling::default_windows().shade_measure)]
        shade_measure: u64,
        /// speed-error, windows: items of each shading pass simulated from its
        /// start as they are (the start-up phase, which windows do not see).
        #[arg(long, default_value_t = dualstream::sampling::default_windows().shade_head)]
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
    },
    /// The memory system: replay a DRAMsim3-format trace and print statistics, or
    /// generate a trace (random, stream, mixed).
    Dram {
        /// Replay this trace (`<hex address> <READ|WRITE> <cycle>` per line).
        #[arg(long)]
        trace: Option<PathBuf>,
        /// Memory preset: paper (16 x 32-bit GDDR5, the default) or dramsim3-gddr5
        /// (DRAMsim3 running its GDDR5_8Gb_x32.ini: its device and its controller
        /// rules). Without it, the config's [mem] is used.
        #[arg(long)]
        preset: Option<String>,
        /// Energy preset: paper, physical or dramsim3 (default: the preset's own).
        #[arg(long)]
        energy: Option<String>,
        /// Record the DRAM commands and run the independent timing checker.
        #[arg(long)]
        check: bool,
        /// Generate a trace: random, stream or mixed (written to --out, or replayed).
        #[arg(long)]
        generate: Option<String>,
        /// Requests to generate.
        #[arg(long, default_value_t = 100_000)]
        requests: u64,
        /// Where to write the generated trace.
        #[arg(long)]
        out: Option<PathBuf>,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// DRAM cycles between generated requests (0: all at cycle 0, unthrottled).
        #[arg(long, default_value_t = 0)]
        interval: u64,
        /// Fraction of generated random/stream requests that are writes.
        #[arg(long, default_value_t = 0.0)]
        write_fraction: f64,
    },
    /// Show the configuration.
    Config {
        /// Print the default configuration as TOML.
        #[arg(long)]
        print_default: bool,
    },
}

#[derive(Subcommand)]
enum SceneCmd {
    /// Triangles, BVH nodes and depth, segments, bytes, children per segment, build time.
    Info {
        /// Builtin scene name, scene description (.toml) or Wavefront .obj.
        scene: String,
    },
}

/// Says that the BVH came from the fallback builder, and why.
fn bvh_fallback_warning(why: &str) -> String {
    format!(
        "BVH: {why}; built with the binned-SAH fallback instead (bounded in time and depth). \
         Meshes of long, thin, overlapping triangles do this, e.g. a large polygon \
         triangulated as a fan"
    )
}

fn parse_res(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("--res '{s}' is not WIDTHxHEIGHT (e.g. 256x256)");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// A size in bytes with an optional K, M or G (powers of 1024).
fn parse_size(s: &str, flag: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mul) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => (
            &t[..i],
            match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                _ => 0,
            },
        ),
        _ => (t, 1),
    };
    match num.trim().parse::<u64>() {
        Ok(n) if mul > 0 => n.checked_mul(mul).ok_or(()),
        _ => Err(()),
    }
    .map_err(|()| format!("{flag} {s}: give a size in bytes, e.g. 500M or 2G (0: no limit)"))
}

/// `--threads`, checked.
fn sim_threads(threads: &str) -> Result<Threads, String> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if threads == "auto" {
        return Ok(Threads::auto());
    }
    match threads.parse::<usize>() {
        Ok(n) if (1..=cores).contains(&n) => Ok(Threads::fixed(n)),
        Ok(n) => Err(format!(
            "--threads {n}: this machine has {cores} core(s); give --threads auto or a number from 1 to {cores}"
        )),
        Err(_) => Err(format!(
            "--threads {threads}: not a number; give --threads auto or a number from 1 to {cores}"
        )),
    }
}

fn render_cfg(config: &Config, threads: Threads) -> dualstream::render::RenderCfg {
    dualstream::render::RenderCfg::for_chip(config, threads.sim())
}

fn load_config(path: &Option<PathBuf>) -> Result<Config, String> {
    match path {
        Some(p) => Config::load(p),
        None => Ok(Config::default()),
    }
}

fn run(cli: Cli) -> Result<(), String> {
    let mut config = load_config(&cli.config)?;
    if let Some(m) = &cli.memory {
        config.chip.memory.model = dualstream::machine::config::MemoryModel::parse(m)?;
    }
    let threads = sim_threads(&cli.threads)?;
    match cli.cmd {
        Cmd::Tb {
            unit,
            cycles,
            seed,
            ready,
            load,
            vcd,
            trace,
            trace_from,
            trace_to,
            trace_max_bytes,
            no_sleep,
            shadow,
            scene,
            treelet,
            mem_latency,
            rays,
            res,
        } => {
            let p = config.clocks.core_ps;
            let spec = TraceSpec {
                filter: trace,
                from: trace_from.saturating_mul(p),
                to: trace_to.map_or(u64::MAX, |c| c.saturating_mul(p)),
                max_bytes: parse_size(&trace_max_bytes, "--trace-max-bytes")?,
            };
            spec.validate().map_err(|e| {
                e.replace(" (", " (ps ")
                    .replace("trace window", "--trace-from/--trace-to: trace window")
            })?;
            let opts = TbOptions {
                cycles,
                seed,
                ready_p: ready,
                load,
                vcd: vcd.clone(),
                trace: spec,
                sim: SimOptions {
                    sleep: !no_sleep,
                    shadow,
                    shuffle_seed: None,
                    threads: 1,
                    auto_lanes: false,
                },
                config,
            };
            let start = std::time::Instant::now();
            if unit == "tm" {
                let topts = testbench::tm_tb::TmTbOptions {
                    scene,
                    treelet,
                    res: res.as_deref().map(parse_res).transpose()?,
                    max_rays: rays,
                    run: testbench::tm_tb::RunOptions {
                        mem_latency,
                        sim: opts.sim.clone(),
                        trace: opts.trace.clone(),
                        log: false,
                    },
                    vcd: vcd.clone(),
                    config: opts.config.clone(),
                };
                let rep = testbench::tm_tb::run(&topts)?;
                print!("{rep}");
                println!("  wall time {:.3} s", start.elapsed().as_secs_f64());
                if let Some(v) = vcd {
                    println!(
                        "  waveform: {} (open with: gtkwave {})",
                        v.display(),
                        v.display()
                    );
                }
                return if rep.passed() {
                    Ok(())
                } else {
                    Err("the TM testbench failed".into())
                };
            }
            let rep = testbench::run_by_name(&unit, &opts)?;
            print!("{rep}");
            println!("  wall time {:.3} s", start.elapsed().as_secs_f64());
            if let Some(v) = vcd {
                println!(
                    "  waveform: {} (open with: gtkwave {})",
                    v.display(),
                    v.display()
                );
            }
            if !rep.passed() {
                return Err(format!(
                    "testbench {unit} failed with {} errors",
                    rep.errors.len()
                ));
            }
            Ok(())
        }
        Cmd::Render {
            scene,
            res,
            mode,
            bounces,
            seed,
            out,
            stats,
            verify,
            dump_rays,
            pass_log,
            vcd,
            trace_units,
            trace_window,
            trace_from,
            trace_to,
            trace_max_bytes,
        } => {
            use dualstream::render::{self, Mode, output};
            let sampled = mode == "windows";
            let mode = match mode.as_str() {
                "functional" | "windows" => dualstream::render::Mode::Functional,
                "reference" => Mode::Reference,
                "cycle" => dualstream::render::Mode::Cycle,
                m => {
                    return Err(format!(
                        "unknown --mode '{m}'; use functional, reference, cycle or windows"
                    ));
                }
            };
            let mut sc = dualstream::scene::load(&scene)?;
            for w in &sc.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(r) = res {
                (sc.settings.width, sc.settings.height) = parse_res(&r)?;
            }
            if let Some(b) = bounces {
                sc.settings.bounces = b;
            }
            if let Some(s) = seed {
                sc.settings.seed = s;
            }
            sc.settings.validate()?;
            let traced = !trace_units.is_empty()
                || trace_window.is_some()
                || trace_from.is_some()
                || trace_to.is_some();
            if traced && vcd.is_none() {
                return Err(
                    "--trace-units/--trace-window choose what goes into a waveform: add --vcd FILE"
                        .into(),
                );
            }
            if vcd.is_some() && mode != Mode::Cycle {
                return Err("--vcd traces the chip: add --mode cycle".into());
            }
            let (from, to) = match &trace_window {
                Some(w) => dualstream::machine::trace::parse_window(w)?,
                None => (trace_from.unwrap_or(0), trace_to),
            };
            if let Some(t) = to
                && t < from
            {
                return Err(format!(
                    "--trace-from {from} --trace-to {t}: the trace window ends before it starts"
                ));
            }
            // Fail on an unwritable output before spending minutes on the frame.
            for (p, what) in [
                (Some(&out), "--out"),
                (stats.as_ref(), "--stats"),
                (vcd.as_ref(), "--vcd"),
            ] {
                if let Some(p) = p {
                    std::fs::OpenOptions::new()
                        .create(true)
                        .append(true)
                        .open(p)
                        .map_err(|e| {
                            format!(
                                "cannot write '{}': {e}; choose a writable {what}",
                                p.display()
                            )
                        })?;
                }
            }
            let mut rc = render_cfg(&config, threads);
            if let (Some(path), Some(run)) = (&vcd, rc.chip.as_mut()) {
                run.trace = Some(render::ChipTrace {
                    path: path.clone(),
                    units: trace_units,
                    from,
                    to,
                    max_bytes: parse_size(&trace_max_bytes, "--trace-max-bytes")?,
                });
            }
            if mode == Mode::Cycle
                && let Some(note) = render::long_frame_note(&sc.settings, config.chip.tms)
            {
                eprintln!("note: {note}");
            }
            rc.verify = verify;
            rc.dump_rays = dump_rays;
            if pass_log.is_some() && mode != Mode::Cycle {
                return Err(
                    "--pass-log records the chip's segment passes; use it with --mode cycle".into(),
                );
            }
            rc.pass_log = pass_log.is_some();
            let bar = indicatif::ProgressBar::new((sc.settings.bounces as u64 + 1) * 1000);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40}] {msg} (ETA {eta})",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            let (mut frame, estimate) = if sampled {
                bar.finish_and_clear();
                eprintln!("time sampling (windows of the chip with GDDR5)...");
                let plan = dualstream::sampling::default_windows();
                let ts = dualstream::sampling::time_sampled_with(&sc, &config, rc, &plan)?;
                (ts.frame, Some(ts.estimate))
            } else {
                let f = render::render(&sc, mode, &rc, &mut |p: &render::Progress| {
                    let frac = (p.done * 1000).checked_div(p.known).unwrap_or(0);
                    bar.set_position(p.wave as u64 * 1000 + frac);
                    bar.set_message(format!(
                        "wavefront {}/{}: {} rays",
                        p.wave, p.waves_max, p.rays
                    ));
                })?;
                bar.finish_and_clear();
                (f, None)
            };
            // A time-sampled frame's energy is the estimate's (below), not the
            // functional model's TMs-only figure.
            if mode != Mode::Reference && !sampled {
                frame.energy = Some(dualstream::energy::frame_energy(&config, &frame));
            }
            output::write_png(&frame, &out)?;
            if let Some(path) = &pass_log {
                output::write_pass_log(&frame, path)?;
            }
            if let Some(why) = &frame.accel.bvh_fallback {
                eprintln!("warning: {}", bvh_fallback_warning(why));
            }
            print!("{}", output::summary(&frame));
            if let Some(e) = &estimate {
                print!("{}", dualstream::sampling::window_summary(e));
            }
            println!("image: {}", out.display());
            if let (Some(p), Some(v)) = (&vcd, frame.chip.as_ref().and_then(|c| c.vcd)) {
                println!(
                    "waveform: {} ({} units, {} signals, {} changes; open with: gtkwave {})",
                    p.display(),
                    v.units,
                    v.signals,
                    v.changes,
                    p.display()
                );
            }
            if let Some(p) = stats {
                match &estimate {
                    Some(e) => dualstream::sampling::write_json_estimated(&frame, e, &p)?,
                    None => output::write_json(&frame, &p)?,
                }
                println!("statistics: {}", p.display());
            }
            Ok(())
        }
        Cmd::Report {
            what,
            res,
            scenes_dir,
            json,
            plots,
            mode,
        } => {
            let sampled = mode == "windows";
            let mode = match mode.as_str() {
                "functional" | "windows" => dualstream::render::Mode::Functional,
                "cycle" => dualstream::render::Mode::Cycle,
                m => {
                    return Err(format!(
                        "unknown report mode '{m}'; use --mode functional, cycle or windows"
                    ));
                }
            };
            if what != "paper" {
                return Err(format!("unknown report '{what}'; available: paper"));
            }
            let (w, h) = parse_res(&res)?;
            let mut rows = Vec::new();
            for row in dualstream::report::paper::TABLE2.iter() {
                let path = scenes_dir.join(row.scene_file);
                let spec = path.to_str().ok_or("scene path is not UTF-8")?;
                let mut sc = dualstream::scene::load(spec).map_err(|e| {
                    format!("{e}\n(the paper scenes need the meshes in ../shared/scenes; run from the repository root or pass --scenes-dir)")
                })?;
                sc.settings.width = w;
                sc.settings.height = h;
                sc.settings.validate()?;
                let how = if sampled {
                    "time sampling".to_string()
                } else {
                    format!("{mode:?}")
                };
                eprintln!("rendering {} at {w}x{h} ({how})...", row.scene);
                let mut cfg = config.clone();
                if mode == dualstream::render::Mode::Cycle {
                    // Time, bandwidth and DRAM energy need the GDDR5 model.
                    cfg.chip.memory.model = dualstream::machine::config::MemoryModel::Gddr5;
                }
                let t0 = std::time::Instant::now();
                if sampled {
                    let plan = dualstream::sampling::default_windows();
                    let ts = dualstream::sampling::time_sampled(&sc, &cfg, threads, &plan)?;
                    let e = &ts.estimate;
                    eprintln!(
                        "  {:.1} s ({} windows, {:.0} s in the chips: {}){}",
                        t0.elapsed().as_secs_f64(),
                        e.windows,
                        e.chip_s,
                        dualstream::sampling::kind_times_text(&e.chip_s_by_kind),
                        e.se_text().map(|t| format!("; {t}")).unwrap_or_default()
                    );
                    rows.extend(dualstream::report::paper::compare_sampled(
                        row, &ts.frame, e,
                    ));
                    continue;
                }
                let mut frame =
                    dualstream::render::render(&sc, mode, &render_cfg(&cfg, threads), &mut |_| {})?;
                eprintln!("  {:.1} s", t0.elapsed().as_secs_f64());
                frame.energy = Some(dualstream::energy::frame_energy(&cfg, &frame));
                rows.extend(dualstream::report::paper::compare(row, &frame));
            }
            print!("{}", dualstream::report::paper::table(&rows));
            if let Some(p) = json {
                let text = serde_json::to_string_pretty(&rows).expect("rows serialise");
                std::fs::write(&p, text).map_err(|e| {
                    format!(
                        "cannot write '{}': {e}; choose a writable --json",
                        p.display()
                    )
                })?;
                println!("comparison: {}", p.display());
            }
            if let Some(dir) = plots {
                std::fs::create_dir_all(&dir).map_err(|e| {
                    format!(
                        "cannot create '{}': {e}; choose a writable --plots directory",
                        dir.display()
                    )
                })?;
                for (name, svg) in dualstream::report::paper::figures(&rows) {
                    let p = dir.join(name);
                    std::fs::write(&p, svg)
                        .map_err(|e| format!("cannot write '{}': {e}", p.display()))?;
                    println!("figure: {}", p.display());
                }
            }
            Ok(())
        }
        Cmd::Scene {
            cmd: SceneCmd::Info { scene },
        } => {
            let sc = dualstream::scene::load(&scene)?;
            for w in &sc.warnings {
                eprintln!("warning: {w}");
            }
            let p = dualstream::render::prepare(&sc, &render_cfg(&config, threads))?;
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
        Cmd::Hdl { out } => {
            for p in dualstream::units::write_hdl(&config, &out)? {
                println!("wrote {}", p.display());
            }
            Ok(())
        }
        Cmd::Bench {
            what,
            scale,
            scene,
            res,
            small_tms,
            modes,
            sample_every,
            tile,
            subsets,
            window_every,
            window_tail_warm,
            window_waves,
            window_head,
            window_root_rays,
            window_bounce_root_rays,
            window_wave_rays,
            window_wave_whole,
            window_wave_l2,
            window_wave_ray_share,
            window_tail,
            window_warm,
            window_measure,
            shade_windows,
            shade_warm,
            shade_warm_cycles,
            shade_measure,
            shade_head,
            window_log,
            reference,
            reference_image,
            reference_passes,
            json,
            plot,
        } => {
            if scale.is_nan() || scale <= 0.0 {
                return Err("--scale must be positive".into());
            }
            match what.as_str() {
                "kernel" => print!("{}", dualstream::bench::kernel_report(scale)),
                // The competing process of `bench threads` (spins until killed).
                "busy" => dualstream::bench::threads::busy(),
                "threads" => {
                    use dualstream::bench::threads as bt;
                    let cases = bt::cases(modes.as_deref())?;
                    let runs = bt::run(&scene, &config, &cases, &mut |what| {
                        eprintln!("bench threads: {what}")
                    })?;
                    println!(
                        "bench threads: {scene} on {} x {} TPs, memory {}, {} core(s); wall time of each frame",
                        config.chip.tms,
                        config.tm.tps,
                        config.chip.memory.model.name(),
                        std::thread::available_parallelism().map_or(1, |n| n.get())
                    );
                    print!("{}", bt::table(&runs));
                    if let Some(p) = json {
                        let text =
                            serde_json::to_string_pretty(&runs).map_err(|e| e.to_string())?;
                        std::fs::write(&p, text)
                            .map_err(|e| format!("cannot write '{}': {e}", p.display()))?;
                    }
                }
                "dram" => print!("{}", dualstream::mem::bench::report(scale)?),
                "speed-error" => {
                    use dualstream::sampling::speed_error as se;
                    let mut sc = dualstream::scene::load(&scene)?;
                    (sc.settings.width, sc.settings.height) = parse_res(&res)?;
                    sc.settings.validate()?;
                    let reference = match &reference {
                        Some(p) => {
                            let mut r =
                                se::Reference::load(p, reference_image.as_deref(), &sc, &config)?;
                            if let Some(csv) = &reference_passes {
                                r.read_passes(csv)?;
                            }
                            Some(r)
                        }
                        None => None,
                    };
                    let opts = se::SpeedErrorOpts {
                        reference,
                        small_tms,
                        sample_every,
                        tile,
                        subsets,
                        modes: modes.map(|m| m.split(',').map(|x| x.trim().to_string()).collect()),
                        threads,
                        windows: dualstream::sampling::WindowPlan {
                            every: window_every,
                            head: window_head,
                            root_rays: window_root_rays,
                            bounce_root_rays: window_bounce_root_rays,
                            wave_rays: window_wave_rays,
                            wave_whole: window_wave_whole,
                            wave_l2_share: window_wave_l2,
                            wave_ray_share: window_wave_ray_share,
                            tail_pending: window_tail,
                            tail_warm: window_tail_warm,
                            wave_every: window_waves,
                            warm: window_warm,
                            measure: window_measure,
                            shade_windows,
                            shade_warm,
                            shade_warm_cycles,
                            shade_measure,
                            shade_head,
                        },
                        window_log,
                    };
                    let rows = se::run(&sc, &config, &opts)?;
                    println!(
                        "speed against error: {} {}x{} on {} x {} TPs (reference: cycle mode, GDDR5)",
                        sc.name,
                        sc.settings.width,
                        sc.settings.height,
                        config.chip.tms,
                        config.tm.tps
                    );
                    print!("{}", se::table(&rows));
                    for r in rows.iter().filter(|r| !r.by_part.is_empty()) {
                        print!("{}", se::part_table(&r.by_part));
                    }
                    if let Some(p) = json {
                        let text =
                            serde_json::to_string_pretty(&rows).map_err(|e| e.to_string())?;
                        std::fs::write(&p, text)
                            .map_err(|e| format!("cannot write '{}': {e}", p.display()))?;
                    }
                    if let Some(p) = plot {
                        std::fs::write(&p, se::plot(&rows))
                            .map_err(|e| format!("cannot write '{}': {e}", p.display()))?;
                    }
                }
                _ => {
                    return Err(format!(
                        "unknown benchmark '{what}'; available: kernel, dram, speed-error, threads"
                    ));
                }
            }
            Ok(())
        }
        Cmd::Dram {
            trace,
            preset,
            energy,
            check,
            generate,
            requests,
            out,
            seed,
            interval,
            write_fraction,
        } => dram(
            config,
            DramArgs {
                trace,
                preset,
                energy,
                check,
                generate,
                requests,
                out,
                seed,
                interval,
                write_fraction,
            },
        ),
        Cmd::Config { print_default } => {
            if print_default {
                print!("{}", Config::default().to_toml());
            } else {
                print!("{}", config.to_toml());
            }
            Ok(())
        }
    }
}

struct DramArgs {
    trace: Option<PathBuf>,
    preset: Option<String>,
    energy: Option<String>,
    check: bool,
    generate: Option<String>,
    requests: u64,
    out: Option<PathBuf>,
    seed: u64,
    interval: u64,
    write_fraction: f64,
}

/// `dualstream dram`: generate and/or replay a trace on the memory model.
fn dram(mut config: Config, a: DramArgs) -> Result<(), String> {
    use dualstream::mem::{MemCfg, config::EnergyCfg, replay, trace};
    // The config as given must hold together (the DRAM image fits its device);
    // a preset then replaces the device for this replay only (the image is unused).
    config.validate()?;
    let preset = match &a.preset {
        Some(p) => {
            let (m, tck) = MemCfg::preset(p)?;
            config.mem = m;
            config.clocks.dram_ps = tck;
            p.clone()
        }
        None => "config".to_string(),
    };
    if let Some(e) = &a.energy {
        config.mem.energy = EnergyCfg::by_name(e, &config.mem.geometry)?;
    }
    config.mem.validate()?;
    let m = &config.mem;
    let reqs = match (&a.trace, &a.generate) {
        (Some(_), Some(_)) => {
            return Err("give either --trace FILE or --generate KIND, not both".into());
        }
        (None, None) => {
            return Err(
                "nothing to do: give --trace FILE to replay, or --generate random|stream|mixed"
                    .into(),
            );
        }
        (Some(t), None) => trace::read_file(t, m.geometry.capacity())?,
        (None, Some(kind)) => {
            if a.requests == 0 {
                return Err("--requests 0 generates nothing; give at least 1".into());
            }
            let g = trace::generate(kind, a.requests, a.seed, m, a.interval, a.write_fraction)?;
            if let Some(out) = &a.out {
                let f = std::fs::File::create(out).map_err(|e| {
                    format!(
                        "cannot write '{}': {e}; choose a writable --out",
                        out.display()
                    )
                })?;
                let mut w = std::io::BufWriter::new(f);
                trace::write(&g, &mut w)
                    .and_then(|_| std::io::Write::flush(&mut w))
                    .map_err(|e| format!("writing '{}' failed: {e}", out.display()))?;
                println!("wrote {} requests to {}", g.len(), out.display());
                return Ok(());
            }
            g
        }
    };
    let opts = replay::ReplayOptions {
        check: a.check,
        preset,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let r = replay::replay(m, config.clocks.dram_ps, &reqs, &opts)?;
    let wall = t0.elapsed().as_secs_f64();
    print!("{}", r.report);
    println!(
        "  wall time {wall:.3} s, {:.0} simulated requests per second",
        reqs.len() as f64 / wall.max(1e-9)
    );
    if let Some(v) = &r.report.violations
        && !v.is_empty()
    {
        return Err(format!("the timing checker found {} violations", v.len()));
    }
    Ok(())
}

/// Restarts the program with glibc's heap on transparent huge pages when the
/// kernel gives them only on request (`madvise` mode) and the user set no glibc
/// tunables: the chip's per-cycle working set spans megabytes of small heap
/// objects, and 2 MB pages save most of its TLB misses (Dragon Box 160x160, one
/// thread: 5-10% less wall time, measured in alternating runs). No `unsafe`: the
/// allocator does the `madvise`. `DUALSTREAM_HUGEPAGES=0` turns it off.
#[cfg(target_os = "linux")]
fn with_huge_pages() {
    use std::os::unix::process::CommandExt;
    const TUNABLE: &str = "glibc.malloc.hugetlb=1";
    if std::env::var_os("GLIBC_TUNABLES").is_some()
        || std::env::var_os("DUALSTREAM_HUGEPAGES").is_some_and(|v| v == "0")
    {
        return;
    }
    let madvise = std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
        .is_ok_and(|m| m.contains("[madvise]"));
    if let (true, Ok(exe)) = (madvise, std::env::current_exe()) {
        // `exec` returns only if it failed: then carry on as we are.
        let _ = std::process::Command::new(exe)
            .args(std::env::args_os().skip(1))
            .env("GLIBC_TUNABLES", TUNABLE)
            .exec();
    }
}

fn main() -> ExitCode {
    #[cfg(target_os = "linux")]
    with_huge_pages();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
