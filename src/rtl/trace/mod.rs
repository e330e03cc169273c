//! Waveform tracing, to VCD or FST (chosen by the file's extension).
//!
//! One scope per unit instance (`chip.tm3.box_pipe`), with the signals of its
//! declaration: `x_valid`, `x_ready`, `x_data` for each port and one signal per traced
//! register. Values are sampled at every edge of a traced unit's clock inside the
//! time window (the simulator makes sure those edges are processed even if the unit
//! sleeps), after evaluation and before the edge: they are the values *during* that
//! cycle. Only changes are written, formatted directly.
//!
//! Port signals, seen from the unit: on an input port `valid` means a payload is
//! visible at the head of the link and `ready` means the unit took it this cycle; on
//! an output port `valid` means the unit pushed (or is offering a held payload) and
//! `ready` means the link had room at the start of the cycle. `data` keeps its last
//! value while `valid` is low.

use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::bits::Bits;
use super::decl::{PortDir, Samples};
use super::link::LinkId;
use super::sim::Time;

mod bind;
mod capture;
mod fst;
mod gtkw;
mod sample;
mod sink;
mod vcd;

use crate::util::FileError;
pub(crate) use capture::{CapUnit, Written};
pub use capture::{CaptureFile, CaptureSpec, DEFAULT_CAPTURE_MAX_BYTES, VECTORS_VERSION};
pub use fst::WriteSeek;
pub(crate) use sample::Activity;
use sink::Sink;

/// Why a waveform could not be traced.
#[derive(Debug)]
pub enum TraceError {
    /// The window ends before it starts.
    Window { from: Time, to: Time },
    /// The filter matches no unit.
    NoUnit { filter: String, units: Vec<String> },
    /// The size guard refused the waveform, before it started or while it was
    /// written (its file removed): what it would take and how to narrow it.
    Oversized(String),
    /// The waveform file could not be created.
    File(FileError),
    /// `--trace-signals` names no kind of signal the tracer knows.
    Signals(String),
    /// The header could not be written (`format`: VCD or FST).
    Header {
        format: &'static str,
        source: io::Error,
    },
}

impl std::fmt::Display for TraceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TraceError::Window { from, to } => write!(
                f,
                "trace window ends ({to}) before it starts ({from}); give an end at or after the start"
            ),
            TraceError::NoUnit { filter, units } => write!(
                f,
                "no unit matches the trace filter '{filter}'; units are: {}",
                units.join(", ")
            ),
            TraceError::Oversized(advice) => f.write_str(advice),
            TraceError::Signals(k) => write!(
                f,
                "unknown kind of signal '{k}' in --trace-signals; the kinds are {}",
                Show::KINDS
            ),
            TraceError::File(e) => write!(f, "{e}"),
            TraceError::Header { format, source } => {
                write!(f, "cannot write the {format} header: {source}")
            }
        }
    }
}

impl std::error::Error for TraceError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TraceError::File(e) => Some(e),
            TraceError::Header { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// Counts of what a trace wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceStats {
    pub changes: u64,
    pub bytes: u64,
    pub signals: u64,
    pub units: u64,
}

/// A written variable: its handle, width and last value written. Small
/// (24 bytes), as the tracer reads one per sampled or derived signal.
struct Sig {
    h: u32,
    width: u32,
    /// The last value of a signal of at most 64 bits, kept here: most are,
    /// and comparing in place spares a cache miss per signal and sample.
    small: u64,
    /// Where a wider signal's last value starts in its unit's `wide` words
    /// (`u32::MAX` until its first value).
    at: u32,
    /// Whether a value was written (nothing is before the first).
    written: bool,
    /// Whether the file holds it (a sampled signal `Show` leaves out is still
    /// followed: fire and the fields are derived from it).
    shown: bool,
}

impl Sig {
    fn new(h: u32, width: u32) -> Self {
        Sig {
            h,
            width,
            small: 0,
            at: u32::MAX,
            written: false,
            shown: true,
        }
    }

    /// A sampled signal the file does not hold.
    fn hidden(width: u32) -> Self {
        Sig {
            shown: false,
            ..Sig::new(u32::MAX, width)
        }
    }

