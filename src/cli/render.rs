//! `dualstream render`: one frame, functional, reference, cycle or time-sampled
//! (windows), with its image, summary, statistics and optional waveform.

use std::path::PathBuf;

use clap::Args;

use dualstream::config::Config;
use dualstream::render::header::{RunHeader, RunParams};
use dualstream::render::{self, Frame, Mode, RenderCfg, output};
use dualstream::rtl::Threads;
use dualstream::scene::Scene;

use super::progress::Meter;
use super::{
    CliError, WaveArgs, bvh_fallback_warning, parse_res, parse_size, render_cfg, unwritable,
};
use dualstream::sampling::{self, WindowEstimate};

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub threads: super::ThreadsArg,
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
    #[arg(long, default_value = "functional",
          value_parser = ["functional", "reference", "cycle", "windows"])]
    mode: String,
    /// Early ray termination across segments (overrides `[chip]
    /// early_termination`): none, pre (read the ray's hit record before a
    /// segment, drop it if the hit is closer than its entry), post (read it
    /// before enqueueing into child segments, skip the farther ones) or both.
    /// Functional mode only so far.
    #[arg(long, value_enum, value_name = "CHOICE")]
    early_termination: Option<super::EarlyTermArg>,
    /// Hit points per path (default: the scene's, 5 as in the paper).
    #[arg(long)]
    bounces: Option<u32>,
    /// Seed of the path tracer's random numbers (default: the scene's, 1
    /// unless its file sets `seed`): the same seed gives the same image and
    /// statistics, bit for bit.
    #[arg(long)]
    seed: Option<u64>,
    /// Paths per pixel (1..=4096): each pixel traces N paths, as N times
    /// the rays; the image (and --hdr) is their average in linear radiance.
    /// 1 (the default) is the frame without samples, bit for bit.
    #[arg(long, default_value_t = 1)]
    spp: u32,
    /// Output image (PNG).
    #[arg(long, default_value = "render.png")]
    out: PathBuf,
    /// Also write the linear radiance, unclamped, as a PFM (32-bit float
    /// RGB) here: to compare with another renderer numerically.
    #[arg(long)]
    hdr: Option<PathBuf>,
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
    /// cycle: log every event of one ray through the chip: [WAVE:]ID, the
    /// wavefront (default 0) and the ray id (the pixel index y * width + x,
    /// decimal or 0x hex; an `s` suffix for the shadow ray), with its
    /// duplicates; with --vcd the trace window defaults to its span and the
    /// save file marks its key events. Repeat to follow several.
    #[arg(long, value_name = "[WAVE:]ID")]
    follow_ray: Vec<String>,
    /// cycle: follow every ray of pixel X,Y: its primary ray and, in each
    /// later wavefront, its bounce and shadow rays.
    #[arg(long, value_name = "X,Y")]
    follow_pixel: Option<String>,
    /// Where the followed rays' log goes (`-`: stdout). Default: beside
    /// --out, `<out>.follow.txt`.
    #[arg(long, value_name = "FILE")]
    follow_ray_out: Option<PathBuf>,
    #[command(flatten)]
    wave: WaveArgs,
    #[command(flatten)]
    capture: super::CaptureArgs,
}

/// `dualstream render`: checks every option and output before the frame (it
/// may take minutes), renders it and writes what was asked for. On an error
/// the outputs the check created are removed: no empty file is left.
pub fn render(config: Config, threads: Threads, a: RenderArgs) -> Result<(), CliError> {
    let outputs: Vec<PathBuf> = [
        Some(&a.out),
        a.stats.as_ref(),
        a.vcd.as_ref(),
        a.hdr.as_ref(),
    ]
    .into_iter()
    .flatten()
    .filter(|p| p.as_os_str() != "-" && !p.exists())
    .cloned()
    .collect();
    // A waveform stopped by a failed frame is no output either, nor its save
    // file and the follow log.
    let partial: Vec<PathBuf> = [
        a.vcd
            .as_ref()
            .map(|v| dualstream::rtl::trace::save_file_for(v)),
        a.vcd.clone(),
        follow_out(&a),
    ]
    .into_iter()
    .flatten()
    .filter(|p| !p.exists())
    .collect();
    let r = render_checked(config, threads, a);
    if r.is_err() {
        for p in outputs {
            if std::fs::metadata(&p).is_ok_and(|m| m.len() == 0) {
                let _ = std::fs::remove_file(&p);
            }
        }
        for p in partial {
            let _ = std::fs::remove_file(&p);
        }
    }
    r
}

