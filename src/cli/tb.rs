//! `dualstream tb`: a unit testbench (random stimulus, scoreboard against the
//! reference, optional VCD), or the TM testbench on one treelet.

use std::path::PathBuf;

use clap::Args;

use dualstream::config::Config;
use dualstream::rtl::{SimOptions, TraceSpec};
use dualstream::testbench::{self, TbOptions};

use super::{CliError, WaveArgs, parse_res, parse_size};

#[derive(Args)]
pub struct TbArgs {
    #[arg(help = unit_help(), long_help = unit_long_help())]
    unit: String,
    /// Cycles of stimulus, then the bench drains [default: 10000]. Random
    /// benches only: a directed or scripted bench refuses it.
    #[arg(long)]
    cycles: Option<u64>,
    /// Seed of the random stimulus and back-pressure.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Probability that a sink is ready in a cycle (back-pressure below 1)
    /// [default: 0.8]. Benches with sinks only.
    #[arg(long)]
    ready: Option<f64>,
    /// Probability of a new request per cycle [default: 0.5]. Random
    /// benches only.
    #[arg(long)]
    load: Option<f64>,
    /// Write a waveform here: FST for a `.fst` path (FSM states by name), VCD
    /// otherwise.
    #[arg(long, alias = "wave")]
    vcd: Option<PathBuf>,
    /// Units to trace: comma-separated instance patterns (`*` wildcard), or a
    /// bench's name in either spelling (`scheduler` for `stream_scheduler`).
    /// `--trace-units` as in `render`.
    #[arg(long, alias = "trace-units", default_value = "")]
    trace: String,
    /// Cycles to trace, of the bench's own clock: A..B (B excluded), A..=B or
    /// A.. (to the end), as in `render`.
    #[arg(long, conflicts_with_all = ["trace_from", "trace_to"])]
    trace_window: Option<String>,
    /// First cycle to trace, of the bench's own clock (the one `--cycles`
    /// counts: the DRAM clock for mem_ctrl, the core clock for the others).
    #[arg(long, default_value_t = 0)]
    trace_from: u64,
    /// Last cycle to trace, included, of the bench's own clock.
    #[arg(long)]
    trace_to: Option<u64>,
    /// The most the waveform may take (bytes, or with K, M, G; 0: no
    /// limit): a larger one is refused or stopped, and its file removed.
    #[arg(long, default_value = "1G")]
    trace_max_bytes: String,
    #[command(flatten)]
    wave: WaveArgs,
    #[command(flatten)]
    capture: super::CaptureArgs,
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
}

/// The unit argument's help, from the registry of testbenches.
fn unit_help() -> String {
    format!("Unit to test: {}", testbench::bench_names())
}

/// The unit argument's long help (`tb --help`): each bench and what it checks.
fn unit_long_help() -> String {
    let mut s = String::from("Unit to test:");
    for b in testbench::BENCHES {
        let name = match b.aliases {
            [] => b.name.to_string(),
            al => format!("{} ({})", b.name, al.join(", ")),
        };
        let clock = match b.clock {
            testbench::BenchClock::Core => String::new(),
            c => format!(
                " (runs on the {} clock: --cycles and --trace-from/--trace-to count its cycles)",
                c.name()
            ),
        };
        s.push_str(&format!("\n  {name:<24} {}{clock}", b.checks));
    }
    s
}