    /// Whether `v` differs from the last value written; if so it becomes it
    /// (a wide one's in `wide`), and with `diff` the bits that changed go
    /// there (old xor new per word; all ones for the first value): fields
    /// derived from a signal need recomputing only where its bits changed.
    #[inline]
    fn update(&mut self, v: &Bits, wide: &mut Vec<u64>, diff: Option<&mut Vec<u64>>) -> bool {
        let new = v.words();
        if self.width <= 64 {
            let x = new.first().copied().unwrap_or(0);
            if self.written && x == self.small {
                return false;
            }
            if let Some(d) = diff {
                d.clear();
                d.push(if self.written {
                    x ^ self.small
                } else {
                    u64::MAX
                });
            }
            self.small = x;
        } else {
            let n = self.width.div_ceil(64) as usize;
            if self.at == u32::MAX {
                self.at = wide.len() as u32;
                wide.resize(wide.len() + n, 0);
            }
            let old = &mut wide[self.at as usize..][..n];
            // A sample holds the signal's width in whole words.
            let new = &new[..n];
            if self.written && old == new {
                return false;
            }
            if let Some(d) = diff {
                d.clear();
                if self.written {
                    d.extend(old.iter().zip(new).map(|(o, n)| o ^ n));
                } else {
                    d.resize(n, u64::MAX);
                }
            }
            old.copy_from_slice(new);
        }
        self.written = true;
        true
    }
}

/// How a derived signal is computed from a unit's sampled ones.
enum Derive {
    /// Port `port`'s valid and ready.
    Fire { port: usize },
    /// Bits `offset..offset + width` of sampled signal `of` (a port's data).
    Field { of: usize, offset: u32, float: bool },
}

struct Derived {
    sig: Sig,
    how: Derive,
}

struct TracedUnit {
    index: usize,
    period: Time,
    /// Sampled at every edge up to this time: it ran, or a link of its was
    /// pushed or popped, within a period before (`Time::MAX`: not yet).
    busy_until: Time,
    /// Whether its state's view moved on with time alone at its last sample
    /// (`Unit::state_moves`), or it has not been sampled yet.
    moving: bool,
    /// Whether it is in `Tracer::active`.
    queued: bool,
    /// Whether it has not been sampled yet (everything is, the first time).
    fresh: bool,
    /// Per port (as `ports`): sampled at every edge up to this time (its
    /// link was pushed or popped within a period before; `Time::MAX`: not
    /// yet), and at the first edge at or after the time in `port_wake` (its
    /// link's head becomes visible then).
    port_busy: Vec<Time>,
    port_wake: Vec<Time>,
    /// When it last ran, and when its registers were last sampled
    /// (`Time::MAX`: not yet): they change only at the edge after it runs.
    ran_at: Time,
    regs_at: Time,
    ports: Vec<(LinkId, PortDir)>,
    /// One per sampled signal, in `UnitDecl::signals` order.
    sigs: Vec<Sig>,
    /// In port order: each port's fire, then its fields.
    derived: Vec<Derived>,
    /// The last values of its signals wider than 64 bits (`Sig::at`).
    wide: Vec<u64>,
    /// Per derived signal (as `derived`), a field's bits in what it comes
    /// from, `(offset, width)`: kept apart, dense, so finding the fields a
    /// change touched reads 8 bytes per field, not a whole `Derived`.
    spans: Vec<(u32, u32)>,
    /// Per port, where its signals are in `derived`: fire at the first
    /// index if the range up to the second is not empty (`Show` may leave
    /// it out), its fields from the second to the third.
    port_derived: Vec<(usize, usize, usize)>,
    /// Per struct register: its sampled signal and its fields' range in
    /// `derived`.
    reg_derived: Vec<(usize, usize, usize)>,
}

/// Not a traced unit.
const NONE: u32 = u32::MAX;

/// A clock domain's waveform: its level and when it next toggles.
struct ClockSig {
    h: u32,
    period: Time,
    level: bool,
    next: Time,
}

