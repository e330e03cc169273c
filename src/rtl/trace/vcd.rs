//! The VCD writer: a text header of scopes and variables, then `#time` lines
//! and one line per value change, formatted directly into a reused buffer.

use std::io::{self, Write};

use super::super::bits::Bits;
use super::super::sim::Time;
use super::sink::{ScopeKind, Sink, VarDef, VarKind};

pub(super) struct VcdSink {
    out: Box<dyn Write>,
    /// Value changes formatted in place, handed to `out` a block at a time.
    buf: Vec<u8>,
    /// Bytes handed to `out` so far.
    flushed: u64,
    /// A failed write of the header (declarations cannot fail; `end_header`
    /// reports it).
    header_error: Option<io::Error>,
    /// Each variable's identifier: up to 7 characters, the length in byte 7
    /// (one load per change, not a pointer to chase).
    ids: Vec<[u8; 8]>,
    time_written: Option<Time>,
}

/// How much `buf` holds before it goes to the file.
const BLOCK: usize = 1 << 20;

impl VcdSink {
    pub(super) fn new(out: Box<dyn Write>) -> Self {
        let mut buf = Vec::with_capacity(BLOCK + 4096);
        buf.extend_from_slice(b"$version dualstream ");
        buf.extend_from_slice(env!("CARGO_PKG_VERSION").as_bytes());
        buf.extend_from_slice(b" $end\n$timescale 1ps $end\n");
        VcdSink {
            out,
            buf,
            flushed: 0,
            header_error: None,
            ids: Vec::new(),
            time_written: None,
        }
    }

    fn at(&mut self, t: Time) -> io::Result<()> {
        if self.time_written != Some(t) {
            self.time_written = Some(t);
            self.buf.push(b'#');
            self.buf.extend_from_slice(t.to_string().as_bytes());
            self.buf.push(b'\n');
        }
        if self.buf.len() >= BLOCK {
            self.flush_block()?;
        }
        Ok(())
    }