/// `dualstream tb UNIT`: runs the bench, prints its report and fails if the
/// scoreboard found errors.
pub fn tb(config: Config, mut a: TbArgs) -> Result<(), CliError> {
    let bench = testbench::find(&a.unit)?;
    if let Some(w) = &a.trace_window {
        let what = format!("cycles of the {} clock", bench.clock.name());
        (a.trace_from, a.trace_to) =
            dualstream::machine::trace::parse_window_of(w, "--trace-window", &what)?;
    }
    check_knobs(bench, &a)?;
    let cycles = a.cycles.unwrap_or(10_000);
    // Trace options without a waveform file would be ignored: say so.
    let traced = !a.trace.is_empty()
        || a.trace_window.is_some()
        || a.trace_from != 0
        || a.trace_to.is_some()
        || a.wave.trims();
    if traced && a.vcd.is_none() {
        return Err(CliError::Usage(
            "--trace, --trace-from/--trace-to, --trace-signals and --trace-max-width choose what a waveform holds; give --vcd FILE (.vcd or .fst) to write one".into(),
        ));
    }
    // The window counts the bench's own clock, as `--cycles` does.
    let (clock, p) = (bench.clock.name(), bench.clock.period_ps(&config));
    if let Some(to) = a.trace_to
        && to < a.trace_from
    {
        return Err(CliError::Usage(format!(
            "--trace-from {} --trace-to {to}: the trace window ends before it starts; give --trace-to at or after --trace-from (cycles of the bench's {clock} clock, both included)",
            a.trace_from
        )));
    }
    let ps = |c: u64, flag: &str| {
        c.checked_mul(p).ok_or_else(|| {
            CliError::Usage(format!(
                "{flag} {c}: no run reaches that cycle of the {clock} clock ({p} ps); give a cycle within the run (--cycles {cycles})"
            ))
        })
    };
    // A bench's other name (render's `scheduler`) stands for its unit's
    // instance (`tb.stream_scheduler`).
    let filter: Vec<&str> = a
        .trace
        .split(',')
        .map(|p| testbench::find(p.trim()).map_or(p, |b| b.name))
        .collect();
    let spec = TraceSpec {
        filter: filter.join(","),
        from: ps(a.trace_from, "--trace-from")?,
        to: a.trace_to.map_or(Ok(u64::MAX), |c| ps(c, "--trace-to"))?,
        max_bytes: parse_size(&a.trace_max_bytes, "--trace-max-bytes")?,
        every_edge: a.wave.trace_every_edge,
        show: a.wave.show()?,
        cycles_of: Some((clock, p)),
    };
    spec.validate()?;
    let opts = TbOptions {
        cycles,
        seed: a.seed,
        ready_p: a.ready.unwrap_or(0.8),
        load: a.load.unwrap_or(0.5),
        vcd: a.vcd.clone(),
        trace: spec,
        sim: SimOptions {
            sleep: !a.no_sleep,
            shadow: a.shadow,
            shuffle_seed: None,
            threads: 1,
            auto_lanes: false,
            check_ready: true,
            capture: a.capture.spec(Some(&|n: &str| {
                testbench::find(n).map_or(n.to_string(), |b| b.name.to_string())
            }))?,
        },
        config,
    };
    let start = std::time::Instant::now();
    let start_time = std::time::SystemTime::now();
    if matches!(bench.runner, testbench::Runner::Treelet) {
        let topts = testbench::tm_tb::TmTbOptions {
            scene: a.scene.clone(),
            treelet: a.treelet,
            res: a.res.as_deref().map(parse_res).transpose()?,
            max_rays: a.rays,
            run: testbench::tm_tb::RunOptions {
                mem_latency: a.mem_latency,
                sim: opts.sim.clone(),
                trace: opts.trace.clone(),
                log: false,
            },
            vcd: a.vcd.clone(),
            config: opts.config.clone(),
        };
        let rep = testbench::tm_tb::run(&topts)?;
        print!("{rep}");
        println!("  stimulus: {}", (bench.workload)());
        println!("  wall time {:.3} s", start.elapsed().as_secs_f64());
        print_waveform(&a.vcd);
        print_vectors(&a, start_time);
        return if rep.passed() {
            Ok(())
        } else {
            Err(CliError::Failed("the TM testbench failed".into()))
        };
    }
    let rep = testbench::run_by_name(&a.unit, &opts)?;
    print!("{rep}");
    println!("  stimulus: {}", stimulus(bench, &opts));
    if a.shadow {
        println!(
            "  shadow: every sleeping unit was also evaluated at each edge of its clock, and none would have changed anything (the run fails if one would)"
        );
    }
    println!("  wall time {:.3} s", start.elapsed().as_secs_f64());
    print_waveform(&a.vcd);
    print_vectors(&a, start_time);
    if !rep.passed() {
        return Err(CliError::Failed(format!(
            "testbench {} failed with {} errors",
            a.unit,
            rep.errors.len()
        )));
    }
    Ok(())
}