/// Which units and which time window to trace.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceSpec {
    /// Comma-separated instance-path patterns; `*` matches any run of characters. A
    /// pattern also matches every unit below it (`chip.tm3` traces all of TM 3), and
    /// a bare unit name matches that unit anywhere (`box_pipe`). Empty: every unit.
    pub filter: String,
    /// First and last time (ps) to trace, inclusive.
    pub from: Time,
    pub to: Time,
    /// The size guard: the most bytes the trace may take (0: no limit;
    /// `DEFAULT_MAX_BYTES` unless told).
    pub max_bytes: u64,
    /// Sample every traced unit at every edge of its clock, not only the
    /// units that ran or whose links moved: the same waveform, slower (the
    /// check that activity-driven sampling misses nothing).
    pub every_edge: bool,
    /// Which signals of a traced unit the file holds.
    pub show: Show,
    /// The clock whose cycles the user gave the window in, as (clock
    /// domain, period in ps): messages state the window in its cycles
    /// (`None`: in ps).
    pub cycles_of: Option<(&'static str, Time)>,
}

/// Which kinds of signal a trace holds, and how wide they may be (as
/// Verilator's `--trace-depth` and `--trace-max-width` trim a trace).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Show {
    /// Ports' valid, ready and fire.
    pub handshakes: bool,
    /// Ports' packed data vectors.
    pub data: bool,
    /// Ports' payload fields.
    pub fields: bool,
    /// Registers that are FSM states.
    pub fsm: bool,
    /// Every other register.
    pub regs: bool,
    /// Leave out signals wider than this (0: any width).
    pub max_width: u32,
}

impl Default for Show {
    fn default() -> Self {
        Show {
            handshakes: true,
            data: true,
            fields: true,
            fsm: true,
            regs: true,
            max_width: 0,
        }
    }
}

impl Show {
    /// The kinds that `--trace-signals` names.
    pub const KINDS: &'static str =
        "ports (each port's valid, ready and fire), data, fields, fsm, regs, all";

    /// Parses a comma-separated list of kinds (`ports,fsm`); `max_width` as given.
    pub fn parse(list: &str, max_width: u32) -> Result<Show, TraceError> {
        let mut s = Show {
            handshakes: false,
            data: false,
            fields: false,
            fsm: false,
            regs: false,
            max_width,
        };
        for k in list.split(',').map(str::trim).filter(|k| !k.is_empty()) {
            match k {
                "ports" => s.handshakes = true,
                "data" => s.data = true,
                "fields" => s.fields = true,
                "fsm" => s.fsm = true,
                "regs" => s.regs = true,
                "all" => {
                    s = Show {
                        max_width,
                        ..Show::default()
                    }
                }
                _ => return Err(TraceError::Signals(k.to_string())),
            }
        }
        Ok(s)
    }

    /// Whether a signal of this kind and width goes in the file.
    pub(crate) fn keeps(&self, kind_shown: bool, width: u32) -> bool {
        kind_shown && (self.max_width == 0 || width <= self.max_width)
    }
}

impl TraceSpec {
    pub fn all() -> Self {
        TraceSpec {
            filter: String::new(),
            from: 0,
            to: Time::MAX,
            max_bytes: DEFAULT_MAX_BYTES,
            every_edge: false,
            show: Show::default(),
            cycles_of: None,
        }
    }

    /// The window `from..=to` (ps) in the user's terms: `cycles A to B of
    /// clk_core (N cycles)`, or in ps without `cycles_of`; `open`: the end
    /// is only the run's expected end.
    pub fn window_text(&self, from: Time, to: Time, open: bool) -> String {
        let about = if open { "about " } else { "" };
        let to = to.max(from);
        match self.cycles_of {
            Some((clock, p)) if p > 0 => {
                let (a, b) = (from.div_ceil(p), to / p);
                format!(
                    "cycles {a} to {about}{b} of clk_{clock} ({about}{} cycles)",
                    (b + 1).saturating_sub(a)
                )
            }
            _ => format!("{from} to {about}{to} ps ({about}{} ps)", to - from + 1),
        }
    }

    /// A time in the user's terms: `cycle N of clk_core (T ps)`, or `T ps`.
    pub fn time_text(&self, t: Time) -> String {
        match self.cycles_of {
            Some((clock, p)) if p > 0 => format!("cycle {} of clk_{clock} ({t} ps)", t / p),
            _ => format!("{t} ps"),
        }
    }