/// Where the follow log goes: `None` for stdout or no following.
fn follow_out(a: &RenderArgs) -> Option<PathBuf> {
    if a.follow_ray.is_empty() && a.follow_pixel.is_none() {
        return None;
    }
    match &a.follow_ray_out {
        Some(p) if p.as_os_str() == "-" => None,
        Some(p) => Some(p.clone()),
        None => Some(a.out.with_extension("follow.txt")),
    }
}

fn render_checked(mut config: Config, threads: Threads, a: RenderArgs) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    super::EarlyTermArg::apply(a.early_termination, &mut config);
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
    let et = config.chip.early_termination;
    if (mode != Mode::Functional || sampled) && et != dualstream::config::EarlyTermination::None {
        return Err(CliError::Usage(render::only_functional(et)));
    }
    if let Some(p) = &a.hdr
        && !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("pfm"))
    {
        return Err(CliError::Usage(format!(
            "--hdr {}: the HDR image is a PFM (32-bit float RGB); give a path ending in .pfm",
            p.display()
        )));
    }
    let sc = load_scene(&a)?;
    let (from, to) = trace_window(&a, mode)?;
    check_writable(&a)?;
    let mut rc = render_cfg(&config, threads);
    if let Some(cap) = a.capture.spec(None)? {
        if mode != Mode::Cycle {
            return Err(CliError::Usage(
                "--capture records the chip's units: add --mode cycle".into(),
            ));
        }
        if let Some(run) = rc.chip.as_mut() {
            run.capture = Some(cap);
        }
    }
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
    let targets = follow_targets(&a, &sc, mode)?;
    if let Some(run) = rc.chip.as_mut() {
        run.follow = targets.clone();
    }
    let windowed = a.trace_window.is_some() || a.trace_from.is_some() || a.trace_to.is_some();
    if targets.is_some()
        && !windowed
        && let Some(trace) = rc.chip.as_mut().and_then(|r| r.trace.take())
    {
        // The trace window defaults to the followed rays' span: a first
        // frame without the waveform finds it (the same frame: results do
        // not depend on tracing).
        eprintln!("following: a first frame finds the rays' span for the trace window");
        let (first, _) = run_frame(&sc, &config, mode, sampled, rc.clone())?;
        let (lo, hi) = follow_span(&first).expect("a followed ray was traced");
        eprintln!(
            "following: tracing cycles {}..={} (the rays' events at {lo}..={hi})",
            lo.saturating_sub(FOLLOW_MARGIN),
            hi + FOLLOW_MARGIN
        );
        if let Some(run) = rc.chip.as_mut() {
            run.trace = Some(render::ChipTrace {
                from: lo.saturating_sub(FOLLOW_MARGIN),
                to: Some(hi + FOLLOW_MARGIN),
                ..trace
            });
        }
    }
    let (mut frame, estimate) = run_frame(&sc, &config, mode, sampled, rc)?;
    // A time-sampled frame's energy is the estimate's (below), not the
    // functional model's TMs-only figure.
    if mode != Mode::Reference && !sampled {
        frame.energy = Some(dualstream::render::energy::frame_energy(&config, &frame));
    }
    let run = RunParams {
        scene: Some(a.scene.clone()),
        resolution: Some([sc.settings.width, sc.settings.height]),
        mode: Some(a.mode.clone()),
        seed: Some(sc.settings.seed),
        bounces: Some(sc.settings.bounces),
        spp: Some(sc.settings.spp),
        threads: Some(a.threads.threads.clone()),
    };
    let header = RunHeader::new(&config, run, started.elapsed().as_secs_f64());
    write_outputs(&a, &frame, estimate.as_ref(), &header)
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
    sc.settings.spp = a.spp;
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
        (a.stats.as_ref().filter(|p| p.as_os_str() != "-"), "--stats"),
        (a.hdr.as_ref(), "--hdr"),
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
    if let Some(p) = follow_out(a) {
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&p)
            .map_err(|e| unwritable(&p, e, "; choose a writable --follow-ray-out"))?;
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
    if sampled {
        let plan = sampling::default_windows();
        let mut bar = windows_meter(sc);
        let ts = sampling::time_sampled_progress(sc, config, rc, &plan, &mut |p| {
            windows_progress(&mut bar, p)
        })?;
        bar.finish(&format!("done, {} windows measured", ts.estimate.windows));
        return Ok((ts.frame, Some(ts.estimate)));
    }
    let s = &sc.settings;
    let waves = s.bounces as u64 + 1;
    // Cycle mode counts simulated core cycles against the frame's estimate
    // (known before it starts: a steady ETA); the others wavefronts and the
    // ray-segment traversals of each.
    let cycles = (mode == Mode::Cycle).then(|| {
        render::estimated_frame_cycles(
            s.width as u64 * s.height as u64 * s.spp as u64,
            s.bounces,
            config.chip.tms,
        )
    });
    let mut bar = Meter::new("render", cycles.unwrap_or(waves * 1000));
    let f = render::render(sc, mode, &rc, &mut |p: &render::Progress| {
        let msg = || format!("wavefront {}/{}: {} rays", p.wave, p.waves_max, p.rays);
        if cycles.is_some() {
            // Past the estimate: keep the bar short of its end.
            if p.cycles >= bar.len() {
                bar.set_len(p.cycles + p.cycles / 20);
            }
            bar.set(p.cycles, || {
                format!("{} cycles, wavefront {}/{}", p.cycles, p.wave, p.waves_max)
            });
        } else {
            let frac = (p.done * 1000).checked_div(p.known).unwrap_or(0);
            bar.set(p.wave as u64 * 1000 + frac, msg);
        }
    })?;
    bar.finish(&format!("{} wavefronts done", f.waves.len()));
    Ok((f, None))
}

