//! `dualstream render`: one frame, functional, reference, cycle or time-sampled
//! (windows), with its image, summary, statistics and optional waveform.

use std::path::PathBuf;

use clap::Args;

use dualstream::config::Config;
use dualstream::render::{self, Frame, Mode, RenderCfg, output};
use dualstream::rtl::Threads;
use dualstream::scene::Scene;

use super::{
    CliError, WaveArgs, bvh_fallback_warning, parse_res, parse_size, render_cfg, unwritable,
};
use dualstream::sampling::{self, WindowEstimate};

#[derive(Args)]
pub struct RenderArgs {
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
    /// cycle: write a waveform of the chip here: FST for a `.fst` path (FSM
    /// states by name), VCD otherwise. Open with gtkwave or surfer.
    #[arg(long, alias = "wave")]
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
    #[command(flatten)]
    wave: WaveArgs,
}

/// `dualstream render`: checks every option and output before the frame (it
/// may take minutes), renders it and writes what was asked for. On an error
/// the outputs the check created are removed: no empty file is left.
pub fn render(config: Config, threads: Threads, a: RenderArgs) -> Result<(), CliError> {
    let outputs: Vec<PathBuf> = [Some(&a.out), a.stats.as_ref(), a.vcd.as_ref()]
        .into_iter()
        .flatten()
        .filter(|p| !p.exists())
        .cloned()
        .collect();
    let r = render_checked(config, threads, a);
    if r.is_err() {
        for p in outputs {
            if std::fs::metadata(&p).is_ok_and(|m| m.len() == 0) {
                let _ = std::fs::remove_file(&p);
            }
        }
    }
    r
}

fn render_checked(config: Config, threads: Threads, a: RenderArgs) -> Result<(), CliError> {
    let sampled = a.mode == "windows";
    let mode = match a.mode.as_str() {
        "functional" | "windows" => Mode::Functional,
        "reference" => Mode::Reference,
        "cycle" => Mode::Cycle,
        m => {
            return Err(CliError::Usage(format!(
                "unknown --mode '{m}'; use functional, reference, cycle or windows"
            )));
        }
    };
    let sc = load_scene(&a)?;
    let (from, to) = trace_window(&a, mode)?;
    check_writable(&a)?;
    let mut rc = render_cfg(&config, threads);
    if let (Some(path), Some(run)) = (&a.vcd, rc.chip.as_mut()) {
        run.trace = Some(render::ChipTrace {
            path: path.clone(),
            units: a.trace_units.clone(),
            from,
            to,
            max_bytes: parse_size(&a.trace_max_bytes, "--trace-max-bytes")?,
            every_edge: a.wave.trace_every_edge,
            show: a.wave.show()?,
        });
    }
    if mode == Mode::Cycle
        && let Some(note) = render::long_frame_note(&sc.settings, config.chip.tms)
    {
        eprintln!("note: {note}");
    }
    rc.verify = a.verify;
    rc.dump_rays = a.dump_rays.clone();
    if a.pass_log.is_some() && mode != Mode::Cycle {
        return Err(CliError::Usage(
            "--pass-log records the chip's segment passes; use it with --mode cycle".into(),
        ));
    }
    rc.pass_log = a.pass_log.is_some();
    let (mut frame, estimate) = run_frame(&sc, &config, mode, sampled, rc)?;
    // A time-sampled frame's energy is the estimate's (below), not the
    // functional model's TMs-only figure.
    if mode != Mode::Reference && !sampled {
        frame.energy = Some(dualstream::render::energy::frame_energy(&config, &frame));
    }
    write_outputs(&a, &frame, estimate.as_ref())
}

/// The scene with the command line's resolution, bounces and seed, checked.
fn load_scene(a: &RenderArgs) -> Result<Scene, CliError> {
    let mut sc = dualstream::scene::load(&a.scene)?;
    for w in &sc.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(r) = &a.res {
        (sc.settings.width, sc.settings.height) = parse_res(r)?;
    }
    if let Some(b) = a.bounces {
        sc.settings.bounces = b;
    }
    if let Some(s) = a.seed {
        sc.settings.seed = s;
    }
    sc.settings.validate()?;
    Ok(sc)
}