    pub fn validate(&self) -> Result<(), TraceError> {
        if self.to < self.from {
            return Err(TraceError::Window {
                from: self.from,
                to: self.to,
            });
        }
        Ok(())
    }
    pub fn matches(&self, path: &str) -> bool {
        let pats: Vec<&str> = self
            .filter
            .split(',')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .collect();
        pats.is_empty() || pats.iter().any(|p| pattern_matches(p, path))
    }
}

fn glob(p: &[u8], s: &[u8]) -> bool {
    match (p.first(), s.first()) {
        (None, None) => true,
        (Some(b'*'), _) => glob(&p[1..], s) || (!s.is_empty() && glob(p, &s[1..])),
        (Some(a), Some(b)) if a == b => glob(&p[1..], &s[1..]),
        _ => false,
    }
}

fn pattern_matches(p: &str, path: &str) -> bool {
    if glob(p.as_bytes(), path.as_bytes()) {
        return true;
    }
    // A prefix scope matches everything below it.
    if path.len() > p.len()
        && path.as_bytes()[p.len()] == b'.'
        && glob(p.as_bytes(), &path.as_bytes()[..p.len()])
    {
        return true;
    }
    // A bare name matches that component anywhere.
    !p.contains('.') && path.split('.').any(|c| glob(p.as_bytes(), c.as_bytes()))
}

/// A waveform writer bound to a simulator.
pub struct Tracer {
    sink: Box<dyn Sink>,
    /// "VCD" or "FST", for messages.
    format: &'static str,
    spec: TraceSpec,
    units: Vec<TracedUnit>,
    periods: Vec<Time>,
    samples: Samples,
    scratch: Bits,
    /// The ports of a unit sampled at this edge, and whether its registers
    /// were.
    sampled: Vec<u32>,
    regs_sampled: bool,
    /// The bits that changed in the signal being written (old xor new, a
    /// word per 64 bits; all ones for a first value).
    diff: Vec<u64>,
    clocks: Vec<ClockSig>,
    rst: Option<u32>,
    /// The time up to which the clocks are written.
    clock_t: Option<Time>,
    /// What the GTKWave save file shows.
    view: gtkw::View,
    /// Per link, the traced units at its ends and the port of each (producer,
    /// its port, consumer, its port; `NONE`: not traced).
    link_ends: Vec<[u32; 4]>,
    /// Links touched at the last step, whose heads are known after its edge.
    pending: Vec<u32>,
    /// Per simulator unit, its index in `units` (`NONE`: not traced).
    traced_of: Vec<u32>,
    /// The traced units to sample at their next edges: busy or moving (a
    /// full chip has thousands of units, a few dozen of them active).
    active: Vec<u32>,
    /// Units to sample at an edge of theirs, as (edge, unit): a link's head
    /// becomes visible to them then.
    wakes: std::collections::BinaryHeap<std::cmp::Reverse<(Time, u32)>>,
    /// The units sampled at this step, in unit order (the file's order).
    due: Vec<u32>,
    changes: u64,
    error: Option<io::Error>,
    /// The size guard: the most bytes the trace may take, the time the run is
    /// expected to end (for a window without an end), the file to remove when
    /// the guard stops the trace, and why it stopped it.
    max_bytes: u64,
    expect_end: Option<Time>,
    path: Option<PathBuf>,
    stopped: Option<String>,
    /// Bytes a sample of every traced signal would take, per ps of the window
    /// (the sum over the traced units of their signals' widths plus the VCD
    /// identifier and line end, over their clock periods; FST takes less).
    full_bytes_per_ps: f64,
    header_bytes: u64,
    /// Named markers for the save file (`set_markers`).
    markers: Vec<(Time, String)>,
}

/// The default size guard (`--trace-max-bytes`): 1 GiB.
pub const DEFAULT_MAX_BYTES: u64 = 1 << 30;

/// Share of the traced signals the up-front estimate assumes change in a
/// sample: 2.5 times the 0.08% of a full-chip window mid-frame. A busy unit
/// testbench reaches 40%, so the guard also projects the bytes written after
/// `PROJECT_AFTER` of the window, and stops at the limit in any case.
const ACTIVITY: f64 = 0.002;

/// Share of a bounded window after which the written bytes are projected to
/// the window's end (and the trace stopped if that is over the limit).
const PROJECT_AFTER: f64 = 0.05;

