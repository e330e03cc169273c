//! The VCD writer: a text header of scopes and variables, then `#time` lines
//! and one line per value change, formatted directly into a reused buffer.

use std::fmt::Write as _;
use std::io::{self, BufWriter, Write};

use super::super::bits::Bits;
use super::super::sim::Time;
use super::sink::{ScopeKind, Sink, VarDef, VarKind};

/// Counts what passes through, for the size guard.
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

pub(super) struct VcdSink {
    out: CountingWriter,
    header: String,
    ids: Vec<String>,
    time_written: Option<Time>,
    line: Vec<u8>,
}

impl VcdSink {
    pub(super) fn new(out: Box<dyn Write>) -> Self {
        let mut header = String::new();
        header.push_str("$version dualstream ");
        header.push_str(env!("CARGO_PKG_VERSION"));
        header.push_str(" $end\n$timescale 1ps $end\n");
        VcdSink {
            out: CountingWriter {
                inner: BufWriter::with_capacity(1 << 16, out),
                bytes: 0,
            },
            header,
            ids: Vec::new(),
            time_written: None,
            line: Vec::with_capacity(256),
        }
    }

    fn at(&mut self, t: Time) -> io::Result<()> {
        if self.time_written != Some(t) {
            self.time_written = Some(t);
            self.line.clear();
            self.line.push(b'#');
            self.line.extend_from_slice(t.to_string().as_bytes());
            self.line.push(b'\n');
            self.out.write_all(&self.line)?;
        }
        Ok(())
    }
}

impl Sink for VcdSink {
    fn begin_scope(&mut self, name: &str, kind: ScopeKind) {
        // The `vcd` crate and GTKWave both read `begin` as a named block: the
        // nearest VCD has to a struct.
        let k = match kind {
            ScopeKind::Module => "module",
            ScopeKind::Struct => "begin",
        };
        let _ = writeln!(self.header, "$scope {k} {name} $end");
    }
    fn end_scope(&mut self) {
        self.header.push_str("$upscope $end\n");
    }
    fn comment(&mut self, text: &str) {
        let _ = writeln!(self.header, "$comment {text} $end");
    }
    fn var(&mut self, v: &VarDef) -> u32 {
        let id = vcd_id(self.ids.len() as u64);
        let kind = match v.kind {
            VarKind::Wire => "wire",
            VarKind::Reg => "reg",
            VarKind::Real => "real",
        };
        let name = v.name;
        // Formatted in place: a full chip declares hundreds of thousands.
        let _ = if v.kind == VarKind::Real {
            writeln!(self.header, "$var real 64 {id} {name} $end")
        } else if v.width == 1 {
            writeln!(self.header, "$var {kind} 1 {id} {name} $end")
        } else {
            writeln!(
                self.header,
                "$var {kind} {} {id} {name} [{}:0] $end",
                v.width,
                v.width - 1
            )
        };
        self.ids.push(id);
        (self.ids.len() - 1) as u32
    }
    fn id_len(&self, h: u32) -> usize {
        self.ids[h as usize].len()
    }
    fn end_header(&mut self) -> io::Result<u64> {
        self.header.push_str("$enddefinitions $end\n");
        let h = std::mem::take(&mut self.header);
        self.out.write_all(h.as_bytes())?;
        Ok(h.len() as u64)
    }
    fn bits(&mut self, t: Time, h: u32, v: &Bits, width: u32) -> io::Result<()> {
        self.at(t)?;
        self.line.clear();
        format_value(&mut self.line, v, width, &self.ids[h as usize]);
        self.out.write_all(&self.line)
    }
    fn real(&mut self, t: Time, h: u32, v: f64) -> io::Result<()> {
        self.at(t)?;
        self.line.clear();
        // `{:?}` prints the shortest text that reads back as the same f64
        // (and `NaN`/`inf`, which GTKWave reads).
        self.line.push(b'r');
        let _ = io::Write::write_fmt(&mut self.line, format_args!("{v:?} "));
        self.line.extend_from_slice(self.ids[h as usize].as_bytes());
        self.line.push(b'\n');
        self.out.write_all(&self.line)
    }
    fn finish(&mut self, end: Time) -> io::Result<()> {
        // Close the trace at the last simulated time so viewers show the final values.
        if self.time_written.is_none_or(|t| t < end) {
            writeln!(self.out, "#{end}")?;
        }
        self.out.flush()
    }
    fn bytes(&self) -> u64 {
        self.out.bytes
    }
}

/// Short VCD identifier from printable ASCII 33..=126.
pub(super) fn vcd_id(mut n: u64) -> String {
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
pub(super) fn format_value(out: &mut Vec<u8>, v: &Bits, width: u32, id: &str) {
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
