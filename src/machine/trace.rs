//! Waveforms of the chip (`render --mode cycle --vcd`): friendly unit names for
//! `--trace-units` and the core-cycle window of `--trace-window`, turned into the
//! kernel's [`TraceSpec`] (instance patterns, picoseconds). docs/chip.md has the
//! how-to.

use super::ChipError;
use crate::rtl::{Time, TraceSpec};

/// Names that stand for one global unit or a family of units: the name, the
/// other names it takes (`dualstream tb`'s bench names, so one name works in
/// both), the instance pattern it traces and what that is. `tm<k>` and
/// `mem_ctrl<c>` are added per instance.
type Named = (
    &'static str,
    &'static [&'static str],
    &'static str,
    &'static str,
);
const NAMED: &[Named] = &[
    (
        "scheduler",
        &["stream_scheduler"],
        "chip.scheduler",
        "the stream scheduler",
    ),
    ("scene_buffer", &[], "chip.scene_buffer", "the scene buffer"),
    (
        "hit_updater",
        &["hit_record_updater", "hru"],
        "chip.hit_updater",
        "the hit record updater",
    ),
    (
        "memory",
        &[],
        "chip.memory",
        "the memory unit (channel router)",
    ),
    (
        "mem_ctrl",
        &["dram"],
        "chip.mem_ctrl*",
        "every GDDR5 channel controller",
    ),
    (
        "tms",
        &["tm"],
        "chip.tm*",
        "every TM with its TPs, L1, crossbar, pipelines",
    ),
    ("host", &[], "chip.host", "the host stand-in"),
    ("l2", &[], "chip.l2*", "the L2"),
    ("tp", &[], "chip.tm*.tp*", "every TM's TPs"),
    ("l1", &[], "chip.tm*.l1", "every TM's L1"),
    ("xbar", &["tm_xbar"], "chip.tm*.xbar", "every TM's crossbar"),
    (
        "staging_buffer",
        &[],
        "chip.tm*.staging_buffer",
        "every TM's staging buffer",
    ),
    (
        "tri_pipe",
        &[],
        "chip.tm*.tri_pipe*",
        "every TM's triangle pipelines",
    ),
    ("divider", &[], "chip.tm*.divider", "every TM's divider"),
];

/// A unit name: a friendly name or one of its others, `tm<k>`, `mem_ctrl<c>`,
/// or an instance pattern (it has a `.` or a `*`: `chip.tm3.l1`, `chip.tm*.xbar`).
fn pattern_of(name: &str) -> Option<String> {
    if let Some((_, _, p, _)) = NAMED
        .iter()
        .find(|(n, also, _, _)| *n == name || also.contains(&name))
    {
        return Some(p.to_string());
    }
    for base in ["tm", "mem_ctrl"] {
        if let Some(k) = name.strip_prefix(base)
            && !k.is_empty()
            && k.bytes().all(|b| b.is_ascii_digit())
        {
            return Some(format!("chip.{base}{}", k.parse::<u64>().ok()?));
        }
    }
    (name.contains('.') || name.contains('*')).then(|| name.to_string())
}

/// The names valid for a chip whose instances are `paths`, for error messages.
pub fn valid_names(paths: &[&str]) -> String {
    let spec = |p: &str| TraceSpec {
        filter: p.into(),
        from: 0,
        to: 0,
        ..TraceSpec::all()
    };
    let mut v: Vec<String> = NAMED
        .iter()
        .filter(|(_, _, p, _)| paths.iter().any(|q| spec(p).matches(q)))
        .map(|(n, also, _, what)| match also {
            [] => format!("{n} ({what})"),
            a => format!("{n} ({what}; also {})", a.join(", ")),
        })
        .collect();
    // Instances are numbered from 0: the highest index names the range.
    let count = |base: &str| {
        paths
            .iter()
            .filter_map(|p| p.strip_prefix("chip.")?.split('.').next())
            .filter_map(|c| c.strip_prefix(base)?.parse::<usize>().ok())
            .map(|k| k + 1)
            .max()
            .unwrap_or(0)
    };
    let tms = count("tm");
    if tms > 0 {
        v.push(format!("tm0..tm{} (one TM)", tms - 1));
    }
    let ch = count("mem_ctrl");
    if ch > 0 {
        v.push(format!("mem_ctrl0..mem_ctrl{} (one channel)", ch - 1));
    }
    v.push("or an instance pattern such as chip.tm0.l1 or chip.tm*.xbar".into());
    v.join(", ")
}