fn gb(b: f64) -> String {
    const G: f64 = (1u64 << 30) as f64;
    if b >= G {
        format!("{:.1} GiB", b / G)
    } else if b >= (1u64 << 20) as f64 {
        format!("{:.0} MiB", b / (1u64 << 20) as f64)
    } else {
        format!("{:.0} KiB", b / 1024.0)
    }
}

impl Tracer {
    /// A VCD tracer writing to `out`.
    pub fn new(out: Box<dyn Write>, spec: TraceSpec) -> Result<Self, TraceError> {
        Self::with_sink(Box::new(vcd::VcdSink::new(out)), "VCD", spec)
    }

    /// An FST tracer writing to `out`.
    pub fn new_fst(out: Box<dyn WriteSeek>, spec: TraceSpec) -> Result<Self, TraceError> {
        let sink = fst::FstSink::new(out).map_err(|source| TraceError::Header {
            format: "FST",
            source,
        })?;
        Self::with_sink(Box::new(sink), "FST", spec)
    }

    /// A tracer writing vectors of `units` (`--capture`, docs/rtl.md):
    /// every port's valid, ready and data, sampled at every edge of each
    /// unit's clock over the cycles of `spec`; `written` is filled in with
    /// the files when it finishes.
    pub(crate) fn capture(
        spec: &CaptureSpec,
        units: Vec<CapUnit>,
        written: Written,
    ) -> Result<Self, TraceError> {
        let filter = units
            .iter()
            .map(|u| u.path.as_str())
            .collect::<Vec<_>>()
            .join(",");
        let from = units
            .iter()
            .map(|u| spec.from.saturating_mul(u.period))
            .min()
            .unwrap_or(0);
        let to = match spec.to {
            None => Time::MAX,
            Some(c) => units
                .iter()
                .map(|u| {
                    c.saturating_add(1)
                        .saturating_mul(u.period)
                        .saturating_sub(1)
                })
                .max()
                .unwrap_or(Time::MAX),
        };
        let show = Show {
            handshakes: true,
            data: true,
            fields: false,
            fsm: false,
            regs: false,
            max_width: 0,
        };
        let tspec = TraceSpec {
            filter,
            from,
            to,
            max_bytes: 0,
            every_edge: true,
            show,
            cycles_of: None,
        };
        let sink = capture::CaptureSink::new(spec, units, written);
        Self::with_sink(Box::new(sink), "vector", tspec)
    }

    fn with_sink(
        sink: Box<dyn Sink>,
        format: &'static str,
        spec: TraceSpec,
    ) -> Result<Self, TraceError> {
        spec.validate()?;
        let max_bytes = if spec.max_bytes == 0 {
            u64::MAX
        } else {
            spec.max_bytes
        };
        Ok(Tracer {
            sink,
            format,
            spec,
            units: Vec::new(),
            periods: Vec::new(),
            samples: Samples::default(),
            scratch: Bits::new(),
            sampled: Vec::new(),
            regs_sampled: false,
            diff: Vec::new(),
            clocks: Vec::new(),
            rst: None,
            clock_t: None,
            view: gtkw::View::default(),
            link_ends: Vec::new(),
            pending: Vec::new(),
            traced_of: Vec::new(),
            active: Vec::new(),
            wakes: std::collections::BinaryHeap::new(),
            due: Vec::new(),
            changes: 0,
            error: None,
            max_bytes,
            expect_end: None,
            path: None,
            stopped: None,
            full_bytes_per_ps: 0.0,
            header_bytes: 0,
            markers: Vec::new(),
        })
    }

    /// When the run is expected to end, for the estimate of a window without
    /// an end (e.g. a whole frame).
    pub fn expect_end(&mut self, t: Time) {
        self.expect_end = Some(t);
    }

    /// Named markers (time, name) for the save file: those within the
    /// traced window, the first `gtkw::NAMED_MARKERS` of them in time order.
    pub fn set_markers(&mut self, mut markers: Vec<(Time, String)>) {
        markers.sort_by_key(|m| m.0);
        self.markers = markers;
    }

    /// The window's end as far as it is known.
    fn window_end(&self) -> Option<Time> {
        match (self.spec.to, self.expect_end) {
            (Time::MAX, e) => e,
            (to, Some(e)) => Some(to.min(e)),
            (to, None) => Some(to),
        }
    }