/// Time sampling's meter: the functional frame's wavefronts, 1000 steps each.
pub fn windows_meter(sc: &Scene) -> Meter {
    Meter::new("windows", (sc.settings.bounces as u64 + 1) * 1000)
}

/// Moves a [`windows_meter`] to `p`: how far the functional frame is, and
/// the windows answered.
pub fn windows_progress(bar: &mut Meter, p: &sampling::WindowsProgress) {
    let frac = (p.segment as u64 * 1000)
        .checked_div(p.segments as u64)
        .unwrap_or(0);
    bar.set(p.wave as u64 * 1000 + frac, || {
        format!(
            "wavefront {}/{}, {} windows done of {} taken",
            p.wave, p.waves_max, p.windows_done, p.windows_taken
        )
    });
}

/// Core cycles traced before a followed ray's first event and after its last
/// (the default trace window).
const FOLLOW_MARGIN: u64 = 50;

/// The first and last cycle of the followed rays' events.
fn follow_span(f: &Frame) -> Option<(u64, u64)> {
    let ev = f.chip.as_ref()?.follow.as_ref()?;
    Some((ev.first()?.cycle, ev.last()?.cycle))
}

/// The rays `--follow-ray` and `--follow-pixel` name, as (wavefront, ray id),
/// once checked to go with `--mode cycle` and to lie in the frame.
fn follow_targets(
    a: &RenderArgs,
    sc: &Scene,
    mode: Mode,
) -> Result<Option<Vec<(u32, u32)>>, CliError> {
    use dualstream::contract::SHADOW_BIT;
    if a.follow_ray.is_empty() && a.follow_pixel.is_none() {
        if a.follow_ray_out.is_some() {
            return Err(CliError::Usage(
                "--follow-ray-out is where a followed ray's log goes: add --follow-ray or --follow-pixel".into(),
            ));
        }
        return Ok(None);
    }
    if mode != Mode::Cycle || a.mode != "cycle" {
        return Err(CliError::Usage(format!(
            "--follow-ray/--follow-pixel follow rays through the chip's units; use them with --mode cycle, not {}",
            a.mode
        )));
    }
    let mut t = Vec::new();
    for r in &a.follow_ray {
        t.push(parse_ray(r)?);
    }
    let (w, h) = (sc.settings.width, sc.settings.height);
    if let Some(p) = &a.follow_pixel {
        let bad = || CliError::Usage(format!("--follow-pixel '{p}' is not X,Y (e.g. 12,40)"));
        let (x, y) = p.split_once(',').ok_or_else(bad)?;
        let (x, y): (u32, u32) = (
            x.trim().parse().map_err(|_| bad())?,
            y.trim().parse().map_err(|_| bad())?,
        );
        if x >= w || y >= h {
            return Err(CliError::Render(render::RenderError::NoSuchRay {
                wave: 0,
                ray_id: y.saturating_mul(w).saturating_add(x),
                why: format!(
                    "pixel ({x},{y}) is outside the {w}x{h} frame (x in 0..{w}, y in 0..{h})"
                ),
            }));
        }
        let pix = y * w + x;
        t.push((0, pix));
        for wave in 1..=sc.settings.bounces {
            t.extend([(wave, pix), (wave, pix | SHADOW_BIT)]);
        }
    }
    Ok(Some(t))
}

