//! Reads a waveform into plain maps: every variable with its width and kind,
//! and every value change, keyed by the variable's full path.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Var {
    pub width: u32,
    /// `wire`, `reg`, `real`, ...
    pub kind: String,
}

#[derive(Default, Debug)]
pub struct Wave {
    pub vars: BTreeMap<String, Var>,
    /// Path -> (time, value) in time order; vectors without leading zeros,
    /// reals as text.
    pub changes: BTreeMap<String, Vec<(u64, String)>>,
    /// The last timestamp.
    pub end: u64,
}

/// The value with leading zeros dropped (`b0101` and `b101` are one value).
fn canon(bits: &str) -> String {
    let t = bits.trim_start_matches('0');
    if t.is_empty() { "0".into() } else { t.into() }
}

pub fn vcd(path: &Path) -> Wave {
    let f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut w = Wave::default();
    let mut stack: Vec<String> = Vec::new();
    // One id may stand for several variables (aliases).
    let mut ids: BTreeMap<vcd::IdCode, Vec<String>> = BTreeMap::new();
    let mut now = 0;
    for cmd in vcd::Parser::new(f) {
        let mut change = |code: vcd::IdCode, v: String| {
            for p in ids.get(&code).expect("a change of a declared id") {
                w.changes
                    .entry(p.clone())
                    .or_default()
                    .push((now, v.clone()));
            }
        };
        match cmd.unwrap_or_else(|e| panic!("{}: not valid VCD: {e}", path.display())) {
            vcd::Command::ScopeDef(_, name) => stack.push(name),
            vcd::Command::Upscope => {
                stack.pop();
            }
            vcd::Command::VarDef(t, size, code, name, _) => {
                let p = format!("{}.{name}", stack.join("."));
                let kind = t.to_string();
                w.vars.insert(p.clone(), Var { width: size, kind });
                ids.entry(code).or_default().push(p);
            }
            vcd::Command::Timestamp(t) => {
                assert!(t >= now, "time goes backwards");
                now = t;
                w.end = t;
            }
            vcd::Command::ChangeScalar(code, v) => change(code, v.to_string()),
            vcd::Command::ChangeVector(code, v) => {
                let s: String = v.iter().map(|b| b.to_string()).collect();
                change(code, canon(&s))
            }
            vcd::Command::ChangeReal(code, v) => change(code, format!("{v:?}")),
            _ => {}
        }
    }
    w
}

/// An FST file through GTKWave's own converter; also returns the converter's
/// text with extensions (`-e`: enum tables as `$attrbegin misc 07`).
pub fn fst(path: &Path) -> (Wave, String) {
    let plain = path.with_extension("fst.vcd");
    let o = Command::new("fst2vcd")
        .arg(path)
        .arg("-o")
        .arg(&plain)
        .output()
        .unwrap();
    assert!(o.status.success(), "fst2vcd {}: {:?}", path.display(), o);
    let ext = Command::new("fst2vcd")
        .arg("-e")
        .arg(path)
        .output()
        .unwrap();
    assert!(ext.status.success());
    (vcd(&plain), String::from_utf8(ext.stdout).unwrap())
}