/// The trace filter (comma-separated instance patterns) for the comma-separated
/// `units`, checked against the chip's instance `paths`: an unknown name or one
/// that matches no instance (`mem_ctrl` with the fixed memory, `tm9` on 8 TMs)
/// is an error listing the valid names. Empty `units`: every unit.
pub fn resolve(units: &str, paths: &[&str]) -> Result<String, ChipError> {
    let mut pats = Vec::new();
    for name in units.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let Some(p) = pattern_of(name) else {
            return Err(ChipError::UnknownUnit {
                name: name.to_string(),
                valid: valid_names(paths),
            });
        };
        let spec = TraceSpec {
            filter: p.clone(),
            from: 0,
            to: 0,
            ..TraceSpec::all()
        };
        if !paths.iter().any(|q| spec.matches(q)) {
            let hint = if name.starts_with("mem_ctrl") {
                " (the channel controllers exist with chip.memory.model = \"gddr5\")"
            } else {
                ""
            };
            return Err(ChipError::NoSuchUnit {
                name: name.to_string(),
                hint,
                valid: valid_names(paths),
            });
        }
        pats.push(p);
    }
    Ok(pats.join(","))
}

/// The instance patterns for `--capture`'s comma-separated `units`: the
/// names `--trace-units` takes, and instance paths with or without the root
/// (`tm0.staging_buffer` is `chip.tm0.staging_buffer`). An unknown name, or
/// one that matches no instance, is an error listing the valid ones.
pub fn resolve_capture(units: &str, paths: &[&str]) -> Result<String, ChipError> {
    let mut pats = Vec::new();
    for name in units.split(',').map(str::trim).filter(|n| !n.is_empty()) {
        let rooted = format!("chip.{name}");
        let found = resolve(name, paths).or_else(|e| match name.contains('.') {
            true => resolve(&rooted, paths).map_err(|_| e),
            false => Err(e),
        });
        match found {
            Ok(p) => pats.push(p),
            Err(e) => {
                let why = e.to_string();
                let why = why.strip_prefix("--trace-units: ").unwrap_or(&why);
                return Err(ChipError::Capture(format!(
                    "--capture: {why}; an instance path is also taken without its root (tm0.staging_buffer)"
                )));
            }
        }
    }
    if pats.is_empty() {
        return Err(ChipError::Capture(format!(
            "--capture names no unit; valid names: {}",
            valid_names(paths)
        )));
    }
    Ok(pats.join(","))
}

/// A window of core cycles: `A..B` (B excluded), `A..=B` (B included) or `A..`
/// (to the end). Returns the first and the last cycle (`None`: open).
pub fn parse_window(s: &str) -> Result<(u64, Option<u64>), ChipError> {
    parse_window_of(s, "--trace-window", "core cycles")
}

/// `parse_window` for option `flag`, whose cycles are `what`.
pub fn parse_window_of(s: &str, flag: &str, what: &str) -> Result<(u64, Option<u64>), ChipError> {
    let bad = |why: &str| {
        ChipError::BadWindow(format!(
            "{flag} '{s}' {why}; give {what} as A..B (B excluded), A..=B or A.."
        ))
    };
    let (a, b) = s.split_once("..").ok_or_else(|| bad("has no '..'"))?;
    let num = |t: &str| {
        t.trim()
            .replace('_', "")
            .parse::<u64>()
            .map_err(|_| bad(&format!("has '{}', not a cycle number", t.trim())))
    };
    let from = num(a)?;
    let to = if let Some(b) = b.strip_prefix('=') {
        Some(num(b)?)
    } else if b.trim().is_empty() {
        None
    } else {
        let b = num(b)?;
        if b == 0 {
            return Err(bad("is empty"));
        }
        Some(b - 1)
    };
    if let Some(t) = to
        && t < from
    {
        return Err(bad("ends before it starts"));
    }
    Ok((from, to))
}

