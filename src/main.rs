//! The dualstream command line: the global flags, one subcommand each in
//! `cli/`, errors printed as `error: ...` with a failing exit code.

mod cli;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
    /// The chip's memory in cycle mode: gddr5 (the paper's 16-channel GDDR5,
    /// the default) or fixed (a fixed latency and bandwidth: faster to think
    /// about, not the paper's figures). Overrides `[chip.memory] model`.
    #[arg(long, global = true, value_parser = ["gddr5", "fixed"])]
    memory: Option<String>,
    /// A directory to look for scene files and meshes in when they are not
    /// where a path names them (repeat for several; after them, those in
    /// $DUALSTREAM_SCENES). A mesh is found by its file name.
    #[arg(long = "scenes-dir", global = true, value_name = "DIR")]
    scenes_dir: Vec<PathBuf>,
    /// No progress on stderr (bars, or the plain lines every few seconds
    /// when stderr is not a terminal); warnings and errors still show.
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a unit testbench: random stimulus, scoreboard against the reference, optional VCD.
    Tb(cli::tb::TbArgs),
    /// Render a frame: dual streaming (functional) or the reference traversal.
    Render(cli::render::RenderArgs),
    /// Our figures next to the paper's (Table 2) for Dragon, Dragon Box and Sponza.
    Report(cli::report::ReportArgs),
    /// Scene tools.
    Scene {
        #[command(subcommand)]
        cmd: cli::scene::SceneCmd,
    },
    /// Write the Verilog skeleton of every unit.
    Hdl(cli::hdl::HdlArgs),
    /// Measure the simulator: kernel, dram, speed-error, threads or trace.
    Bench {
        #[command(subcommand)]
        cmd: cli::bench::BenchCmd,
    },
    /// The memory system: replay a DRAMsim3-format trace and print statistics, or
    /// generate a trace (random, stream, mixed).
    Dram(cli::dram::DramArgs),
    /// Show the configuration.
    Config(cli::config::ConfigArgs),
}

fn run(cli: Cli) -> Result<(), cli::CliError> {
    dualstream::scene::search::set_dirs(cli.scenes_dir.clone());
    cli::progress::set_quiet(cli.quiet);
    let mut config = cli::load_config(&cli.config)?;
    if let Some(m) = &cli.memory {
        config.chip.memory.model = dualstream::units::memory::MemoryModel::parse(m)?;
    }
    match cli.cmd {
        Cmd::Tb(a) => cli::tb::tb(config, a),
        Cmd::Render(a) => cli::render::render(config, a.threads.get()?, a),
        Cmd::Report(a) => cli::report::report(config, a.threads.get()?, a),
        Cmd::Scene { cmd } => cli::scene::scene(&config, cmd),
        Cmd::Hdl(a) => cli::hdl::hdl(&config, a),
        Cmd::Bench { cmd } => cli::bench::bench(config, cmd),
        Cmd::Dram(a) => cli::dram::dram(config, a),
        Cmd::Config(a) => cli::config::config(&config, a),
    }
}

/// `dualstream ... | head` closes stdout early: Rust ignores SIGPIPE, so the
/// next `print!` panics ("failed printing to stdout: Broken pipe"). A
/// command-line tool stops quietly then, as one killed by SIGPIPE would (exit
/// status 141); restoring the signal's default action would need `unsafe`.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(141);
        }
        default(info);
    }));
}

/// Restarts the program with glibc's heap on transparent huge pages when the
/// kernel gives them only on request (`madvise` mode) and the user set no glibc
/// tunables: the chip's per-cycle working set spans megabytes of small heap
/// objects, and 2 MB pages save most of its TLB misses (docs/kernel.md, "Chip
/// simulation speed": huge pages). No `unsafe`: the
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
    quiet_on_closed_stdout();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