    /// The trace's size estimated before it starts, and the window in ps it
    /// assumes (`None`: the window has no known end). An FST's is its VCD's:
    /// an FST took 7% to 96% of the bytes of the VCD of the same trace in
    /// every run measured (docs/waveforms.md), least on a few units' long
    /// signal chains, most on a whole chip's short ones.
    pub fn estimate(&self) -> Option<(u64, Time)> {
        let end = self.window_end()?;
        let w = end.saturating_sub(self.spec.from);
        let bytes = self.header_bytes as f64 + self.full_bytes_per_ps * ACTIVITY * w as f64;
        Some((bytes as u64, w))
    }

    /// What to say when the guard refuses: the size, what it covers, how to
    /// narrow it.
    fn advice(&self, what: &str) -> String {
        let signals: usize = self.units.iter().map(|u| u.sigs.len()).sum();
        let limit = if self.max_bytes == u64::MAX {
            "none".to_string()
        } else {
            gb(self.max_bytes as f64)
        };
        format!(
            "the waveform {what}, over the limit of {limit} ({} units, {signals} signals); trace fewer units or a shorter window (render: --trace-units, --trace-window; tb: --trace, --trace-from/--trace-to) or raise --trace-max-bytes",
            self.units.len()
        )
    }

    /// Refuses a trace whose estimate is over the limit.
    pub(crate) fn check_estimate(&self) -> Result<(), TraceError> {
        match self.estimate() {
            Some((bytes, w)) if bytes > self.max_bytes => {
                let from = self.spec.from;
                let open = self.spec.to == Time::MAX;
                let window = self.spec.window_text(from, from + w, open);
                Err(TraceError::Oversized(self.advice(&format!(
                    "would take about {} over {window} (estimated before it started)",
                    gb(bytes as f64)
                ))))
            }
            _ => Ok(()),
        }
    }

    /// Why the guard stopped the trace while it was written (the file is
    /// removed then).
    pub(crate) fn stopped(&self) -> Option<&str> {
        self.stopped.as_deref()
    }

    /// Removes the file being written (a trace the guard refused).
    pub(crate) fn discard(&mut self) {
        if let Some(p) = self.path.take() {
            let _ = std::fs::remove_file(p);
        }
    }

    /// The guard, after a sample at `t`: stop when the bytes written pass the
    /// limit, or when their projection to the window's end does.
    fn guard(&mut self, t: Time) {
        let written = self.sink.bytes();
        let why = if written > self.max_bytes {
            Some(format!(
                "reached {} at {}",
                gb(written as f64),
                self.spec.time_text(t)
            ))
        } else if let Some(end) = self.window_end() {
            let (from, span) = (self.spec.from, end.saturating_sub(self.spec.from));
            let frac = t.saturating_sub(from) as f64 / span.max(1) as f64;
            let projected = written as f64 / frac.max(1e-9);
            ((PROJECT_AFTER..1.0).contains(&frac) && projected > self.max_bytes as f64).then(|| {
                format!(
                    "would take about {} (projected from its first {:.0}%)",
                    gb(projected),
                    100.0 * frac
                )
            })
        } else {
            None
        };
        if let Some(why) = why {
            self.stopped = Some(self.advice(&why));
            self.discard();
        }
    }

    /// A tracer writing to a file: FST for a `.fst` path, VCD otherwise. The
    /// error names the path and what to do.
    pub fn to_file(path: &Path, spec: TraceSpec) -> Result<Self, TraceError> {
        let fst = is_fst(path);
        let f = File::create(path).map_err(|e| {
            let msg = format!(
                "cannot write the {} file '{}': {e}; choose a writable path with --vcd",
                if fst { "FST" } else { "VCD" },
                path.display()
            );
            TraceError::File(FileError::new(path, e, msg))
        })?;
        let mut t = if fst {
            Tracer::new_fst(Box::new(f), spec)?
        } else {
            Tracer::new(Box::new(f), spec)?
        };
        t.path = Some(path.to_path_buf());
        Ok(t)
    }

    /// The simulator's indices of the units bound (`bind`).
    /// The first and last time traced.
    pub(crate) fn window(&self) -> (Time, Time) {
        (self.spec.from, self.spec.to)
    }