/// The kernel's spec for cycles `from..=to` of a `core_ps` clock, at most
/// `max_bytes` (0: no limit).
pub fn spec(
    filter: String,
    from: u64,
    to: Option<u64>,
    core_ps: Time,
    max_bytes: u64,
) -> TraceSpec {
    TraceSpec {
        filter,
        max_bytes,
        every_edge: false,
        show: crate::rtl::trace::Show::default(),
        cycles_of: Some(("core", core_ps)),
        from: from.saturating_mul(core_ps),
        // The last cycle's edge and everything before the next one (DRAM edges).
        to: to.map_or(Time::MAX, |c| {
            c.saturating_add(1)
                .saturating_mul(core_ps)
                .saturating_sub(1)
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paths() -> Vec<&'static str> {
        vec![
            "chip.host",
            "chip.scheduler",
            "chip.scene_buffer",
            "chip.hit_updater",
            "chip.mem_ctrl0",
            "chip.mem_ctrl1",
            "chip.memory",
            "chip.tm0.tp0",
            "chip.tm0.l1",
            "chip.tm1.tp0",
            "chip.tm10.tp0",
        ]
    }

    fn traced(units: &str) -> Vec<&'static str> {
        let f = resolve(units, &paths()).unwrap();
        let s = spec(f, 0, None, 1000, 0);
        paths().into_iter().filter(|p| s.matches(p)).collect()
    }

    #[test]
    fn names_select_their_units_only() {
        assert_eq!(traced("scheduler"), ["chip.scheduler"]);
        assert_eq!(traced("tm1"), ["chip.tm1.tp0"]);
        assert_eq!(traced("tm0"), ["chip.tm0.tp0", "chip.tm0.l1"]);
        assert_eq!(
            traced("tms"),
            [
                "chip.tm0.tp0",
                "chip.tm0.l1",
                "chip.tm1.tp0",
                "chip.tm10.tp0"
            ]
        );
        assert_eq!(traced("mem_ctrl"), ["chip.mem_ctrl0", "chip.mem_ctrl1"]);
        assert_eq!(traced("mem_ctrl1"), ["chip.mem_ctrl1"]);
        assert_eq!(
            traced("scheduler, tm0,mem_ctrl"),
            [
                "chip.scheduler",
                "chip.mem_ctrl0",
                "chip.mem_ctrl1",
                "chip.tm0.tp0",
                "chip.tm0.l1"
            ]
        );
        assert_eq!(traced("chip.tm*.l1"), ["chip.tm0.l1"]);
        assert_eq!(traced(""), paths());
    }

    #[test]
    fn unknown_or_absent_names_list_the_valid_ones() {
        let e = resolve("scheduler,tm_0", &paths()).unwrap_err();
        assert!(
            matches!(&e, ChipError::UnknownUnit { name, .. } if name == "tm_0"),
            "{e:?}"
        );
        let e = e.to_string();
        assert!(e.contains("unknown unit 'tm_0'"), "{e}");
        assert!(e.contains("scheduler") && e.contains("tm0..tm10"), "{e}");
        assert!(e.contains("mem_ctrl0..mem_ctrl1"), "{e}");
        let e = resolve("tm11", &paths()).unwrap_err();
        assert!(
            matches!(&e, ChipError::NoSuchUnit { name, .. } if name == "tm11"),
            "{e:?}"
        );
        assert!(e.to_string().contains("matches no unit"), "{e}");
        let e = resolve("l2", &paths()).unwrap_err().to_string();
        assert!(e.contains("'l2' matches no unit"), "{e}");
        assert!(!e.contains("l2 ("), "l2 is not listed without one: {e}");
        let fixed: Vec<&str> = paths()
            .into_iter()
            .filter(|p| !p.contains("mem_ctrl"))
            .collect();
        let e = resolve("mem_ctrl", &fixed).unwrap_err().to_string();
        assert!(e.contains("gddr5"), "{e}");
    }

    #[test]
    fn windows() {
        assert_eq!(parse_window("10000..20000").unwrap(), (10000, Some(19999)));
        assert_eq!(parse_window("5..=5").unwrap(), (5, Some(5)));
        assert_eq!(parse_window(" 7 ..").unwrap(), (7, None));
        assert_eq!(parse_window("1_000..2_000").unwrap(), (1000, Some(1999)));
        for bad in ["10", "a..b", "20..10", "5..5", "0..0", "..5x"] {
            let e = parse_window(bad).unwrap_err();
            assert!(matches!(e, ChipError::BadWindow(_)), "{e:?}");
            let e = e.to_string();
            assert!(e.contains("--trace-window") && e.contains("A..B"), "{e}");
        }
        let s = spec(String::new(), 10, Some(19), 1000, 0);
        assert_eq!((s.from, s.to), (10_000, 19_999));
        assert_eq!(spec(String::new(), 3, None, 1000, 0).to, Time::MAX);
    }
}