/// The core cycles to trace, `from` and the last one (if any), once the trace
/// options are checked to go with `--vcd` and `--mode cycle`.
fn trace_window(a: &RenderArgs, mode: Mode) -> Result<(u64, Option<u64>), CliError> {
    let traced = !a.trace_units.is_empty()
        || a.trace_window.is_some()
        || a.trace_from.is_some()
        || a.trace_to.is_some();
    if traced && a.vcd.is_none() {
        return Err(CliError::Usage(
            "--trace-units/--trace-window choose what goes into a waveform: add --vcd FILE".into(),
        ));
    }
    if a.vcd.is_some() && mode != Mode::Cycle {
        return Err(CliError::Usage(
            "--vcd traces the chip: add --mode cycle".into(),
        ));
    }
    let (from, to) = match &a.trace_window {
        Some(w) => dualstream::machine::trace::parse_window(w)?,
        None => (a.trace_from.unwrap_or(0), a.trace_to),
    };
    if let Some(t) = to
        && t < from
    {
        return Err(CliError::Usage(format!(
            "--trace-from {from} --trace-to {t}: the trace window ends before it starts"
        )));
    }
    Ok((from, to))
}

/// Fail on an unwritable output before spending minutes on the frame.
fn check_writable(a: &RenderArgs) -> Result<(), CliError> {
    for (p, what) in [
        (Some(&a.out), "--out"),
        (a.stats.as_ref(), "--stats"),
        (a.vcd.as_ref(), "--vcd"),
    ] {
        if let Some(p) = p {
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(p)
                .map_err(|e| unwritable(p, e, &format!("; choose a writable {what}")))?;
        }
    }
    Ok(())
}

/// The frame, with a progress bar, or time-sampled (then with its estimate).
fn run_frame(
    sc: &Scene,
    config: &Config,
    mode: Mode,
    sampled: bool,
    rc: RenderCfg,
) -> Result<(Frame, Option<WindowEstimate>), CliError> {
    let bar = indicatif::ProgressBar::new((sc.settings.bounces as u64 + 1) * 1000);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {msg} (ETA {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    if sampled {
        bar.finish_and_clear();
        eprintln!("time sampling (windows of the chip with GDDR5)...");
        let plan = sampling::default_windows();
        let ts = sampling::time_sampled_with(sc, config, rc, &plan)?;
        return Ok((ts.frame, Some(ts.estimate)));
    }
    let f = render::render(sc, mode, &rc, &mut |p: &render::Progress| {
        let frac = (p.done * 1000).checked_div(p.known).unwrap_or(0);
        bar.set_position(p.wave as u64 * 1000 + frac);
        bar.set_message(format!(
            "wavefront {}/{}: {} rays",
            p.wave, p.waves_max, p.rays
        ));
    })?;
    bar.finish_and_clear();
    Ok((f, None))
}

/// The image, pass log, summary, waveform note and statistics.
fn write_outputs(
    a: &RenderArgs,
    frame: &Frame,
    estimate: Option<&WindowEstimate>,
) -> Result<(), CliError> {
    output::write_png(frame, &a.out)?;
    if let Some(path) = &a.pass_log {
        output::write_pass_log(frame, path)?;
    }
    if let Some(why) = &frame.accel.bvh_fallback {
        eprintln!("warning: {}", bvh_fallback_warning(why));
    }
    print!("{}", output::summary(frame));
    if let Some(e) = estimate {
        print!("{}", sampling::window_summary(e));
    }
    println!("image: {}", a.out.display());
    if let (Some(p), Some(v)) = (&a.vcd, frame.chip.as_ref().and_then(|c| c.vcd)) {
        println!(
            "waveform: {} ({} units, {} signals, {} changes; open with: gtkwave {} {})",
            p.display(),
            v.units,
            v.signals,
            v.changes,
            p.display(),
            dualstream::rtl::trace::save_file_for(p).display()
        );
    }
    if let Some(p) = &a.stats {
        match estimate {
            Some(e) => sampling::write_json_estimated(frame, e, p)?,
            None => output::write_json(frame, p)?,
        }
        println!("statistics: {}", p.display());
    }
    Ok(())
}
