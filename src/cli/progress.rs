//! Progress of long commands on stderr: an indicatif bar with its ETA when
//! stderr is a terminal, else a plain line at most every few seconds (a time
//! check on each update, no thread), nothing with `--quiet`.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// `--quiet`: no progress at all.
static QUIET: AtomicBool = AtomicBool::new(false);

/// The plain lines' interval when stderr is not a terminal.
const LINE_EVERY: Duration = Duration::from_secs(5);

/// Overrides [`LINE_EVERY`] (milliseconds), for tests of the plain lines.
const LINE_EVERY_ENV: &str = "DUALSTREAM_PROGRESS_INTERVAL_MS";

/// Sets `--quiet` for the whole command.
pub fn set_quiet(q: bool) {
    QUIET.store(q, Ordering::Relaxed);
}

/// Whether `--quiet` was given: what is said only to show progress stays unsaid.
pub fn quiet() -> bool {
    QUIET.load(Ordering::Relaxed)
}

/// One piece of long work: `len` units (`0`: unknown), with a message.
pub struct Meter {
    how: How,
}

enum How {
    Quiet,
    Bar(indicatif::ProgressBar),
    Lines {
        what: String,
        len: u64,
        pos: u64,
        msg: String,
        start: Instant,
        last: Instant,
        every: Duration,
    },
}

impl Meter {
    /// A meter of `what` (e.g. "render") over `len` units (0: unknown).
    pub fn new(what: &str, len: u64) -> Meter {
        let how = if quiet() {
            How::Quiet
        } else if std::io::stderr().is_terminal() {
            let bar = if len == 0 {
                indicatif::ProgressBar::new_spinner()
            } else {
                indicatif::ProgressBar::new(len)
            };
            let tpl = if len == 0 {
                format!("{what} {{elapsed_precise}} {{spinner}} {{msg}}")
            } else {
                format!(
                    "{what} {{elapsed_precise}} [{{bar:40}}] {{percent}}% {{msg}} (ETA {{eta}})"
                )
            };
            bar.set_style(
                indicatif::ProgressStyle::with_template(&tpl)
                    .expect("valid template")
                    .progress_chars("=> "),
            );
            How::Bar(bar)
        } else {
            let every = std::env::var(LINE_EVERY_ENV)
                .ok()
                .and_then(|v| v.parse().ok())
                .map_or(LINE_EVERY, Duration::from_millis);
            let now = Instant::now();
            How::Lines {
                what: what.to_string(),
                len,
                pos: 0,
                msg: String::new(),
                start: now,
                last: now,
                every,
            }
        };
        Meter { how }
    }

    /// Moves to `pos` of the length, with `msg`; cheap when nothing is shown.
    pub fn set(&mut self, pos: u64, msg: impl FnOnce() -> String) {
        match &mut self.how {
            How::Quiet => {}
            How::Bar(b) => {
                b.set_position(pos);
                b.set_message(msg());
            }
            How::Lines {
                pos: p,
                msg: m,
                last,
                every,
                ..
            } => {
                *p = pos;
                let now = Instant::now();
                if now.duration_since(*last) >= *every {
                    *last = now;
                    *m = msg();
                    self.line();
                }
            }
        }
    }

    /// A new length (when the first estimate is passed).
    pub fn set_len(&mut self, n: u64) {
        match &mut self.how {
            How::Quiet => {}
            How::Bar(b) => b.set_length(n),
            How::Lines { len, .. } => *len = n,
        }
    }

    /// The current length (0: unknown).
    pub fn len(&self) -> u64 {
        match &self.how {
            How::Quiet => 0,
            How::Bar(b) => b.length().unwrap_or(0),
            How::Lines { len, .. } => *len,
        }
    }

    /// Prints a plain line: elapsed, fraction, ETA from the rate so far.
    fn line(&mut self) {
        if let How::Lines {
            what,
            len,
            pos,
            msg,
            start,
            ..
        } = &self.how
        {
            let el = start.elapsed().as_secs_f64();
            let frac = if *len > 0 {
                (*pos as f64 / *len as f64).min(1.0)
            } else {
                0.0
            };
            let eta = if frac > 0.0 && frac < 1.0 {
                format!(", ETA {:.0} s", el * (1.0 - frac) / frac)
            } else {
                String::new()
            };
            let pct = if *len > 0 {
                format!(" {:.0}%", frac * 100.0)
            } else {
                String::new()
            };
            eprintln!("{what}: {el:.0} s{pct}{eta}: {msg}");
        }
    }

    /// The work is done: the bar is cleared; a plain line says so.
    pub fn finish(mut self, msg: &str) {
        match &mut self.how {
            How::Quiet => {}
            How::Bar(b) => b.finish_and_clear(),
            How::Lines {
                pos, len, msg: m, ..
            } => {
                if *len > 0 {
                    *pos = *len;
                }
                *m = msg.to_string();
                self.line();
            }
        }
    }
}