    fn flush_block(&mut self) -> io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.flushed += self.buf.len() as u64;
        self.buf.clear();
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
        let _ = writeln!(self.buf, "$scope {k} {name} $end");
    }
    fn end_scope(&mut self) {
        self.buf.extend_from_slice(b"$upscope $end\n");
    }
    fn comment(&mut self, text: &str) {
        let _ = writeln!(self.buf, "$comment {text} $end");
    }
    fn var(&mut self, v: &VarDef) -> u32 {
        let id = vcd_id(self.ids.len() as u64);
        let mut packed = [0u8; 8];
        packed[..id.len()].copy_from_slice(id.as_bytes());
        packed[7] = id.len() as u8;
        let kind = match v.kind {
            VarKind::Wire => "wire",
            VarKind::Reg => "reg",
            VarKind::Real => "real",
        };
        let name = v.name;
        // Formatted in place: a full chip declares hundreds of thousands.
        let _ = if v.kind == VarKind::Real {
            writeln!(self.buf, "$var real 64 {id} {name} $end")
        } else if v.width == 1 {
            writeln!(self.buf, "$var {kind} 1 {id} {name} $end")
        } else {
            writeln!(
                self.buf,
                "$var {kind} {} {id} {name} [{}:0] $end",
                v.width,
                v.width - 1
            )
        };
        self.ids.push(packed);
        // The header goes out a block at a time (a full chip's is 38 MB).
        if self.buf.len() >= BLOCK && self.header_error.is_none() {
            self.header_error = self.flush_block().err();
        }
        (self.ids.len() - 1) as u32
    }
    fn id_len(&self, h: u32) -> usize {
        self.ids[h as usize][7] as usize
    }
    fn end_header(&mut self) -> io::Result<u64> {
        self.buf.extend_from_slice(b"$enddefinitions $end\n");
        if let Some(e) = self.header_error.take() {
            return Err(e);
        }
        self.flush_block()?;
        Ok(self.flushed)
    }
    fn bits(&mut self, t: Time, h: u32, v: &Bits, width: u32) -> io::Result<()> {
        self.at(t)?;
        let id = &self.ids[h as usize];
        format_value(&mut self.buf, v, width, &id[..id[7] as usize]);
        Ok(())
    }
    fn real(&mut self, t: Time, h: u32, v: f64) -> io::Result<()> {
        self.at(t)?;
        // `{:?}` prints the shortest text that reads back as the same f64
        // (and `NaN`/`inf`, which GTKWave reads).
        self.buf.push(b'r');
        let _ = io::Write::write_fmt(&mut self.buf, format_args!("{v:?} "));
        let id = &self.ids[h as usize];
        self.buf.extend_from_slice(&id[..id[7] as usize]);
        self.buf.push(b'\n');
        Ok(())
    }
    fn finish(&mut self, end: Time) -> io::Result<()> {
        // Close the trace at the last simulated time so viewers show the final values.
        if self.time_written.is_none_or(|t| t < end) {
            self.buf.extend_from_slice(format!("#{end}\n").as_bytes());
        }
        self.flush_block()?;
        self.out.flush()
    }
    fn bytes(&self) -> u64 {
        self.flushed + self.buf.len() as u64
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

/// `0!` for a scalar, `b1011 !` for a vector (leading zeros dropped, as VCD
/// allows). A vector's digits go a byte at a time: most of a chip trace's
/// bytes are wide payloads' digits.
pub(super) fn format_value(out: &mut Vec<u8>, v: &Bits, width: u32, id: &[u8]) {
    if width == 1 {
        out.push(if v.bit(0) { b'1' } else { b'0' });
    } else {
        out.push(b'b');
        let words = v.words();
        let top = words
            .iter()
            .enumerate()
            .rev()
            .find(|(_, w)| **w != 0)
            .map(|(wi, w)| wi as u32 * 64 + 63 - w.leading_zeros());
        match top {
            None => out.push(b'0'),
            Some(top) => {
                let bit = |i: u32| (words[(i / 64) as usize] >> (i % 64)) & 1;
                // The digits above the highest whole byte, one at a time ...
                let whole = (top + 1) / 8;
                for i in (whole * 8..=top).rev() {
                    out.push(b'0' + bit(i) as u8);
                }
                // ... then eight at a time.
                let start = out.len();
                out.resize(start + whole as usize * 8, 0);
                for (k, chunk) in out[start..].chunks_exact_mut(8).enumerate() {
                    let i = (whole - 1 - k as u32) * 8;
                    let byte = (words[(i / 64) as usize] >> (i % 64)) as u8;
                    chunk.copy_from_slice(&DIGITS[byte as usize]);
                }
            }
        }
        out.push(b' ');
    }
    out.extend_from_slice(id);
    out.push(b'\n');
}

/// A byte's eight binary digits, most significant first.
static DIGITS: [[u8; 8]; 256] = {
    let mut t = [[b'0'; 8]; 256];
    let mut b = 0;
    while b < 256 {
        let mut k = 0;
        while k < 8 {
            if (b >> (7 - k)) & 1 == 1 {
                t[b][k] = b'1';
            }
            k += 1;
        }
        b += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_format() {
        let mut b = Bits::new();
        b.push(0b101, 8);
        let mut out = Vec::new();
        format_value(&mut out, &b, 8, b"!");
        assert_eq!(out, b"b101 !\n");
        let mut z = Bits::new();
        z.push(0, 8);
        out.clear();
        format_value(&mut out, &z, 8, b"#");
        assert_eq!(out, b"b0 #\n");
        assert_eq!(vcd_id(0), "!");
        assert_eq!(vcd_id(94 * 94 * 94 - 1).len(), 3);
        assert_eq!(vcd_id(94), "!\"");
    }

    /// The byte-at-a-time digits equal the digits one bit at a time, for
    /// every width up to three words and values with their top bit anywhere.
    #[test]
    fn vector_digits_match_bit_by_bit() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for width in 2..=192u32 {
            for top in [0, width / 3, width / 2, width - 1] {
                let mut b = Bits::new();
                let mut left = width;
                let mut at = 0;
                while left > 0 {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    let w = left.min(64);
                    // Bits above `top` cleared: the leading digit moves.
                    let keep = (top + 1).saturating_sub(at).min(w);
                    let v = if keep == 0 {
                        0
                    } else {
                        x & (u64::MAX >> (64 - keep))
                    };
                    b.push(v, w);
                    left -= w;
                    at += w;
                }
                let mut want = b"b".to_vec();
                let digits: String = (0..width)
                    .rev()
                    .map(|i| if b.bit(i) { '1' } else { '0' })
                    .collect();
                let trimmed = digits.trim_start_matches('0');
                want.extend_from_slice(if trimmed.is_empty() { "0" } else { trimmed }.as_bytes());
                want.extend_from_slice(b" !\n");
                let mut got = Vec::new();
                format_value(&mut got, &b, width, b"!");
                assert_eq!(
                    String::from_utf8_lossy(&got),
                    String::from_utf8_lossy(&want),
                    "width {width}, top {top}"
                );
            }
        }
    }
}
