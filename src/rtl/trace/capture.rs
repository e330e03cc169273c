//! Vectors (`--capture`): a [`Sink`] that turns the tracer's value changes of
//! the captured units' ports into one row per cycle of each unit's own clock,
//! the text format of docs/rtl.md ("Vectors"), one file per unit instance,
//! `<dir>/<instance path>.vec`. The tracer samples every captured unit at
//! every edge of its clock (`TraceSpec::every_edge`), so the values after all
//! changes at an edge are that cycle's; a row is written once time has passed
//! its edge. Files are written under a temporary name and renamed when the
//! run's capture finishes: no partial vector file is left.

use std::collections::HashMap;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::super::bits::Bits;
use super::super::decl::{PortDir, UnitDecl};
use super::super::sim::Time;
use super::sink::{ScopeKind, Sink, VarDef};

/// The format's version, in each file's first line.
pub const VECTORS_VERSION: u32 = 1;

/// What to capture: which unit instances, which cycles of their own clocks,
/// where to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CaptureSpec {
    /// Comma-separated instance-path patterns (as [`super::TraceSpec::filter`]).
    pub filter: String,
    /// First and last cycle (included; `None`: to the run's end) of each
    /// captured unit's own clock.
    pub from: u64,
    pub to: Option<u64>,
    /// The directory the `.vec` files go to (created if missing).
    pub dir: PathBuf,
    /// The most bytes all vector files may take together (0: no limit).
    pub max_bytes: u64,
}

/// The default limit of `--capture-max-bytes`: 1 GiB.
pub const DEFAULT_CAPTURE_MAX_BYTES: u64 = 1 << 30;

/// What a capture wrote, per file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CaptureFile {
    pub path: PathBuf,
    pub instance: String,
    /// Rows (cycles) written.
    pub rows: u64,
    /// Transfers (valid and ready in one row) per port, in declaration order.
    pub fires: Vec<u64>,
    pub bytes: u64,
}

/// One captured unit instance, as the sink knows it.
pub(crate) struct CapUnit {
    pub path: String,
    pub decl: UnitDecl,
    pub clock: String,
    pub period: Time,
}

struct Open {
    unit: CapUnit,
    /// Per port: valid, ready, data.
    vals: Vec<[Bits; 3]>,
    /// The next cycle to write a row for.
    next: u64,
    first: u64,
    last: Option<u64>,
    rows_path: PathBuf,
    rows: Option<BufWriter<File>>,
    nrows: u64,
    fires: Vec<u64>,
    bytes: u64,
    line: String,
}

pub(crate) struct CaptureSink {
    dir: PathBuf,
    units: Vec<Open>,
    by_path: HashMap<String, usize>,
    /// Per handle: (unit, port, 0 valid / 1 ready / 2 data), or none.
    handles: Vec<Option<(u32, u32, u8)>>,
    scopes: Vec<String>,
    /// The time whose changes are being received.
    now: Option<Time>,
    bytes: u64,
    max_bytes: u64,
    /// What `finish` wrote, shared with the simulator that reports it.
    written: Written,
}

/// The files a capture wrote, filled in when it finishes.
pub(crate) type Written = std::sync::Arc<std::sync::Mutex<Vec<CaptureFile>>>;

fn io_err(path: &Path, e: io::Error, what: &str) -> io::Error {
    io::Error::new(
        e.kind(),
        format!(
            "cannot {what} the vector file '{}': {e}; choose a writable directory with --capture-dir",
            path.display()
        ),
    )
}

/// `Some(x)` as hex, `None` as `-`.
fn opt(x: Option<u64>) -> String {
    x.map_or("-".into(), |x| x.to_string())
}

/// Appends `v` as `ceil(width / 4)` hex digits (`0` for no bits).
pub(crate) fn push_hex(out: &mut String, v: &Bits, width: u32) {
    if width == 0 {
        out.push('0');
        return;
    }
    let words = v.words();
    for k in (0..width.div_ceil(4)).rev() {
        let at = 4 * k;
        let w = words.get((at / 64) as usize).copied().unwrap_or(0);
        let nib = (w >> (at % 64)) & 0xf;
        let nib = if at + 4 > width {
            nib & ((1 << (width - at)) - 1)
        } else {
            nib
        };
        out.push(char::from_digit(nib as u32, 16).expect("a nibble"));
    }
}

