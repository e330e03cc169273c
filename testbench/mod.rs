//! Unit testbenches, in the spirit of cocotb and ChiselSim: a driver pokes requests
//! into a unit's input link, the clock is stepped, a sink takes the outputs with a
//! seeded back-pressure pattern, and a scoreboard checks every output against the
//! pure reference function, the exact latency and the initiation interval.
//!
//! Drivers and sinks are units like any other, so the unit under test is exercised
//! through real registered links with their protocol monitors.

mod error;
pub mod harness;
pub mod pipe_tb;

pub mod box_pipe_tb;
pub mod divider_tb;
pub mod hit_record_updater_tb;
pub mod l1_tb;
pub mod l2_tb;
pub mod mem_ctrl_tb;
pub mod memory_tb;
pub mod scene_buffer_tb;
pub mod staging_buffer_tb;
pub mod stream_scheduler_tb;
pub mod tm_tb;
pub mod tri_pipe_tb;

pub use error::TbError;
pub use harness::{Driver, LoadGen, Sink};
pub use pipe_tb::{PipeKind, PipeTb, TbOptions, TbReport};

/// How a testbench is driven.
#[derive(Clone, Copy)]
pub enum Runner {
    /// From [`TbOptions`] (cycles, seed, back-pressure, load, waveform).
    Unit(fn(&TbOptions) -> Result<TbReport, TbError>),
    /// The TM bench: a scene's treelet through one TM ([`tm_tb::run`], its own
    /// options: scene, treelet, memory latency).
    Treelet,
}

/// One unit testbench: the single list `dualstream tb`, its help and errors, the
/// README and the tests read.
pub struct Bench {
    /// The unit's module name, as `dualstream tb NAME` takes it.
    pub name: &'static str,
    /// Other names `tb` accepts (`render --trace-units`' names among them).
    pub aliases: &'static [&'static str],
    /// What the bench checks, in a line.
    pub checks: &'static str,
    /// The units it runs, by their `unit!` module names (a bench may run a
    /// composite of several): `tests/testbenches.rs` checks every unit under
    /// `src/units/` is named by a bench or has a test in its own file.
    pub units: &'static [&'static str],
    /// The clock the bench runs on: `--cycles` and `--trace-from/--trace-to`
    /// count its cycles.
    pub clock: BenchClock,
    /// The stimulus options (`--cycles`, `--ready`, `--load`) the bench
    /// reads; `tb` refuses the others rather than ignore them.
    pub knobs: &'static [Knob],
    /// What it runs when `--cycles` is not among its knobs, or what bounds
    /// it besides `--cycles` (its fixed workload), as `tb` reports it; from
    /// the bench's own defaults, so it cannot go stale.
    pub workload: fn() -> String,
    pub runner: Runner,
}

/// A stimulus option of `dualstream tb`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Knob {
    /// `--cycles`: how long the stimulus runs.
    Cycles,
    /// `--ready`: the sinks' back-pressure.
    Ready,
    /// `--load`: the drivers' request rate.
    Load,
}

impl Knob {
    pub fn flag(self) -> &'static str {
        match self {
            Knob::Cycles => "--cycles",
            Knob::Ready => "--ready",
            Knob::Load => "--load",
        }
    }
}

/// Random stimulus over `--cycles` with back-pressure and load.
const RANDOM: &[Knob] = &[Knob::Cycles, Knob::Ready, Knob::Load];

/// A bench's clock, from the configuration's `[clocks]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchClock {
    /// The core clock (`clocks.core_ps`).
    Core,
    /// The GDDR5 command clock (`clocks.dram_ps`).
    Dram,
}

impl BenchClock {
    /// Its domain's name, as the waveform's `clk_<name>`.
    pub fn name(self) -> &'static str {
        match self {
            BenchClock::Core => "core",
            BenchClock::Dram => "dram",
        }
    }
    pub fn period_ps(self, config: &crate::config::Config) -> u64 {
        match self {
            BenchClock::Core => config.clocks.core_ps,
            BenchClock::Dram => config.clocks.dram_ps,
        }
    }
}

