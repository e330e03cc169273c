//! `dualstream bench threads`: the simulator's wall time on one lane, on as
//! many lanes as the machine has cores, and with `--threads auto`, on cycle
//! frames and on a time-sampled paper-size frame, each on an idle machine and
//! beside one CPU-bound process that the benchmark starts and stops itself. A
//! measurement, not a test: the ratios go in docs/kernel.md.

use std::process::{Child, Command, Stdio};
use std::time::Instant;

use crate::config::Config;
use crate::render::RenderError;
use crate::render::{self, Mode, RenderCfg};
use crate::rtl::Threads;
use crate::sampling::SamplingError;
use crate::scene::SceneError;

/// One frame the benchmark times.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Case {
    pub name: &'static str,
    pub width: u32,
    pub height: u32,
    /// Time sampling (`--mode windows`) instead of the cycle model.
    pub windows: bool,
}

/// The cases: a 64x64 and a 256x256 cycle frame and a paper-size windows frame.
pub const CASES: [Case; 3] = [
    Case {
        name: "cycle64",
        width: 64,
        height: 64,
        windows: false,
    },
    Case {
        name: "cycle256",
        width: 256,
        height: 256,
        windows: false,
    },
    Case {
        name: "windows1024",
        width: 1024,
        height: 1024,
        windows: true,
    },
];

/// The cases named in `list` (comma-separated), or all.
pub fn cases(list: Option<&str>) -> Result<Vec<Case>, BenchError> {
    let Some(list) = list else {
        return Ok(CASES.to_vec());
    };
    list.split(',')
        .map(|n| {
            CASES
                .iter()
                .find(|c| c.name == n.trim())
                .cloned()
                .ok_or_else(|| BenchError::UnknownCase {
                    name: n.trim().to_string(),
                })
        })
        .collect()
}

/// One timed run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Run {
    pub case: String,
    /// "idle" or "busy" (one competing CPU-bound process).
    pub load: &'static str,
    pub threads: String,
    pub wall_s: f64,
    /// Cycle mode: the simulator's steps on each lane count (`lanes_1`, ...).
    #[serde(serialize_with = "crate::render::by_lanes")]
    pub steps_by_lanes: Vec<u64>,
}

/// Times one frame of `case` on `scene` with `threads`.
fn time_one(
    scene: &str,
    config: &Config,
    case: &Case,
    threads: Threads,
) -> Result<(f64, Vec<u64>), BenchError> {
    let mut sc = crate::scene::load(scene)?;
    (sc.settings.width, sc.settings.height) = (case.width, case.height);
    sc.settings.validate()?;
    let t0 = Instant::now();
    if case.windows {
        crate::sampling::time_sampled(&sc, config, threads, &crate::sampling::default_windows())?;
        return Ok((t0.elapsed().as_secs_f64(), Vec::new()));
    }
    let rc = RenderCfg::for_chip(config, threads.sim());
    let f = render::render(&sc, Mode::Cycle, &rc, &mut |_| {})?;
    let by = f.chip.map(|c| c.sim_steps_by_lanes).unwrap_or_default();
    Ok((t0.elapsed().as_secs_f64(), by))
}

