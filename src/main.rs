//! The dualstream command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use dualstream::config::Config;
use dualstream::rtl::{SimOptions, TraceSpec};
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
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a unit testbench: random stimulus, scoreboard against the reference, optional VCD.
    Tb {
        /// Unit to test: box_pipe, tri_pipe or divider.
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
        /// Evaluate every unit every cycle (no sleeping): slower, same results.
        #[arg(long)]
        no_sleep: bool,
        /// Also evaluate sleeping units and fail if that would change anything.
        #[arg(long)]
        shadow: bool,
    },
    /// Write the Verilog skeleton of every unit.
    Hdl {
        #[arg(long, default_value = "hdl")]
        out: PathBuf,
    },
    /// Measure the simulator's speed (kernel: pipelines of 128 TMs at several activities).
    Bench {
        /// What to measure: kernel.
        what: String,
        /// Scale the simulated cycles (1.0 = the full benchmark).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
    },
    /// Show the configuration.
    Config {
        /// Print the default configuration as TOML.
        #[arg(long)]
        print_default: bool,
    },
}

fn load_config(path: &Option<PathBuf>) -> Result<Config, String> {
    match path {
        Some(p) => Config::load(p),
        None => Ok(Config::default()),
    }
}

fn run(cli: Cli) -> Result<(), String> {
    let config = load_config(&cli.config)?;
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
            no_sleep,
            shadow,
        } => {
            let p = config.clocks.core_ps;
            let spec = TraceSpec {
                filter: trace,
                from: trace_from.saturating_mul(p),
                to: trace_to.map_or(u64::MAX, |c| c.saturating_mul(p)),
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
                },
                config,
            };
            let start = std::time::Instant::now();
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
        Cmd::Hdl { out } => {
            for p in dualstream::units::write_hdl(&config, &out)? {
                println!("wrote {}", p.display());
            }
            Ok(())
        }
        Cmd::Bench { what, scale } => {
            if what != "kernel" {
                return Err(format!("unknown benchmark '{what}'; available: kernel"));
            }
            if scale.is_nan() || scale <= 0.0 {
                return Err("--scale must be positive".into());
            }
            print!("{}", dualstream::bench::kernel_report(scale));
            Ok(())
        }
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

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
