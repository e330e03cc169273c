//! Time sampling (`render --mode windows`, `bench speed-error --modes
//! windows`) and the speed/error study it was chosen by.
//!
//! While the functional model traces a frame, the chip with GDDR5 takes it
//! over in windows at some segment boundaries and shading items, each on a
//! snapshot of the DRAM image; the windows' counts, scaled by the functional
//! model's work, estimate what the cycle model would report for the frame.
//!
//! - `plan.rs`: where the windows go ([`WindowPlan`], [`default_windows`]);
//! - `frame.rs`: the hooks in `render`'s functional trace that take the
//!   windows ([`render_windows`]);
//! - `windows.rs`: the chip side, every window on a fresh chip, side by side
//!   on worker threads;
//! - `record.rs`: what the windows recorded ([`WindowRecord`]);
//! - `counts.rs`, `parts.rs`, `estimate.rs`: the estimate, part by part
//!   ([`time_sampled`], [`WindowEstimate`]);
//! - `analytic.rs`: the first-order figures of a functional frame (cycles
//!   from resource bounds, DRAM energy from lines);
//! - `output.rs`: the estimate's summary and JSON;
//! - [`speed_error`]: `bench speed-error`, every faster way of getting a
//!   frame's figures against the cycle model.
//!
//! Layers: this module uses `render`; `render` knows nothing of it (it calls
//! [`crate::render::FunctionalHooks`]).

mod analytic;
mod counts;
mod error;
mod estimate;
mod frame;
mod output;
mod parts;
mod plan;
mod record;
pub mod speed_error;
mod windows;

pub use analytic::{Estimate, dram_energy_estimate, estimate};
pub use counts::root_between;
pub use error::SamplingError;
pub use estimate::{
    TimeSampled, WindowEstimate, WindowPart, time_sampled, time_sampled_progress, time_sampled_with,
};
pub use frame::{WindowsProgress, render_windows, render_windows_progress};
pub use output::{window_summary, write_json_estimated};
pub use plan::{BORROW_ALIKE, ROOT_STEADY_TENTHS, SAMPLE_BORROW_FROM, WindowPlan, default_windows};
pub use record::{KindTime, SampleKind, SegWork, WindowRecord, WindowSample, kind_times_text};

use crate::config::Config;
use crate::render::RenderCfg;
use crate::rtl::Threads;

/// A frame of `c`'s chip on `threads`, over `pixels` (`None`: all).
fn render_cfg(c: &Config, pixels: Option<Vec<u32>>, threads: Threads) -> RenderCfg {
    RenderCfg {
        pixels,
        ..RenderCfg::for_chip(c, threads.sim())
    }
}