impl CaptureSink {
    pub(crate) fn new(spec: &CaptureSpec, units: Vec<CapUnit>, written: Written) -> CaptureSink {
        let by_path = units
            .iter()
            .enumerate()
            .map(|(i, u)| (u.path.clone(), i))
            .collect();
        let units = units
            .into_iter()
            .map(|u| {
                let n = u.decl.ports.len();
                let rows_path = spec.dir.join(format!(".{}.vec.rows.tmp", u.path));
                Open {
                    vals: (0..n).map(|_| Default::default()).collect(),
                    next: spec.from,
                    first: spec.from,
                    last: spec.to,
                    rows_path,
                    rows: None,
                    nrows: 0,
                    fires: vec![0; n],
                    bytes: 0,
                    line: String::new(),
                    unit: u,
                }
            })
            .collect();
        CaptureSink {
            dir: spec.dir.clone(),
            units,
            by_path,
            handles: Vec::new(),
            scopes: Vec::new(),
            now: None,
            bytes: 0,
            max_bytes: if spec.max_bytes == 0 {
                u64::MAX
            } else {
                spec.max_bytes
            },
            written,
        }
    }

    /// Writes every row whose edge is before `t` (`inclusive`: at or before).
    fn rows_until(&mut self, t: Time, inclusive: bool) -> io::Result<()> {
        for u in &mut self.units {
            let p = u.unit.period;
            loop {
                let c = u.next;
                if u.last.is_some_and(|l| c > l) {
                    break;
                }
                let e = c.saturating_mul(p);
                if e > t || (e == t && !inclusive) {
                    break;
                }
                let line = &mut u.line;
                line.clear();
                line.push_str(&format!("{c:x}"));
                for (k, port) in u.unit.decl.ports.iter().enumerate() {
                    let [v, r, d] = &u.vals[k];
                    let bit = |b: &Bits| b.words().first().copied().unwrap_or(0) & 1;
                    let (v, r) = (bit(v), bit(r));
                    u.fires[k] += v & r;
                    line.push_str(&format!(" {v:x} "));
                    push_hex(line, d, port.width);
                    line.push_str(&format!(" {r:x}"));
                }
                line.push('\n');
                let w = u.rows.as_mut().expect("opened at the header");
                w.write_all(line.as_bytes())
                    .map_err(|e| io_err(&u.rows_path, e, "write"))?;
                u.nrows += 1;
                u.bytes += line.len() as u64;
                self.bytes += line.len() as u64;
                u.next += 1;
                if self.bytes > self.max_bytes {
                    return Err(io::Error::other(format!(
                        "the vectors reached {} bytes at cycle {c} of {}; capture fewer units or a shorter window (--capture-window, --capture-from/--capture-to) or raise --capture-max-bytes",
                        self.bytes, u.unit.path
                    )));
                }
            }
        }
        Ok(())
    }

    fn header(u: &Open, rows: u64, to: Option<u64>) -> String {
        let d = &u.unit.decl;
        let mut h = format!(
            "// dualstream vectors {VECTORS_VERSION}\n// module {}\n// instance {}\n// source {}\n// clock {} {}\n// window {} {}\n// from_reset {}\n// rows {rows}\n",
            d.module,
            u.unit.path,
            d.source,
            u.unit.clock,
            u.unit.period,
            u.first,
            opt(to),
            (u.first == 0) as u8,
        );
        for p in &d.params {
            h.push_str(&format!("// param {} {}\n", p.name, p.value));
        }
        for p in &d.ports {
            let dir = if p.dir == PortDir::In { "in" } else { "out" };
            let ty = if p.ty.is_named() {
                p.ty.sv_name()
            } else {
                "-".into()
            };
            h.push_str(&format!("// port {} {dir} {} {ty}\n", p.name, p.width));
        }
        h.push_str("// row: cycle, then per port: valid data ready (hex)\n");
        h
    }

