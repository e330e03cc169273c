//! The subcommands, one file each, and what several of them share: the
//! resolution, size and thread-count parsers, the chip's render settings and
//! the BVH fallback warning.

use std::path::PathBuf;

use dualstream::config::Config;
use dualstream::rtl::Threads;

pub mod bench;
pub mod config;
pub mod dram;
mod error;
pub mod hdl;
pub mod progress;
pub mod render;
pub mod report;
pub mod scene;
pub mod tb;

pub use error::{CliError, unwritable};

/// What a waveform holds, for every command that traces (render, tb).
#[derive(clap::Args)]
pub struct WaveArgs {
    /// Which signals of each traced unit, comma-separated kinds: ports (each
    /// port's valid, ready and fire), data, fields, fsm, regs, or all.
    #[arg(long, default_value = "all")]
    trace_signals: String,
    /// Leave out signals wider than this many bits (0: any width).
    #[arg(long, default_value_t = 0)]
    trace_max_width: u32,
    /// Sample every traced unit at every edge, not only those that ran or
    /// whose links moved: the same waveform, slower (a check of the tracer).
    #[arg(long, hide = true)]
    trace_every_edge: bool,
}

impl WaveArgs {
    pub fn show(&self) -> Result<dualstream::rtl::trace::Show, dualstream::rtl::TraceError> {
        dualstream::rtl::trace::Show::parse(&self.trace_signals, self.trace_max_width)
    }

    /// Whether the flags trim the signals (what needs a waveform to act on).
    pub fn trims(&self) -> bool {
        self.trace_signals != "all" || self.trace_max_width != 0
    }
}

/// Vectors (`--capture`, docs/rtl.md "Vectors"), on `render --mode cycle`
/// and `tb`.
#[derive(clap::Args)]
pub struct CaptureArgs {
    /// Write vectors of these unit instances, comma-separated: the names
    /// --trace-units (render) or --trace (tb) take, or instance paths
    /// (`tm0.staging_buffer`, `hit_record_updater`); one file per instance,
    /// `<dir>/<instance path>.vec`.
    #[arg(long, value_name = "UNITS")]
    capture: Option<String>,
    /// Cycles to capture, of each captured unit's own clock: A..B (B
    /// excluded), A..=B or A.. (default: the whole run, from reset).
    #[arg(long, value_name = "A..B", conflicts_with_all = ["capture_from", "capture_to"])]
    capture_window: Option<String>,
    /// First cycle to capture (of the unit's own clock).
    #[arg(long)]
    capture_from: Option<u64>,
    /// Last cycle to capture, included.
    #[arg(long)]
    capture_to: Option<u64>,
    /// The directory the vector files go to (created if missing).
    #[arg(long, default_value = "vectors")]
    capture_dir: PathBuf,
    /// The most the vector files may take together (bytes, or with K, M, G;
    /// 0: no limit).
    #[arg(long, default_value = "1G")]
    capture_max_bytes: String,
}

impl CaptureArgs {
    /// The capture asked for (`None`: no `--capture`), its names mapped by
    /// `name` (tb: a bench's other names), the window checked.
    pub fn spec(
        &self,
        name: Option<&dyn Fn(&str) -> String>,
    ) -> Result<Option<dualstream::rtl::trace::CaptureSpec>, CliError> {
        let Some(units) = &self.capture else {
            if self.capture_window.is_some()
                || self.capture_from.is_some()
                || self.capture_to.is_some()
            {
                return Err(CliError::Usage(
                    "--capture-window/--capture-from/--capture-to choose the cycles of a capture: add --capture UNITS".into(),
                ));
            }
            return Ok(None);
        };
        let (from, to) = match &self.capture_window {
            Some(w) => dualstream::machine::trace::parse_window_of(
                w,
                "--capture-window",
                "cycles of the captured unit's clock",
            )?,
            None => (self.capture_from.unwrap_or(0), self.capture_to),
        };
        if let Some(t) = to
            && t < from
        {
            return Err(CliError::Usage(format!(
                "--capture-from {from} --capture-to {t}: the capture window ends before it starts; give --capture-to at or after --capture-from"
            )));
        }
        let filter: Vec<String> = units
            .split(',')
            .map(str::trim)
            .filter(|n| !n.is_empty())
            .map(|n| name.map_or(n.to_string(), |f| f(n)))
            .collect();
        if filter.is_empty() {
            return Err(CliError::Usage(
                "--capture names no unit; give instance names (tm0.staging_buffer)".into(),
            ));
        }
        Ok(Some(dualstream::rtl::trace::CaptureSpec {
            filter: filter.join(","),
            from,
            to,
            dir: self.capture_dir.clone(),
            max_bytes: parse_size(&self.capture_max_bytes, "--capture-max-bytes")?,
        }))
    }
}

