//! DRAMsim3's trace format and trace generators.
//!
//! One request per line: `<hex address, 0x optional> <op> <decimal cycle>`, e.g.
//! `0x2000D5C0 READ 30`. The op `WRITE`, `write`, `P_MEM_WR` or `BOFF` is a
//! write, anything else a read. The cycle is the earliest DRAM clock at which the
//! request may issue. Blank lines are skipped.

use std::io::Write;

use super::MemError;
use super::config::MemCfg;
use crate::util::rng::Rng;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceReq {
    pub addr: u64,
    pub write: bool,
    pub cycle: u64,
}

/// Parses one line (`lineno` counts from 1, for the message).
pub fn parse_line(line: &str, lineno: usize) -> Result<Option<TraceReq>, MemError> {
    let mut f = line.split_whitespace();
    let Some(a) = f.next() else {
        return Ok(None);
    };
    let (Some(op), Some(cy)) = (f.next(), f.next()) else {
        return Err(MemError::Trace(format!(
            "trace line {lineno}: '{line}' has fewer than 3 fields; expected '<hex address> <READ|WRITE> <cycle>', e.g. '0x2000D5C0 READ 30'"
        )));
    };
    if let Some(x) = f.next() {
        return Err(MemError::Trace(format!(
            "trace line {lineno}: unexpected 4th field '{x}'; expected '<hex address> <op> <cycle>'"
        )));
    }
    let hex = a
        .strip_prefix("0x")
        .or_else(|| a.strip_prefix("0X"))
        .unwrap_or(a);
    let addr = u64::from_str_radix(hex, 16).map_err(|e| {
        MemError::Trace(format!(
            "trace line {lineno}: address '{a}' is not a hexadecimal number ({e})"
        ))
    })?;
    let cycle = cy.parse::<u64>().map_err(|e| {
        MemError::Trace(format!(
            "trace line {lineno}: cycle '{cy}' is not a non-negative decimal integer ({e})"
        ))
    })?;
    let write = matches!(op, "WRITE" | "write" | "P_MEM_WR" | "BOFF");
    Ok(Some(TraceReq { addr, write, cycle }))
}

/// Parses a whole trace and checks every address against `capacity`.
pub fn parse(text: &str, capacity: u64) -> Result<Vec<TraceReq>, MemError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if let Some(r) = parse_line(line, i + 1)? {
            if r.addr >= capacity {
                return Err(MemError::Trace(format!(
                    "trace line {}: address {:#x} is beyond the configured capacity of {capacity} bytes ({capacity:#x}); use a config with a larger mem.geometry or fix the trace",
                    i + 1,
                    r.addr
                )));
            }
            out.push(r);
        }
    }
    Ok(out)
}

pub fn read_file(path: &std::path::Path, capacity: u64) -> Result<Vec<TraceReq>, MemError> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        let msg = format!("cannot read trace '{}': {e}", path.display());
        MemError::File(crate::util::FileError::new(path, e, msg))
    })?;
    parse(&text, capacity).map_err(|e| MemError::Trace(format!("{} ({})", e, path.display())))
}

/// Writes requests in DRAMsim3's format.
pub fn write(reqs: &[TraceReq], out: &mut impl Write) -> std::io::Result<()> {
    for r in reqs {
        writeln!(
            out,
            "{:#X} {} {}",
            r.addr,
            if r.write { "WRITE" } else { "READ" },
            r.cycle
        )?;
    }
    Ok(())
}

pub const GENERATORS: &[&str] = &["random", "stream", "mixed"];

