//! The GTKWave save file written beside a trace (`trace.vcd.gtkw`), and a
//! translate filter per FSM (`trace.vcd.<fsm>.filter`), so `gtkwave trace.vcd
//! trace.vcd.gtkw` opens on the window with clocks first, one group per unit
//! instance, each port's valid, ready, fire, data and fields, the registers,
//! and every FSM state by name.
//!
//! The files it names are relative to the save file: GTKWave reads a
//! relative `^1` filter path against the working directory, unless the save
//! file has a `[savefile]` line (the path it was written at, as GTKWave
//! writes its own), when it resolves it against the save file's directory
//! (savefile.c, `get_relative_adjusted_name`). So the trace, its filters and
//! its save file can move together and open from anywhere.
//!
//! The format is GTKWave's own (what it writes with File > Write Save File):
//! a line `@<flags>` sets the display flags of the signals after it; a
//! `-name` line under a group flag opens or closes a group.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::super::sim::Time;

/// GTKWave's trace flags (`TR_*` in its analyzer.h).
mod flag {
    pub const HEX: u32 = 0x2;
    pub const DEC: u32 = 0x4;
    pub const BIN: u32 = 0x8;
    pub const RJUSTIFY: u32 = 0x20;
    pub const BLANK: u32 = 0x200;
    pub const FTRANSLATED: u32 = 0x2000;
    pub const CLOSED: u32 = 0x40_0000;
    pub const GRP_BEGIN: u32 = 0x80_0000;
    pub const GRP_END: u32 = 0x100_0000;
    /// Names from the trace's own enum table (FST).
    pub const ENUM: u64 = 0x1_0000_0000;
}

/// Unit groups shown open; the rest start closed (a full chip has thousands).
const OPEN_UNITS: usize = 4;

/// Unit instances the view lists, in trace order: GTKWave takes minutes to
/// load a view of a whole chip's 800,000 signals, and nobody reads them
/// all at once; the rest are in its signal tree.
pub(crate) const VIEW_UNITS: usize = 64;

/// Named markers a save file holds (GTKWave's A to Z).
pub(crate) const NAMED_MARKERS: usize = 26;

/// One line of the view.
pub(crate) enum Entry {
    Begin {
        name: String,
        closed: bool,
    },
    End,
    /// A signal's name as GTKWave shows it (`chip.tm0.tp0.ray_data[383:0]`),
    /// and the FSM whose names it shows, if any.
    Sig {
        name: String,
        width: u32,
        fsm: Option<usize>,
    },
}

/// What the save file shows, collected while the header is declared.
#[derive(Default)]
pub(crate) struct View {
    pub entries: Vec<Entry>,
    /// Units seen so far (the first `OPEN_UNITS` groups are open, the first
    /// `VIEW_UNITS` listed).
    pub units: usize,
    /// Whether the unit being declared is beyond `VIEW_UNITS`.
    skipping: bool,
    /// Where the unit being declared begins in `entries`.
    unit_start: usize,
    /// Each FSM's state names and the file stem of its filter.
    pub fsms: Vec<(&'static [&'static str], String)>,
}