fn print_waveform(vcd: &Option<PathBuf>) {
    if let Some(v) = vcd {
        println!(
            "  waveform: {} (open with: gtkwave {} {})",
            v.display(),
            v.display(),
            dualstream::rtl::trace::save_file_for(v).display()
        );
    }
}

/// Refuses a stimulus option the bench does not read (`--cycles` on a
/// directed script, `--load` on a bench without drivers): ignoring it would
/// report a run the user did not ask for.
fn check_knobs(bench: &testbench::Bench, a: &TbArgs) -> Result<(), CliError> {
    use testbench::Knob;
    let given = [
        (Knob::Cycles, a.cycles.is_some()),
        (Knob::Ready, a.ready.is_some()),
        (Knob::Load, a.load.is_some()),
    ];
    for (k, set) in given {
        if set && !bench.knobs.contains(&k) {
            let takers: Vec<&str> = testbench::BENCHES
                .iter()
                .filter(|b| b.knobs.contains(&k))
                .map(|b| b.name)
                .collect();
            let reads = match bench.knobs {
                [] => "none of --cycles, --ready, --load".to_string(),
                ks => ks.iter().map(|k| k.flag()).collect::<Vec<_>>().join(", "),
            };
            return Err(CliError::Usage(format!(
                "tb {} runs {}; {} does not apply to it (it reads {reads}); drop it, or use a bench that takes it: {}",
                bench.name,
                (bench.workload)(),
                k.flag(),
                takers.join(", ")
            )));
        }
    }
    Ok(())
}

/// What stimulus ran, in the bench's terms.
fn stimulus(bench: &testbench::Bench, opts: &TbOptions) -> String {
    use testbench::Knob;
    let mut s = if bench.knobs.contains(&Knob::Cycles) {
        let mut s = format!(
            "random, {} cycles of the {} clock at load {}",
            opts.cycles,
            bench.clock.name(),
            opts.load
        );
        let w = (bench.workload)();
        if !w.is_empty() {
            s.push_str(&format!(" ({w}; --cycles ends it sooner)"));
        }
        s
    } else {
        (bench.workload)()
    };
    if bench.knobs.contains(&Knob::Ready) {
        s.push_str(&format!(", sinks ready with probability {}", opts.ready_p));
    }
    if !bench.knobs.is_empty() {
        s.push_str(&format!(", seed {}", opts.seed));
    }
    s
}

/// Lists the vector files this run wrote into `--capture-dir` (a bench
/// captures inside its own simulator and reports none).
fn print_vectors(a: &TbArgs, since: std::time::SystemTime) {
    let Some(dir) = a.capture.dir() else {
        return;
    };
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    let mut files: Vec<PathBuf> = rd
        .flatten()
        .filter(|e| {
            e.path().extension().is_some_and(|x| x == "vec")
                && e.metadata()
                    .and_then(|m| m.modified())
                    .is_ok_and(|t| t >= since)
        })
        .map(|e| e.path())
        .collect();
    files.sort();
    for f in files {
        let rows = std::fs::read_to_string(&f)
            .ok()
            .and_then(|t| {
                t.lines()
                    .find_map(|l| l.strip_prefix("// rows ").map(str::to_string))
            })
            .unwrap_or_default();
        println!("  vectors: {} ({rows} cycles)", f.display());
    }
}