/// Trace generators, one line per request, request `i` at cycle `i * interval`
/// (interval 0: all at cycle 0, i.e. unthrottled: a request is always waiting).
/// - `random`: uniform line addresses over the capacity, writes with
///   probability `write_fraction`;
/// - `stream`: consecutive lines from address 0;
/// - `mixed`: dual-streaming-like traffic: 2 KB ray buckets read whole (32
///   lines from a random 2 KB-aligned start, 60%), random reads (15%) and random
///   single-line writes (25%, hit records).
pub fn generate(
    kind: &str,
    n: u64,
    seed: u64,
    cfg: &MemCfg,
    interval: u64,
    write_fraction: f64,
) -> Result<Vec<TraceReq>, MemError> {
    if !(0.0..=1.0).contains(&write_fraction) {
        return Err(MemError::Trace(format!(
            "--write-fraction {write_fraction} is not a probability in [0, 1]"
        )));
    }
    let line = cfg.geometry.line_bytes as u64;
    let lines = cfg.geometry.capacity() / line;
    let mut rng = Rng::new(seed);
    let rand_line = |rng: &mut Rng| {
        // Two draws: `below` covers 2^32 values at a time.
        let hi = rng.below(lines.div_ceil(1 << 32).max(1));
        ((hi << 32) | rng.below(lines.min(1 << 32))) % lines
    };
    let mut out = Vec::with_capacity(n as usize);
    let cycle = |i: usize| i as u64 * interval;
    match kind {
        "random" => {
            for i in 0..n as usize {
                let addr = rand_line(&mut rng) * line;
                let write = write_fraction > 0.0 && rng.chance(write_fraction);
                out.push(TraceReq {
                    addr,
                    write,
                    cycle: cycle(i),
                });
            }
        }
        "stream" => {
            for i in 0..n as usize {
                let write = write_fraction > 0.0 && rng.chance(write_fraction);
                out.push(TraceReq {
                    addr: (i as u64 % lines) * line,
                    write,
                    cycle: cycle(i),
                });
            }
        }
        "mixed" => {
            let bucket = (2048 / line).max(1);
            while (out.len() as u64) < n {
                // Event weights give 60% of requests in buckets (32 lines each),
                // 25% random writes and 15% random reads.
                let lines_per_bucket = bucket as f64;
                let wb = 60.0 / lines_per_bucket;
                let r = rng.unit_f32() as f64 * (wb + 25.0 + 15.0);
                if r >= wb {
                    let addr = rand_line(&mut rng) * line;
                    let i = out.len();
                    out.push(TraceReq {
                        addr,
                        write: r < wb + 25.0,
                        cycle: cycle(i),
                    });
                } else {
                    let base = rand_line(&mut rng) / bucket * bucket;
                    for k in 0..bucket.min(n - out.len() as u64) {
                        let i = out.len();
                        out.push(TraceReq {
                            addr: ((base + k) % lines) * line,
                            write: false,
                            cycle: cycle(i),
                        });
                    }
                }
            }
        }
        _ => {
            return Err(MemError::Unknown(format!(
                "unknown trace generator '{kind}'; available: {}",
                GENERATORS.join(", ")
            )));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_dramsim3_format_and_names_bad_lines() {
        let t = "0x2000D5C0 READ 30\n2000D600 WRITE 31\n\n0x40 P_MEM_WR 32\n0x80 BOFF 33\n0xC0 P_FETCH 34\n";
        let r = parse(t, 1 << 32).unwrap();
        assert_eq!(r.len(), 5);
        assert_eq!(
            r[0],
            TraceReq {
                addr: 0x2000D5C0,
                write: false,
                cycle: 30
            }
        );
        assert!(r[1].write && r[2].write && r[3].write && !r[4].write);
        let e = parse("0x10 READ 1\nzz READ 2\n", 1 << 32)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("hexadecimal"), "{e}");
        let e = parse("0x10 READ\n", 1 << 32).unwrap_err().to_string();
        assert!(e.contains("line 1") && e.contains("fewer than 3"), "{e}");
        let e = parse("0x10 READ -4\n", 1 << 32).unwrap_err().to_string();
        assert!(e.contains("cycle '-4'"), "{e}");
        let e = parse("0x10 READ 1\n0x100000000 READ 2\n", 1 << 32)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("beyond"), "{e}");
    }

    #[test]
    fn generated_traces_round_trip() {
        let cfg = MemCfg::paper();
        for k in GENERATORS {
            let g = generate(k, 500, 3, &cfg, 2, 0.3).unwrap();
            assert_eq!(g.len(), 500);
            let mut buf = Vec::new();
            write(&g, &mut buf).unwrap();
            let back = parse(std::str::from_utf8(&buf).unwrap(), cfg.geometry.capacity()).unwrap();
            assert_eq!(back, g);
        }
        assert!(generate("zigzag", 1, 1, &cfg, 0, 0.0).is_err());
    }
}