/// The competing process: this program's hidden `bench busy`, which spins.
fn start_busy() -> Result<Child, BenchError> {
    let exe = std::env::current_exe().map_err(|source| BenchError::Process {
        what: "cannot find this program",
        source,
    })?;
    Command::new(exe)
        .args(["bench", "busy"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|source| BenchError::Process {
            what: "cannot start the competing process",
            source,
        })
}

/// Spins forever (the competing process of `bench threads`).
pub fn busy() -> ! {
    let mut x = 0u64;
    loop {
        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
    }
}

/// Runs every case on one lane, on `cores` lanes and on auto, idle and busy,
/// calling `progress` before each run (its index, the runs, what it is).
pub fn run(
    scene: &str,
    config: &Config,
    cases: &[Case],
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<Run>, BenchError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let choices = [
        Threads::fixed(1),
        Threads::fixed(cores.max(2)),
        Threads::auto(),
    ];
    let mut runs = Vec::new();
    let loads = ["idle", "busy"];
    let total = cases.len() * loads.len() * choices.len();
    for case in cases {
        for load in loads {
            let mut child = if load == "busy" {
                Some(start_busy()?)
            } else {
                None
            };
            let mut res = Ok(());
            for &t in &choices {
                progress(
                    runs.len(),
                    total,
                    &format!("{} {load} --threads {t}", case.name),
                );
                match time_one(scene, config, case, t) {
                    Ok((wall_s, by)) => runs.push(Run {
                        case: case.name.into(),
                        load,
                        threads: t.to_string(),
                        wall_s,
                        steps_by_lanes: by,
                    }),
                    Err(e) => {
                        res = Err(e);
                        break;
                    }
                }
            }
            if let Some(c) = &mut child {
                let _ = c.kill();
                let _ = c.wait();
            }
            res?;
        }
    }
    Ok(runs)
}

/// The table: per case and load, each choice's wall time and auto's ratio to
/// the better fixed choice.
pub fn table(runs: &[Run]) -> String {
    let mut s = String::from(
        "| case | load | 1 lane (s) | N lanes (s) | auto (s) | auto / best fixed | auto's steps by lanes |\n|---|---|---:|---:|---:|---:|---|\n",
    );
    for chunk in runs.chunks(3) {
        let [one, n, auto] = chunk else { continue };
        let best = one.wall_s.min(n.wall_s);
        let by: u64 = auto.steps_by_lanes.iter().sum();
        let lanes = if by == 0 {
            "-".to_string()
        } else {
            auto.steps_by_lanes
                .iter()
                .enumerate()
                .filter(|&(_, &k)| k > 0)
                .map(|(i, &k)| format!("{}: {:.0}%", i + 1, 100.0 * k as f64 / by as f64))
                .collect::<Vec<_>>()
                .join(", ")
        };
        s += &format!(
            "| {} | {} | {:.2} | {:.2} ({}) | {:.2} | {:.2} | {} |\n",
            one.case,
            one.load,
            one.wall_s,
            n.wall_s,
            n.threads,
            auto.wall_s,
            auto.wall_s / best,
            lanes
        );
    }
    s
}

/// Why `bench threads` cannot run.
#[derive(Debug)]
pub enum BenchError {
    /// `--cases` names a case that does not exist (the cases listed).
    UnknownCase {
        name: String,
    },
    Scene(SceneError),
    Render(RenderError),
    Sampling(SamplingError),
    /// The competing process could not be started.
    Process {
        what: &'static str,
        source: std::io::Error,
    },
}

impl std::fmt::Display for BenchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BenchError::UnknownCase { name } => write!(
                f,
                "unknown case '{name}' for bench threads; the cases are {}",
                CASES.map(|c| c.name).join(", ")
            ),
            BenchError::Scene(e) => write!(f, "{e}"),
            BenchError::Render(e) => write!(f, "{e}"),
            BenchError::Sampling(e) => write!(f, "{e}"),
            BenchError::Process { what, source } => write!(f, "{what}: {source}"),
        }
    }
}

impl std::error::Error for BenchError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            BenchError::UnknownCase { .. } => None,
            BenchError::Scene(e) => Some(e),
            BenchError::Render(e) => Some(e),
            BenchError::Sampling(e) => Some(e),
            BenchError::Process { source, .. } => Some(source),
        }
    }
}

impl From<SceneError> for BenchError {
    fn from(e: SceneError) -> BenchError {
        BenchError::Scene(e)
    }
}
impl From<RenderError> for BenchError {
    fn from(e: RenderError) -> BenchError {
        BenchError::Render(e)
    }
}
impl From<SamplingError> for BenchError {
    fn from(e: SamplingError) -> BenchError {
        BenchError::Sampling(e)
    }
}