impl CaptureArgs {
    /// The directory vectors go to, if any are captured.
    pub fn dir(&self) -> Option<&std::path::Path> {
        self.capture.as_ref().map(|_| self.capture_dir.as_path())
    }
}

/// Lists the vector files a capture wrote.
pub fn print_captured(files: &[dualstream::rtl::trace::CaptureFile]) {
    for f in files {
        println!(
            "vectors: {} ({} cycles, {} transfers, {} bytes)",
            f.path.display(),
            f.rows,
            f.fires.iter().sum::<u64>(),
            f.bytes
        );
    }
}

/// Says that the BVH came from the fallback builder, and why.
pub fn bvh_fallback_warning(why: &str) -> String {
    format!(
        "BVH: {why}; built with the binned-SAH fallback instead (bounded in time and depth). \
         Meshes of long, thin, overlapping triangles do this, e.g. a large polygon \
         triangulated as a fan"
    )
}

pub fn parse_res(s: &str) -> Result<(u32, u32), CliError> {
    let bad = || CliError::Usage(format!("--res '{s}' is not WIDTHxHEIGHT (e.g. 256x256)"));
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// A size in bytes with an optional K, M or G (powers of 1024).
pub fn parse_size(s: &str, flag: &str) -> Result<u64, CliError> {
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
    .map_err(|()| {
        CliError::Usage(format!(
            "{flag} {s}: give a size in bytes, e.g. 500M or 2G (0: no limit)"
        ))
    })
}

/// `--threads`, on the commands that simulate (render, report, scene info,
/// bench speed-error): not a global flag, so `config`, `hdl` and `tb` (one
/// thread, always) neither list nor take it.
/// `--early-termination`: overrides `[chip] early_termination`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum EarlyTermArg {
    /// No shared-record test (the paper's Table 2).
    None,
    /// Read the hit record before a segment; drop rays whose hit is closer.
    Pre,
    /// Read it before enqueueing into child segments; skip farther exits.
    Post,
    /// Both tests.
    Both,
}

impl EarlyTermArg {
    /// Sets the choice in `config`, if one was given.
    pub fn apply(arg: Option<EarlyTermArg>, config: &mut Config) {
        use dualstream::config::EarlyTermination as E;
        if let Some(a) = arg {
            config.chip.early_termination = match a {
                EarlyTermArg::None => E::None,
                EarlyTermArg::Pre => E::Pre,
                EarlyTermArg::Post => E::Post,
                EarlyTermArg::Both => E::Both,
            };
        }
    }
}

#[derive(clap::Args)]
pub struct ThreadsArg {
    /// Simulator threads: `auto` (the default) or 1 up to the machine's cores.
    #[arg(
        long,
        default_value = "auto",
        value_name = "auto|N",
        long_help = "Simulator threads: `auto` (the default) or 1 up to the machine's cores. Cycle mode spreads the TMs over N lanes (auto measures the run and uses one lane while more do not pay); time sampling runs N windows side by side (auto: one per core). Results are bit-identical for every choice."
    )]
    pub threads: String,
}

impl ThreadsArg {
    pub fn get(&self) -> Result<Threads, CliError> {
        sim_threads(&self.threads)
    }
}

/// `--threads`, checked.
pub fn sim_threads(threads: &str) -> Result<Threads, CliError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if threads == "auto" {
        return Ok(Threads::auto());
    }
    match threads.parse::<usize>() {
        Ok(n) if (1..=cores).contains(&n) => Ok(Threads::fixed(n)),
        Ok(n) => Err(CliError::Usage(format!(
            "--threads {n}: this machine has {cores} core(s); give --threads auto or a number from 1 to {cores}"
        ))),
        Err(_) => Err(CliError::Usage(format!(
            "--threads {threads}: not a number; give --threads auto or a number from 1 to {cores}"
        ))),
    }
}

pub fn render_cfg(config: &Config, threads: Threads) -> dualstream::render::RenderCfg {
    dualstream::render::RenderCfg::for_chip(config, threads.sim())
}

pub fn load_config(path: &Option<PathBuf>) -> Result<Config, CliError> {
    match path {
        Some(p) => Ok(Config::load(p)?),
        None => Ok(Config::default()),
    }
}

/// Writes `text` to `p`, naming the file when it cannot.
pub fn write_file(p: &std::path::Path, text: impl AsRef<[u8]>) -> Result<(), CliError> {
    std::fs::write(p, text).map_err(|e| unwritable(p, e, ""))
}