    fn discard(&mut self) {
        for u in &mut self.units {
            u.rows = None;
            let _ = std::fs::remove_file(&u.rows_path);
        }
    }
}

impl Drop for CaptureSink {
    fn drop(&mut self) {
        self.discard();
    }
}

impl Sink for CaptureSink {
    fn begin_scope(&mut self, name: &str, _kind: ScopeKind) {
        self.scopes.push(name.to_string());
    }
    fn end_scope(&mut self) {
        self.scopes.pop();
    }
    fn comment(&mut self, _text: &str) {}
    fn var(&mut self, v: &VarDef) -> u32 {
        let h = self.handles.len() as u32;
        let path = self.scopes.join(".");
        let mut at = None;
        if let Some(&ui) = self.by_path.get(&path) {
            let d = &self.units[ui].unit.decl;
            for (k, p) in d.ports.iter().enumerate() {
                if let Some(s) = v
                    .name
                    .strip_prefix(p.name)
                    .and_then(|s| s.strip_prefix('_'))
                {
                    let j = match s {
                        "valid" => 0,
                        "ready" => 1,
                        "data" => 2,
                        _ => continue,
                    };
                    at = Some((ui as u32, k as u32, j));
                    break;
                }
            }
        }
        self.handles.push(at);
        h
    }
    fn id_len(&self, _h: u32) -> usize {
        4
    }
    fn end_header(&mut self) -> io::Result<u64> {
        std::fs::create_dir_all(&self.dir).map_err(|e| io_err(&self.dir, e, "create"))?;
        for u in &mut self.units {
            let f = File::create(&u.rows_path).map_err(|e| io_err(&u.rows_path, e, "write"))?;
            u.rows = Some(BufWriter::new(f));
        }
        Ok(0)
    }
    fn bits(&mut self, t: Time, h: u32, v: &Bits, _width: u32) -> io::Result<()> {
        if self.now.is_some_and(|n| t > n) {
            self.rows_until(t, false)?;
        }
        self.now = Some(t);
        if let Some(Some((u, k, j))) = self.handles.get(h as usize) {
            let slot = &mut self.units[*u as usize].vals[*k as usize][*j as usize];
            slot.clone_from(v);
        }
        Ok(())
    }
    fn real(&mut self, _t: Time, _h: u32, _v: f64) -> io::Result<()> {
        Ok(())
    }
    fn finish(&mut self, end: Time) -> io::Result<()> {
        self.rows_until(end, true)?;
        let mut written = Vec::new();
        for u in &mut self.units {
            let mut w = u.rows.take().expect("opened at the header");
            w.flush().map_err(|e| io_err(&u.rows_path, e, "write"))?;
            drop(w);
            let last = u.next.checked_sub(1).filter(|&l| l >= u.first);
            let path = self.dir.join(format!("{}.vec", u.unit.path));
            let tmp = self.dir.join(format!(".{}.vec.tmp", u.unit.path));
            let header = Self::header(u, u.nrows, last);
            let r = (|| {
                let mut out = BufWriter::new(File::create(&tmp)?);
                out.write_all(header.as_bytes())?;
                io::copy(&mut File::open(&u.rows_path)?, &mut out)?;
                out.flush()
            })();
            let _ = std::fs::remove_file(&u.rows_path);
            r.map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                io_err(&tmp, e, "write")
            })?;
            std::fs::rename(&tmp, &path).map_err(|e| io_err(&path, e, "write"))?;
            written.push(CaptureFile {
                path,
                instance: u.unit.path.clone(),
                rows: u.nrows,
                fires: u.fires.clone(),
                bytes: header.len() as u64 + u.bytes,
            });
        }
        *self.written.lock().expect("not poisoned") = written;
        Ok(())
    }
    fn bytes(&self) -> u64 {
        self.bytes
    }
}
