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
    /// Paths in declaration order.
    pub order: Vec<String>,
    /// Path -> (time, value) in time order; vectors without leading zeros,
    /// reals as text.
    pub changes: BTreeMap<String, Vec<(u64, String)>>,
    /// The last timestamp.
    pub end: u64,
    /// The paths of the module scopes (unit instances and the structural
    /// ones above them; not the fields' struct scopes).
    pub modules: std::collections::BTreeSet<String>,
    /// The header's comments, in order.
    pub comments: Vec<String>,
}

/// The value with leading zeros dropped (`b0101` and `b101` are one value).
fn canon(bits: &str) -> String {
    let t = bits.trim_start_matches('0');
    if t.is_empty() { "0".into() } else { t.into() }
}

pub fn vcd(path: &Path) -> Wave {
    // fst2vcd writes a struct scope as `$scope struct`, which the `vcd` crate
    // does not know: read it as the named block our VCD writes.
    let text = std::fs::read_to_string(path)
        .unwrap()
        .replace("$scope struct ", "$scope begin ");
    let f = std::io::Cursor::new(text.into_bytes());
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
            vcd::Command::ScopeDef(t, name) => {
                stack.push(name);
                if t == vcd::ScopeType::Module {
                    w.modules.insert(stack.join("."));
                }
            }
            vcd::Command::Comment(c) => w.comments.push(c.trim().to_string()),
            vcd::Command::Upscope => {
                stack.pop();
            }
            vcd::Command::VarDef(t, size, code, name, _) => {
                let p = format!("{}.{name}", stack.join("."));
                let kind = t.to_string();
                w.vars.insert(p.clone(), Var { width: size, kind });
                w.order.push(p.clone());
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
            // As f32: the model's floats are singles, and fst2vcd prints 16 digits.
            vcd::Command::ChangeReal(code, v) => change(code, format!("{:?}", v as f32)),
            _ => {}
        }
    }
    w
}

impl Wave {
    /// The value of `path` at time `t` (its last change at or before `t`).
    pub fn at(&self, path: &str, t: u64) -> Option<&str> {
        let c = self.changes.get(path)?;
        let k = c.partition_point(|(ct, _)| *ct <= t);
        (k > 0).then(|| c[k - 1].1.as_str())
    }
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