/// Every testbench, in the order `tb --help` lists them.
pub const BENCHES: &[Bench] = &[
    Bench {
        name: "box_pipe",
        aliases: &[],
        checks: "ray-box pipeline: results against the reference test, exact latency and interval",
        units: &["box_pipe"],
        clock: BenchClock::Core,
        knobs: RANDOM,
        workload: String::new,
        runner: Runner::Unit(pipe_tb::run_random::<box_pipe_tb::BoxKind>),
    },
    Bench {
        name: "tri_pipe",
        aliases: &[],
        checks: "ray-triangle pipeline: results against the reference test, exact latency and interval",
        units: &["tri_pipe"],
        clock: BenchClock::Core,
        knobs: RANDOM,
        workload: String::new,
        runner: Runner::Unit(pipe_tb::run_random::<tri_pipe_tb::TriKind>),
    },
    Bench {
        name: "divider",
        aliases: &[],
        checks: "TM-shared divider: reciprocals against the reference, exact latency and interval",
        units: &["divider"],
        clock: BenchClock::Core,
        knobs: RANDOM,
        workload: String::new,
        runner: Runner::Unit(pipe_tb::run_random::<divider_tb::DivKind>),
    },
    Bench {
        name: "l1",
        aliases: &[],
        checks: "L1 (directed): a line behind a blocked fill is answered the next cycle",
        units: &["l1"],
        clock: BenchClock::Core,
        knobs: &[],
        workload: || "a directed script: a line requested behind a blocked fill".into(),
        runner: Runner::Unit(l1_tb::run),
    },
    Bench {
        name: "mem_ctrl",
        aliases: &["dram"],
        checks: "one GDDR5 channel: one response per request, the command stream passes the independent timing checker",
        units: &["mem_ctrl"],
        clock: BenchClock::Dram,
        knobs: RANDOM,
        workload: String::new,
        runner: Runner::Unit(mem_ctrl_tb::run_random),
    },
    Bench {
        name: "memory",
        aliases: &[],
        checks: "memory unit (fixed model, directed): answers at its latency, one line per cycle round-robin, masked writes",
        units: &["memory"],
        clock: BenchClock::Core,
        knobs: &[],
        workload: || "a directed script: reads and masked writes on every port".into(),
        runner: Runner::Unit(memory_tb::run),
    },
    Bench {
        name: "staging_buffer",
        aliases: &[],
        checks: "staging buffer (directed): every ray to a TP once with its bucket's header, in fill order, one swap per bucket",
        units: &["staging_buffer"],
        clock: BenchClock::Core,
        knobs: &[Knob::Ready],
        workload: staging_buffer_tb::workload,
        runner: Runner::Unit(staging_buffer_tb::run),
    },
    Bench {
        name: "hit_record_updater",
        aliases: &["hru", "hit_updater"],
        checks: "hit record updater: each record equals the atomic-min of its updates, bit for bit; merges counted",
        units: &["hit_record_updater"],
        clock: BenchClock::Core,
        knobs: RANDOM,
        workload: hit_record_updater_tb::workload,
        runner: Runner::Unit(hit_record_updater_tb::run),
    },
    Bench {
        name: "scene_buffer",
        aliases: &[],
        checks: "scene buffer: every line answered with the DRAM image's bytes, slots reused while late lines of retired segments are dropped",
        units: &["scene_buffer"],
        clock: BenchClock::Core,
        knobs: &[Knob::Ready],
        workload: scene_buffer_tb::workload,
        runner: Runner::Unit(scene_buffer_tb::run),
    },
    Bench {
        name: "l2",
        aliases: &[],
        checks: "L2: every read equals a replay of the access log (hits, MSHR merges, dirty evictions, flushes)",
        units: &["l2"],
        clock: BenchClock::Core,
        knobs: RANDOM,
        workload: l2_tb::workload,
        runner: Runner::Unit(l2_tb::run),
    },
    Bench {
        name: "stream_scheduler",
        aliases: &["scheduler"],
        checks: "stream scheduler on a real scene: every ray reaches every segment it is sent to, once, skipped subtrees stay skipped",
        units: &["stream_scheduler"],
        clock: BenchClock::Core,
        knobs: &[Knob::Ready],
        workload: || "a real scene's segments and ray buckets, until every ray is done".into(),
        runner: Runner::Unit(stream_scheduler_tb::run),
    },
    Bench {
        name: "tm",
        aliases: &[],
        checks: "a whole TM on a treelet: every ray's hit against the functional traversal",
        units: &[
            "tp",
            "tm_xbar",
            "staging_buffer",
            "l1",
            "divider",
            "tri_pipe",
        ],
        clock: BenchClock::Core,
        knobs: &[],
        workload: || "the primary rays of one treelet (--scene, --treelet, --rays, --res)".into(),
        runner: Runner::Treelet,
    },
];

/// The bench named `name` (or one of its aliases), or an error listing them all.
pub fn find(name: &str) -> Result<&'static Bench, TbError> {
    BENCHES
        .iter()
        .find(|b| b.name == name || b.aliases.contains(&name))
        .ok_or_else(|| TbError::UnknownUnit {
            name: name.to_string(),
        })
}

/// The benches' names, comma-separated, aliases in parentheses.
pub fn bench_names() -> String {
    BENCHES
        .iter()
        .map(|b| match b.aliases {
            [] => b.name.to_string(),
            a => format!("{} ({})", b.name, a.join(", ")),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Runs a unit testbench by name (the CLI's `tb` command; `tm` has its own
/// options: [`tm_tb::run`]).
pub fn run_by_name(name: &str, opts: &TbOptions) -> Result<TbReport, TbError> {
    match find(name)?.runner {
        Runner::Unit(run) => run(opts),
        Runner::Treelet => Err(TbError::Invalid(format!(
            "'{name}' runs on a scene's treelet: use `dualstream tb {name}` or testbench::tm_tb::run"
        ))),
    }
}

/// The configuration `dualstream tb <name>` elaborates its unit with, from the
/// base configuration: the global units' benches set their own TM count and sizes.
pub fn bench_config(name: &str, base: &crate::config::Config) -> crate::config::Config {
    let name = find(name).map_or(name, |b| b.name);
    match name {
        "hit_record_updater" => {
            hit_record_updater_tb::unit_config(base, &hit_record_updater_tb::HruTbCfg::default())
        }
        "l2" => l2_tb::unit_config(base, &l2_tb::L2TbCfg::default()),
        "scene_buffer" => {
            scene_buffer_tb::unit_config(base, &scene_buffer_tb::SceneBufferTbCfg::default())
        }
        "stream_scheduler" => {
            stream_scheduler_tb::unit_config(base, &stream_scheduler_tb::SchedTbCfg::default())
        }
        _ => base.clone(),
    }
}
