//! How a run is set up and how it ends: the simulator options ([`SimOptions`],
//! [`Threads`], the command line's `--threads`), why a run stopped ([`RunEnd`])
//! and what can go wrong ([`SimError`]): the plain data callers build and match
//! on, apart from the simulator itself.

use std::fmt;

use super::Time;
use crate::rtl::link::Violation;
use crate::rtl::trace::TraceError;

/// How to run.
#[derive(Clone, Debug)]
pub struct SimOptions {
    /// Skip units that sleep (the fast, normal mode).
    pub sleep: bool,
    /// Evaluate sleeping units too and fail if that would change anything.
    pub shadow: bool,
    /// Evaluate the units of each step in a seeded random order (tests).
    pub shuffle_seed: Option<u64>,
    /// Evaluation lanes (threads): 1, or N to evaluate the units of partitions
    /// 1..N-1 (see [`Sim::set_part`](super::Sim::set_part),
    /// [`Sim::set_lane_plan`](super::Sim::set_lane_plan)) on worker threads
    /// while the caller's thread evaluates those of partition N, then partition 0
    /// alone. The result is bit-identical to one thread (evaluation order never
    /// changes a result). Only with `sleep` on and `shadow` off; otherwise one
    /// thread is used. With `auto_lanes`, the most lanes the run may use.
    pub threads: usize,
    /// Choose the lane count while running (1 up to `threads`), by measuring
    /// the run's own speed (see `lanes.rs`); needs a lane plan
    /// ([`Sim::set_lane_plan`](super::Sim::set_lane_plan)). Results never depend on it.
    pub auto_lanes: bool,
    /// Check every unit's readiness at its pops (`Logic::can_accept` must hold
    /// whenever a unit pops an input; a protocol violation otherwise). Always
    /// on for the units a tracer watches, whose waveform shows it.
    pub check_ready: bool,
    /// Capture vectors of these units (`tb --capture`): attached when the
    /// run starts ([`Sim::attach_capture`](super::Sim::attach_capture)),
    /// written by [`Sim::finish_trace`](super::Sim::finish_trace).
    pub capture: Option<crate::rtl::trace::CaptureSpec>,
}

/// How many evaluation threads a run uses (the command line's `--threads`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Threads {
    /// Lanes (with `auto`, the most the run may use).
    pub n: usize,
    /// Choose between 1 and `n` lanes while running (`SimOptions::auto_lanes`).
    pub auto: bool,
}

impl Threads {
    pub fn fixed(n: usize) -> Threads {
        Threads {
            n: n.max(1),
            auto: false,
        }
    }
    /// Up to the machine's cores, chosen while running.
    pub fn auto() -> Threads {
        Threads {
            n: std::thread::available_parallelism().map_or(1, |n| n.get()),
            auto: true,
        }
    }
    /// The simulator options of a run on these threads.
    pub fn sim(self) -> SimOptions {
        SimOptions {
            threads: self.n,
            auto_lanes: self.auto,
            ..SimOptions::default()
        }
    }
}

impl From<usize> for Threads {
    fn from(n: usize) -> Threads {
        Threads::fixed(n)
    }
}

impl fmt::Display for Threads {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.auto {
            write!(f, "auto (1 to {})", self.n)
        } else {
            write!(f, "{}", self.n)
        }
    }
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            sleep: true,
            shadow: false,
            shuffle_seed: None,
            threads: 1,
            auto_lanes: false,
            check_ready: false,
            capture: None,
        }
    }
}

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunEnd {
    /// Every unit sleeps with nothing scheduled.
    Idle,
    /// The time limit was reached.
    Limit,
}

#[derive(Debug)]
pub enum SimError {
    /// A link monitor saw a protocol violation (a bug in a unit).
    Protocol(Vec<Violation>),
    /// A sleeping unit would have changed something if evaluated (a sleep bug).
    Shadow {
        unit: String,
        at: Time,
        what: String,
    },
    /// The netlist is not well formed.
    Elaboration(String),
    /// `run_to_idle` reached its limit with work left.
    Busy { limit: Time },
    /// A link's configuration is impossible (`what` names its config key).
    LinkCfg { what: String, why: &'static str },
    /// The waveform could not be attached: no unit matches its filter, or its
    /// header could not be written.
    TraceBind(TraceError),
    /// The waveform's size guard refused or stopped the trace (its file removed).
    Trace(TraceError),
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Protocol(v) => {
                write!(f, "link protocol violation")?;
                for x in v {
                    write!(f, "; link '{}' at {} ps: {}", x.link, x.at, x.what)?;
                }
                Ok(())
            }
            SimError::Shadow { unit, at, what } => {
                write!(
                    f,
                    "sleeping unit '{unit}' at {at} ps would change {what} if evaluated: it must not sleep here"
                )
            }
            SimError::Elaboration(s) => write!(f, "netlist error: {s}"),
            SimError::Busy { limit } => write!(
                f,
                "netlist error: the design was still busy after {limit} ps; raise the limit or look for a unit that never sleeps"
            ),
            SimError::LinkCfg { what, why } => write!(f, "{what}: {why}"),
            SimError::TraceBind(e) => write!(f, "netlist error: {e}"),
            SimError::Trace(e) => write!(f, "{e}"),
        }
    }
}
impl std::error::Error for SimError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SimError::TraceBind(e) | SimError::Trace(e) => Some(e),
            _ => None,
        }
    }
}