impl View {
    /// A signal as GTKWave names it: vectors carry their range.
    pub fn sig(
        &mut self,
        path: std::fmt::Arguments,
        width: u32,
        real: bool,
        fsm: Option<&'static [&'static str]>,
        fsm_name: &str,
    ) {
        if self.skipping {
            return;
        }
        let name = if width > 1 && !real {
            format!("{path}[{}:0]", width - 1)
        } else {
            path.to_string()
        };
        let fsm =
            fsm.map(
                |names| match self.fsms.iter().position(|(n, _)| std::ptr::eq(*n, names)) {
                    Some(k) => k,
                    None => {
                        self.fsms.push((names, fsm_name.to_string()));
                        self.fsms.len() - 1
                    }
                },
            );
        self.entries.push(Entry::Sig {
            name,
            width: if real { 1 } else { width },
            fsm,
        });
    }

    /// A filter's file name, beside the trace: named after the whole file
    /// name, as the save file is.
    fn filter_name(trace: &Path, stem: &str) -> String {
        let base = trace
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        format!("{base}.{stem}.filter")
    }

    /// Writes `trace.vcd.gtkw` (the trace's whole name plus `.gtkw`) beside `trace`, and for a VCD the filters;
    /// `from..=to` is the window shown, `markers` (time, name; at most
    /// `NAMED_MARKERS`) its named markers, the primary marker on the first.
    /// Returns the save file's path.
    pub fn write(
        &self,
        trace: &Path,
        fst: bool,
        from: Time,
        to: Time,
        markers: &[(Time, String)],
    ) -> std::io::Result<PathBuf> {
        let trace = std::path::absolute(trace)?;
        // An FST carries its enum tables, which GTKWave applies itself.
        for (names, stem) in self.fsms.iter().filter(|_| !fst) {
            let mut f = String::from("# FSM state encodings, written by dualstream\n");
            for (k, n) in names.iter().enumerate() {
                let _ = writeln!(f, "{k} {n}");
            }
            std::fs::write(trace.with_file_name(Self::filter_name(&trace, stem)), f)?;
        }
        let mut s = String::new();
        let _ = writeln!(
            s,
            "[*] written by dualstream {} beside the trace",
            env!("CARGO_PKG_VERSION")
        );
        if self.units > VIEW_UNITS {
            let _ = writeln!(
                s,
                "[*] the first {VIEW_UNITS} of {} unit instances; the rest are in the signal tree",
                self.units
            );
        }
        // Paths relative to the save file (see the module's comment).
        let out = super::save_file_for(&trace);
        let name = trace.file_name().unwrap_or_default().to_string_lossy();
        let _ = writeln!(s, "[dumpfile] \"{name}\"");
        let _ = writeln!(s, "[savefile] \"{}\"", out.display());
        let _ = writeln!(s, "[timestart] {from}");
        let _ = writeln!(s, "[size] 1600 900");
        // GTKWave's zoom is a power of two: this fits the window's span in
        // the wave pane of a 1600-pixel window.
        let span = (to.saturating_sub(from)).max(1) as f64;
        let zoom = 2.2 - span.log2();
        if markers.is_empty() {
            let _ = writeln!(s, "*{zoom:.6} {from} -1");
        } else {
            // `*zoom primary A B ...`, then each named marker's `[markername]`
            // (its letter, then the name), as GTKWave writes them.
            let _ = write!(s, "*{zoom:.6} {}", markers[0].0);
            for (t, _) in markers.iter().take(NAMED_MARKERS) {
                let _ = write!(s, " {t}");
            }
            let _ = writeln!(s);
            for (k, (_, name)) in markers.iter().take(NAMED_MARKERS).enumerate() {
                let _ = writeln!(s, "[markername] {}{name}", (b'A' + k as u8) as char);
            }
        }
        let _ = writeln!(s, "[sst_width] 280");
        let _ = writeln!(s, "[signals_width] 320");
        let mut last_flags = None;
        let mut set = |s: &mut String, f: u64| {
            if last_flags != Some(f) {
                let _ = writeln!(s, "@{f:x}");
                last_flags = Some(f);
            }
        };
        // Open groups: name and whether closed (a group inside a closed one is too).
        let mut groups: Vec<(&str, bool)> = Vec::new();
        for e in &self.entries {
            match e {
                Entry::Begin { name, closed } => {
                    let closed = *closed || groups.last().is_some_and(|g| g.1);
                    let c = if closed { flag::CLOSED } else { 0 };
                    set(&mut s, (flag::GRP_BEGIN | flag::BLANK | c) as u64);
                    let _ = writeln!(s, "-{name}");
                    groups.push((name, closed));
                }
                Entry::End => {
                    let (name, closed) = groups.pop().expect("a group is open");
                    let c = if closed { flag::CLOSED } else { 0 };
                    set(&mut s, (flag::GRP_END | flag::BLANK | c) as u64);
                    let _ = writeln!(s, "-{name}");
                }
                Entry::Sig { name, width, fsm } => {
                    let f = match (fsm, width) {
                        (Some(_), _) if fst => flag::ENUM | (flag::RJUSTIFY | flag::BIN) as u64,
                        (Some(k), _) => {
                            set(
                                &mut s,
                                (flag::FTRANSLATED | flag::RJUSTIFY | flag::DEC) as u64,
                            );
                            let _ =
                                writeln!(s, "^1 {}", Self::filter_name(&trace, &self.fsms[*k].1));
                            let _ = writeln!(s, "{name}");
                            continue;
                        }
                        (None, 1) => (flag::RJUSTIFY | flag::BIN) as u64,
                        _ => (flag::RJUSTIFY | flag::HEX) as u64,
                    };
                    set(&mut s, f);
                    let _ = writeln!(s, "{name}");
                }
            }
        }
        std::fs::write(&out, s)?;
        Ok(out)
    }

    /// Opens a unit's group (closed beyond the first few).
    pub fn begin_unit(&mut self, path: &str) {
        let closed = self.units >= OPEN_UNITS;
        self.units += 1;
        self.skipping = self.units > VIEW_UNITS;
        self.unit_start = self.entries.len();
        self.begin(path, closed);
    }

    /// Closes a unit's group, its FSM registers moved to its top: what an
    /// RTL engineer looks for first, above the ports.
    pub fn end_unit(&mut self) {
        if self.skipping {
            return;
        }
        let body = self.entries.split_off(self.unit_start + 1);
        let (mut fsms, mut rest) = (Vec::new(), Vec::new());
        let mut depth = 0;
        for e in body {
            match &e {
                Entry::Begin { .. } => depth += 1,
                Entry::End => depth -= 1,
                Entry::Sig { fsm: Some(_), .. } if depth == 0 => {
                    fsms.push(e);
                    continue;
                }
                Entry::Sig { .. } => {}
            }
            rest.push(e);
        }
        self.entries.append(&mut fsms);
        self.entries.append(&mut rest);
        self.end();
    }

    pub fn begin(&mut self, name: &str, closed: bool) {
        if self.skipping {
            return;
        }
        self.entries.push(Entry::Begin {
            name: name.to_string(),
            closed,
        });
    }

    pub fn end(&mut self) {
        if self.skipping {
            return;
        }
        self.entries.push(Entry::End);
    }
}
