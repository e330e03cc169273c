//! The FST writer (GTKWave's and Surfer's compressed format), through the
//! `wavefst` crate: FSM registers carry an enum table, so every state shows by
//! name with no filter file, as Verilator's `--trace-fst` does.

use std::collections::HashMap;
use std::io::{self, Seek, SeekFrom, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use wavefst::{FstWriter, GeomEntry, Header, ScopeType, SignalValue, VarDir, VarType};

use super::super::bits::Bits;
use super::super::sim::Time;
use super::sink::{ScopeKind, Sink, VarDef, VarKind};

/// What an FST file is written to: a file, or memory in tests.
pub trait WriteSeek: Write + Seek {}
impl<T: Write + Seek> WriteSeek for T {}

/// Counts the bytes that reach the sink (the size guard's measure; FST writes
/// in blocks, so the count moves in steps).
struct Counting {
    inner: Box<dyn WriteSeek>,
    bytes: Arc<AtomicU64>,
}

impl Write for Counting {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes.fetch_add(n as u64, Ordering::Relaxed);
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for Counting {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

pub(super) struct FstSink {
    w: Option<FstWriter<Counting>>,
    /// Handles: the writer's (1-based) per declared variable.
    handles: Vec<u32>,
    /// One enum table per FSM type, keyed by its name list.
    tables: HashMap<usize, u32>,
    text: String,
    error: Option<io::Error>,
    bytes: Arc<AtomicU64>,
}

fn io_err(e: wavefst::Error) -> io::Error {
    io::Error::other(format!("FST writer: {e}"))
}

impl FstSink {
    pub(super) fn new(out: Box<dyn WriteSeek>) -> io::Result<Self> {
        let bytes = Arc::new(AtomicU64::new(0));
        let w = FstWriter::builder(Counting {
            inner: out,
            bytes: bytes.clone(),
        })
        .timescale_exponent(-12)
        // LZ4 per signal chain, as GTKWave's own writer can: without a
        // codec (the crate's default here) a chip trace is as big as its VCD.
        .chain_compression(wavefst::ChainCompression::Lz4)
        .build()
        .map_err(io_err)?;
        Ok(FstSink {
            w: Some(w),
            handles: Vec::new(),
            tables: HashMap::new(),
            text: String::new(),
            error: None,
            bytes,
        })
    }

    fn w(&mut self) -> &mut FstWriter<Counting> {
        self.w
            .as_mut()
            .expect("an FST sink is used until it finishes")
    }

    /// Keeps the first declaration error for `end_header` to report (the
    /// declarations cannot fail on their own: names come from the declaration).
    fn keep<T>(&mut self, r: wavefst::Result<T>) -> Option<T> {
        match r {
            Ok(v) => Some(v),
            Err(e) => {
                self.error.get_or_insert(io_err(e));
                None
            }
        }
    }

    /// The table of an FSM's encodings, created at its first register (and
    /// named after it: `state_t`).
    fn enum_table(&mut self, var: &str, names: &'static [&'static str], width: u32) -> Option<u32> {
        let key = names.as_ptr() as usize;
        if let Some(h) = self.tables.get(&key) {
            return Some(*h);
        }
        let values: Vec<String> = (0..names.len())
            .map(|k| format!("{k:0w$b}", w = width as usize))
            .collect();
        let entries: Vec<(&str, &str)> = names
            .iter()
            .zip(&values)
            .map(|(n, v)| (*n, v.as_str()))
            .collect();
        let r = self
            .w()
            .create_enum_table(&format!("{var}_t"), &entries, width as usize);
        let h = self.keep(r)?;
        self.tables.insert(key, h);
        Some(h)
    }
}

impl Sink for FstSink {
    fn begin_scope(&mut self, name: &str, kind: ScopeKind) {
        let t = match kind {
            ScopeKind::Module => ScopeType::VcdModule,
            ScopeKind::Struct => ScopeType::VcdStruct,
        };
        let r = self.w().begin_scope(t, name, None);
        self.keep(r);
    }
    fn end_scope(&mut self) {
        let r = self.w().end_scope();
        self.keep(r);
    }
    fn comment(&mut self, text: &str) {
        let r = self
            .w()
            .add_misc_attribute(wavefst::MiscAttributeType::Comment, text, 0);
        self.keep(r);
    }
    fn var(&mut self, v: &VarDef) -> u32 {
        if let Some(names) = v.enum_names
            && let Some(table) = self.enum_table(v.name, names, v.width)
        {
            let r = self.w().add_enum_table_ref(table);
            self.keep(r);
        }
        let (t, g) = match v.kind {
            VarKind::Wire => (VarType::VcdWire, GeomEntry::Fixed(v.width)),
            VarKind::Reg => (VarType::VcdReg, GeomEntry::Fixed(v.width)),
            VarKind::Real => (VarType::VcdReal, GeomEntry::Real),
        };
        let r = self.w().add_variable(t, VarDir::Implicit, v.name, g);
        let h = self.keep(r).unwrap_or(0);
        self.handles.push(h);
        (self.handles.len() - 1) as u32
    }
    fn id_len(&self, _h: u32) -> usize {
        // A change is a varint time delta and the value, per signal chain.
        1
    }
    fn end_header(&mut self) -> io::Result<u64> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let header = Header {
            version: format!("dualstream {}", env!("CARGO_PKG_VERSION")),
            ..Header::default()
        };
        self.w().write_header(header).map_err(io_err)?;
        Ok(self.bytes())
    }
    fn bits(&mut self, t: Time, h: u32, v: &Bits, width: u32) -> io::Result<()> {
        let handle = self.handles[h as usize];
        if width == 1 {
            return self
                .w()
                .emit_binary_change(t, handle, v.bit(0))
                .map_err(io_err);
        }
        // MSB first, one character per bit, as the format stores vectors.
        self.text.clear();
        let words = v.words();
        for i in (0..width).rev() {
            let w = words.get((i / 64) as usize).copied().unwrap_or(0);
            self.text
                .push(if (w >> (i % 64)) & 1 == 1 { '1' } else { '0' });
        }
        let text = std::mem::take(&mut self.text);
        let r = self
            .w()
            .emit_change(t, handle, SignalValue::Vector(text.as_str().into()));
        self.text = text;
        r.map_err(io_err)
    }
    fn real(&mut self, t: Time, h: u32, v: f64) -> io::Result<()> {
        let handle = self.handles[h as usize];
        self.w()
            .emit_change(t, handle, SignalValue::Real(v))
            .map_err(io_err)
    }
    fn finish(&mut self, end: Time) -> io::Result<()> {
        let Some(mut w) = self.w.take() else {
            return Ok(());
        };
        // The trace's end time is its last recorded time: mark `end` so the
        // viewer shows the final values up to it.
        w.emit_dump_active(end, true).map_err(io_err)?;
        w.finish().map_err(io_err)?.flush()
    }
    fn bytes(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }
}
