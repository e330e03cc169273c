//! VCD waveform tracing.
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
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::bits::Bits;
use super::decl::{PortDir, Samples, SignalDecl};
use super::link::{LinkDyn, LinkId};
use super::sim::{Clock, Time};
use super::unit::Unit;
use crate::util::FileError;

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
    /// The VCD file could not be created.
    File(FileError),
    /// The VCD header could not be written.
    Header(io::Error),
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
            TraceError::File(e) => write!(f, "{e}"),
            TraceError::Header(e) => write!(f, "cannot write the VCD header: {e}"),
        }
    }
}

impl std::error::Error for TraceError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TraceError::File(e) => Some(e),
            TraceError::Header(e) => Some(e),
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

struct Sig {
    id: String,
    width: u32,
    last: Option<Bits>,
}

struct TracedUnit {
    index: usize,
    period: Time,
    ports: Vec<(LinkId, PortDir)>,
    sigs: Vec<Sig>,
}

struct CountingWriter {
    inner: BufWriter<Box<dyn Write>>,
    bytes: u64,
}

impl Write for CountingWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
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
}

impl TraceSpec {
    pub fn all() -> Self {
        TraceSpec {
            filter: String::new(),
            from: 0,
            to: Time::MAX,
            max_bytes: DEFAULT_MAX_BYTES,
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

/// A VCD writer bound to a simulator.
pub struct Tracer {
    out: CountingWriter,
    spec: TraceSpec,
    units: Vec<TracedUnit>,
    periods: Vec<Time>,
    samples: Samples,
    time_written: Option<Time>,
    changes: u64,
    line: Vec<u8>,
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
    /// identifier and line end, over their clock periods).
    full_bytes_per_ps: f64,
    header_bytes: u64,
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
    pub fn new(out: Box<dyn Write>, spec: TraceSpec) -> Result<Self, TraceError> {
        spec.validate()?;
        let max_bytes = if spec.max_bytes == 0 {
            u64::MAX
        } else {
            spec.max_bytes
        };
        Ok(Tracer {
            out: CountingWriter {
                inner: BufWriter::with_capacity(1 << 16, out),
                bytes: 0,
            },
            spec,
            units: Vec::new(),
            periods: Vec::new(),
            samples: Samples::default(),
            time_written: None,
            changes: 0,
            line: Vec::with_capacity(256),
            error: None,
            max_bytes,
            expect_end: None,
            path: None,
            stopped: None,
            full_bytes_per_ps: 0.0,
            header_bytes: 0,
        })
    }

    /// When the run is expected to end, for the estimate of a window without
    /// an end (e.g. a whole frame).
    pub fn expect_end(&mut self, t: Time) {
        self.expect_end = Some(t);
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
    /// assumes (`None`: the window has no known end).
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
                let cycles = self.periods.iter().min().map_or(0, |p| w / p);
                Err(TraceError::Oversized(self.advice(&format!(
                    "would take about {} over {cycles} cycles (estimated before it started)",
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
        let written = self.out.bytes;
        let why = if written > self.max_bytes {
            Some(format!("reached {} at {t} ps", gb(written as f64)))
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

    /// A tracer writing to a file; the error names the path and what to do.
    pub fn to_file(path: &Path, spec: TraceSpec) -> Result<Self, TraceError> {
        let f = File::create(path).map_err(|e| {
            let msg = format!(
                "cannot write the VCD file '{}': {e}; choose a writable path with --vcd",
                path.display()
            );
            TraceError::File(FileError::new(path, e, msg))
        })?;
        let mut t = Tracer::new(Box::new(f), spec)?;
        t.path = Some(path.to_path_buf());
        Ok(t)
    }

    /// The simulator's indices of the units bound (`bind`).
    pub(crate) fn unit_indices(&self) -> impl Iterator<Item = usize> + '_ {
        self.units.iter().map(|u| u.index)
    }

    /// Selects the units to trace and writes the header.
    pub(crate) fn bind(&mut self, units: &[(&str, &dyn Unit, &Clock)]) -> Result<(), TraceError> {
        let mut chosen = Vec::new();
        for (i, (path, u, clk)) in units.iter().enumerate() {
            if self.spec.matches(path) {
                chosen.push((i, *path, *u, *clk));
            }
        }
        if chosen.is_empty() {
            return Err(TraceError::NoUnit {
                filter: self.spec.filter.clone(),
                units: units.iter().map(|u| u.0.to_string()).collect(),
            });
        }
        let mut header = String::new();
        header.push_str("$version dualstream ");
        header.push_str(env!("CARGO_PKG_VERSION"));
        header.push_str(" $end\n$timescale 1ps $end\n");
        let mut next_id = 0u64;
        let mut open: Vec<&str> = Vec::new();
        for (index, path, u, clk) in chosen {
            let decl = u.decl();
            let scopes: Vec<&str> = path.split('.').collect();
            let common = open.iter().zip(&scopes).take_while(|(a, b)| a == b).count();
            for _ in common..open.len() {
                header.push_str("$upscope $end\n");
            }
            open.truncate(common);
            for s in &scopes[common..] {
                header.push_str(&format!("$scope module {s} $end\n"));
                open.push(s);
            }
            header.push_str(&format!(
                "$comment {path}: module {} ({}), clock {} period {} ps $end\n",
                decl.module, decl.source, clk.name, clk.period_ps
            ));
            let mut sigs = Vec::new();
            for SignalDecl {
                name,
                width,
                enum_names,
            } in decl.signals()
            {
                let id = vcd_id(next_id);
                next_id += 1;
                if let Some(names) = enum_names {
                    let enc: Vec<String> = names
                        .iter()
                        .enumerate()
                        .map(|(i, n)| format!("{i}={n}"))
                        .collect();
                    header.push_str(&format!(
                        "$comment {path}.{name} states: {} $end\n",
                        enc.join(" ")
                    ));
                }
                let kind = if decl
                    .ports
                    .iter()
                    .any(|p| name.starts_with(p.name) && name[p.name.len()..].starts_with('_'))
                {
                    "wire"
                } else {
                    "reg"
                };
                if width == 1 {
                    header.push_str(&format!("$var {kind} 1 {id} {name} $end\n"));
                } else {
                    header.push_str(&format!(
                        "$var {kind} {width} {id} {name} [{}:0] $end\n",
                        width - 1
                    ));
                }
                sigs.push(Sig {
                    id,
                    width,
                    last: None,
                });
            }
            let ports = decl.ports.iter().map(|p| (p.link, p.dir)).collect();
            self.full_bytes_per_ps += sigs
                .iter()
                .map(|s| (s.width + s.id.len() as u32 + 3) as f64)
                .sum::<f64>()
                / clk.period_ps as f64;
            if !self.periods.contains(&clk.period_ps) {
                self.periods.push(clk.period_ps);
            }
            self.units.push(TracedUnit {
                index,
                period: clk.period_ps,
                ports,
                sigs,
            });
        }
        for _ in 0..open.len() {
            header.push_str("$upscope $end\n");
        }
        header.push_str("$enddefinitions $end\n");
        self.header_bytes = header.len() as u64;
        self.out
            .write_all(header.as_bytes())
            .map_err(TraceError::Header)?;
        Ok(())
    }

    /// The first traced edge at or after `after`, inside the window.
    pub(crate) fn next_sample_time(&self, after: Time, _clocks: &[Clock]) -> Option<Time> {
        let after = after.max(self.spec.from);
        let t = self.periods.iter().map(|p| after.div_ceil(*p) * p).min()?;
        (t <= self.spec.to).then_some(t)
    }

    pub(crate) fn sample<'u>(
        &mut self,
        t: Time,
        unit_at: &dyn Fn(usize) -> &'u dyn Unit,
        links: &[Box<dyn LinkDyn>],
    ) {
        if t < self.spec.from || t > self.spec.to || self.error.is_some() || self.stopped.is_some()
        {
            return;
        }
        for ui in 0..self.units.len() {
            let (period, index) = (self.units[ui].period, self.units[ui].index);
            if !t.is_multiple_of(period) {
                continue;
            }
            let unit = unit_at(index);
            self.samples.begin();
            for k in 0..self.units[ui].ports.len() {
                let (l, dir) = self.units[ui].ports[k];
                let link = &links[l.0 as usize];
                let base = self.samples.n;
                self.samples.slot();
                self.samples.slot();
                self.samples.slot();
                let [a, b, c] = <&mut [Bits; 3]>::try_from(&mut self.samples.vals[base..base + 3])
                    .expect("three slots")
                    .each_mut();
                match dir {
                    PortDir::In => link.sample_consumer(t, [a, b, c]),
                    PortDir::Out => link.sample_producer([a, b, c]),
                }
            }
            unit.sample_state(t / period, &mut self.samples);
            debug_assert_eq!(
                self.samples.n,
                self.units[ui].sigs.len(),
                "sampled signals match the declaration"
            );
            for k in 0..self.units[ui].sigs.len() {
                let v = &self.samples.vals[k];
                if v.is_empty() {
                    continue; // hold
                }
                let sig = &mut self.units[ui].sigs[k];
                if sig.last.as_ref() == Some(v) {
                    continue;
                }
                if self.time_written != Some(t) {
                    self.time_written = Some(t);
                    self.line.clear();
                    self.line.push(b'#');
                    self.line.extend_from_slice(t.to_string().as_bytes());
                    self.line.push(b'\n');
                    if let Err(e) = self.out.write_all(&self.line) {
                        self.error = Some(e);
                        return;
                    }
                }
                self.line.clear();
                format_value(&mut self.line, v, sig.width, &sig.id);
                if let Err(e) = self.out.write_all(&self.line) {
                    self.error = Some(e);
                    return;
                }
                self.changes += 1;
                match &mut sig.last {
                    Some(l) => l.clone_from(v),
                    None => sig.last = Some(v.clone()),
                }
            }
        }
        self.guard(t);
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
        // Close the trace at the last simulated time so viewers show the final values.
        let end = now.min(self.spec.to);
        if self.time_written.is_none_or(|t| t < end) {
            writeln!(self.out, "#{end}")?;
        }
        self.out.flush()?;
        Ok(TraceStats {
            changes: self.changes,
            bytes: self.out.bytes,
            signals: self.units.iter().map(|u| u.sigs.len() as u64).sum(),
            units: self.units.len() as u64,
        })
    }
}

/// Short VCD identifier from printable ASCII 33..=126.
fn vcd_id(mut n: u64) -> String {
    let mut s = String::new();
    loop {
        s.push((33 + (n % 94) as u8) as char);
        n /= 94;
        if n == 0 {
            break;
        }
    }
    s
}

/// `0!` for a scalar, `b1011 !` for a vector (leading zeros dropped, as VCD allows).
fn format_value(out: &mut Vec<u8>, v: &Bits, width: u32, id: &str) {
    if width == 1 {
        out.push(if v.bit(0) { b'1' } else { b'0' });
    } else {
        out.push(b'b');
        let words = v.words();
        let mut top = None;
        for (wi, w) in words.iter().enumerate().rev() {
            if *w != 0 {
                top = Some(wi as u32 * 64 + 63 - w.leading_zeros());
                break;
            }
        }
        match top {
            None => out.push(b'0'),
            Some(top) => {
                for i in (0..=top).rev() {
                    out.push(b'0' + ((words[(i / 64) as usize] >> (i % 64)) & 1) as u8);
                }
            }
        }
        out.push(b' ');
    }
    out.extend_from_slice(id.as_bytes());
    out.push(b'\n');
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

    #[test]
    fn value_format() {
        let mut b = Bits::new();
        b.push(0b101, 8);
        let mut out = Vec::new();
        format_value(&mut out, &b, 8, "!");
        assert_eq!(out, b"b101 !\n");
        let mut z = Bits::new();
        z.push(0, 8);
        out.clear();
        format_value(&mut out, &z, 8, "#");
        assert_eq!(out, b"b0 #\n");
        assert_eq!(vcd_id(0), "!");
        assert_eq!(vcd_id(94), "!\"");
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