    pub(crate) fn unit_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.units.iter().map(|u| u.index)
    }

    /// The links at the traced units' ports (they keep their last payload:
    /// `LinkDyn::sample_held`).
    pub(crate) fn traced_links(&self) -> impl Iterator<Item = LinkId> + '_ {
        self.units.iter().flat_map(|u| u.ports.iter().map(|p| p.0))
    }

    /// Flushes and reports what was written.
    pub(crate) fn finish(mut self, now: Time) -> io::Result<TraceStats> {
        if let Some(why) = self.stopped.take() {
            return Err(io::Error::other(why));
        }
        if let Some(e) = self.error.take() {
            self.discard();
            return Err(e);
        }
        let end = now.min(self.spec.to);
        if self.clock_t.is_none() {
            // Nothing was sampled: a file with no values is no waveform
            // (GTKWave cannot open such an FST).
            self.discard();
            return Err(io::Error::other(format!(
                "the run ended at {}, before the trace window starts at {}: nothing was traced; choose a window within the run",
                self.spec.time_text(now),
                self.spec.time_text(self.spec.from)
            )));
        }
        self.clocks_until(end)?;
        self.sink.finish(end)?;
        if let Some(p) = &self.path {
            let from = self.spec.from.min(end);
            let markers: Vec<(Time, String)> = std::mem::take(&mut self.markers)
                .into_iter()
                .filter(|m| (from..=end).contains(&m.0))
                .take(gtkw::NAMED_MARKERS)
                .collect();
            self.view
                .write(p, self.format == "FST", from, end, &markers)?;
        }
        Ok(TraceStats {
            changes: self.changes,
            bytes: self.sink.bytes(),
            signals: self
                .units
                .iter()
                .map(|u| (u.sigs.iter().filter(|s| s.shown).count() + u.derived.len()) as u64)
                .sum::<u64>()
                + self.clocks.len() as u64
                + self.rst.is_some() as u64,
            units: self.units.len() as u64,
        })
    }
}

/// The GTKWave save file written beside a trace file: its whole name and
/// `.gtkw` (`x.vcd.gtkw`, `x.fst.gtkw`), so traces of one stem in two
/// formats keep their own.
pub fn save_file_for(trace: &Path) -> PathBuf {
    let mut name = trace.file_name().unwrap_or_default().to_os_string();
    name.push(".gtkw");
    trace.with_file_name(name)
}

/// Whether a path names an FST file (by its extension, any case).
pub fn is_fst(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("fst"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns() {
        let s = |f: &str| TraceSpec {
            filter: f.into(),
            from: 0,
            to: 10,
            ..TraceSpec::all()
        };
        assert!(s("").matches("chip.tm3.box_pipe"));
        assert!(s("box_pipe").matches("chip.tm3.box_pipe"));
        assert!(s("chip.tm3").matches("chip.tm3.box_pipe"));
        assert!(!s("chip.tm3").matches("chip.tm31.box_pipe"));
        assert!(s("chip.tm*.box_pipe").matches("chip.tm31.box_pipe"));
        assert!(!s("tri_pipe*").matches("chip.tm3.box_pipe"));
        assert!(s("tri_pipe*, box_pipe").matches("chip.tm3.box_pipe"));
    }

    #[test]
    fn window_must_be_ordered() {
        let e = TraceSpec {
            filter: String::new(),
            from: 10,
            to: 5,
            ..TraceSpec::all()
        }
        .validate()
        .unwrap_err();
        assert!(matches!(e, TraceError::Window { from: 10, to: 5 }), "{e:?}");
        assert!(e.to_string().contains("before it starts"), "{e}");
    }
}

/// A `Write` into shared memory: a trace kept in RAM (tests hash whole waveforms
/// with it; a watchdog can keep the last cycles before a hang).
#[derive(Clone, Default)]
pub struct SharedBuf(pub std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl SharedBuf {
    pub fn bytes(&self) -> Vec<u8> {
        self.0.lock().expect("not poisoned").clone()
    }
}

impl Write for SharedBuf {
    fn write(&mut self, b: &[u8]) -> io::Result<usize> {
        self.0.lock().expect("not poisoned").extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
