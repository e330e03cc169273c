//! The clocked-simulation kernel: registers, RAMs, fixed-latency pipelines, registered
//! links, the unit declaration, the lock-step simulator, VCD tracing and Verilog
//! emission.
pub mod bits;
mod calendar;
pub mod decl;
pub mod link;
pub mod model;
pub mod pipe;
pub mod sim;
pub mod state;
pub mod sv;
pub mod tbgen;
pub mod trace;
pub mod unit;
pub mod verilog;

pub use bits::{Bits, Payload};
pub use decl::{PortDecl, PortDir, SignalDecl, StateDecl, UnitDecl};
pub use link::{In, LinkCfg, LinkEvent, LinkId, Out, PortArray, PortEnd};
pub use pipe::{FixedPipe, LocalEnds, LocalLink, PipeCfg, PipeEnds};
pub use sim::{
    ClockId, Ctx, ModuleEvals, RunEnd, Sim, SimError, SimOptions, Threads, Time, UnitId, UnitStats,
    round_robin,
};
pub use state::{Ram, Reg, State};
pub use trace::{SharedBuf, TraceError, TraceSpec, TraceStats, Tracer};
pub use unit::{Declared, Logic, Next, Ready, Status, Unit};