/// `[WAVE:]ID`: wavefront (default 0) and ray id (decimal or 0x hex, `s`
/// suffix: the shadow ray).
fn parse_ray(s: &str) -> Result<(u32, u32), CliError> {
    let bad = || {
        CliError::Usage(format!(
            "--follow-ray '{s}' is not [WAVE:]ID (e.g. 2:137 for the bounce ray of pixel 137 in wavefront 2, 2:137s for its shadow ray, or 2:0x80000089)"
        ))
    };
    let (wave, id) = match s.split_once(':') {
        Some((w, id)) => (w.trim().parse().map_err(|_| bad())?, id.trim()),
        None => (0, s.trim()),
    };
    let (id, shadow) = match id.strip_suffix('s') {
        Some(i) => (i, true),
        None => (id, false),
    };
    let id = match id.strip_prefix("0x") {
        Some(h) => u32::from_str_radix(h, 16),
        None => id.parse(),
    }
    .map_err(|_| bad())?;
    let shadow = if shadow {
        dualstream::contract::SHADOW_BIT
    } else {
        0
    };
    Ok((wave, id | shadow))
}

/// The followed rays' log: a header, then one event per line.
fn follow_log(f: &Frame) -> String {
    use std::fmt::Write as _;
    let ev = f
        .chip
        .as_ref()
        .and_then(|c| c.follow.as_deref())
        .unwrap_or(&[]);
    let mut s = String::from(
        "# dualstream --follow-ray: cycle (core, from the frame's start), unit instance, wavefront, ray id, event\n",
    );
    for e in ev {
        let _ = writeln!(s, "{e}");
    }
    s
}

/// The image, pass log, summary, waveform note and statistics.
fn write_outputs(
    a: &RenderArgs,
    frame: &Frame,
    estimate: Option<&WindowEstimate>,
    header: &RunHeader,
) -> Result<(), CliError> {
    // With `--stats -` the JSON is stdout; what is said for people goes to
    // stderr, so the JSON can be piped.
    let to_stdout = a.stats.as_ref().is_some_and(|p| p.as_os_str() == "-");
    macro_rules! say {
        ($($t:tt)*) => {
            if to_stdout { eprint!($($t)*) } else { print!($($t)*) }
        };
    }
    output::write_png(frame, &a.out)?;
    if let Some(p) = &a.hdr {
        output::write_pfm(frame, p)?;
    }
    if let Some(path) = &a.pass_log {
        output::write_pass_log(frame, path)?;
    }
    if let Some(why) = &frame.accel.bvh_fallback {
        eprintln!("warning: {}", bvh_fallback_warning(why));
    }
    say!("{}", output::summary(frame));
    if let Some(e) = estimate {
        say!("{}", sampling::window_summary(e));
    }
    say!("image: {}\n", a.out.display());
    if let Some(p) = &a.hdr {
        say!("HDR image: {} (PFM, linear radiance)\n", p.display());
    }
    if let (Some(p), Some(v)) = (&a.vcd, frame.chip.as_ref().and_then(|c| c.vcd)) {
        say!(
            "waveform: {} ({} units, {} signals, {} changes; open with: gtkwave {} {})\n",
            p.display(),
            v.units,
            v.signals,
            v.changes,
            p.display(),
            dualstream::rtl::trace::save_file_for(p).display()
        );
    }
    if let Some(c) = &frame.chip {
        super::print_captured(&c.captured);
    }
    if !a.follow_ray.is_empty() || a.follow_pixel.is_some() {
        let log = follow_log(frame);
        let n = log.lines().count() - 1;
        match follow_out(a) {
            Some(p) => {
                super::write_file(&p, &log)?;
                say!("followed: {n} events: {}\n", p.display());
            }
            None => say!("{log}"),
        }
    }
    if let Some(p) = &a.stats {
        let p = (!to_stdout).then_some(p.as_path());
        match estimate {
            Some(e) => sampling::write_json_estimated(frame, e, Some(header), p)?,
            None => output::write_json(frame, Some(header), p)?,
        }
        if let Some(p) = p {
            println!("statistics: {}", p.display());
        }
    }
    Ok(())
}
