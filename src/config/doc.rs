//! The configuration as commented TOML (`dualstream config --print-default`):
//! each key's comment is the doc comment of its field in the Rust source, read
//! from the source files of the config structs built into the binary, so a
//! field documented once is documented in both places, and a field added
//! without a doc comment fails `every_printed_key_has_a_comment`.

use std::collections::HashMap;

/// The sources of every struct a [`super::Config`] holds, by path.
const SOURCES: [(&str, &str); 16] = [
    ("config/mod.rs", include_str!("mod.rs")),
    ("config/chip.rs", include_str!("chip.rs")),
    ("rtl/link.rs", include_str!("../rtl/link.rs")),
    ("rtl/pipe.rs", include_str!("../rtl/pipe.rs")),
    ("accel/mod.rs", include_str!("../accel/mod.rs")),
    ("accel/bvh.rs", include_str!("../accel/bvh.rs")),
    ("contract/memmap.rs", include_str!("../contract/memmap.rs")),
    ("mem/config.rs", include_str!("../mem/config.rs")),
    ("energy.rs", include_str!("../energy.rs")),
    ("units/tm.rs", include_str!("../units/tm.rs")),
    ("units/memory.rs", include_str!("../units/memory.rs")),
    (
        "units/scene_buffer.rs",
        include_str!("../units/scene_buffer.rs"),
    ),
    (
        "units/stream_scheduler.rs",
        include_str!("../units/stream_scheduler.rs"),
    ),
    (
        "units/hit_record_updater.rs",
        include_str!("../units/hit_record_updater.rs"),
    ),
    ("units/l2/config.rs", include_str!("../units/l2/config.rs")),
    ("units/tp.rs", include_str!("../units/tp.rs")),
];

/// What the top of the printed file says.
const PREAMBLE: &str = "\
# dualstream configuration (`dualstream config --print-default`). Every key may be
# left out: it then takes the value shown, the default. Sources in brackets:
# [DS17 Table 1] and [DS17 §5.1] are the paper's (Shkurko et al., HPG 2017), the
# others the hardware reference sheet and the simulators named. Three sections hold
# memory: [memory] is the DRAM image's layout (what lies where), [mem] the GDDR5
# device and its controllers (timing, mapping, energy), [chip.memory] the chip's
# memory unit, which picks the model (GDDR5 or a fixed latency) in cycle mode.
";

/// One documented field of a struct: its TOML key, doc and type's name.
struct Field {
    key: String,
    doc: Vec<String>,
    ty: String,
    /// The type's path as written (`crate::mem::MemCfg`), to tell apart
    /// structs of one name.
    ty_path: String,
}

/// Every `pub struct` of the sources: (file, name) -> its fields.
struct Structs {
    by_name: HashMap<String, Vec<(&'static str, Vec<Field>)>>,
}

impl Structs {
    fn parse() -> Structs {
        let mut by_name: HashMap<String, Vec<(&'static str, Vec<Field>)>> = HashMap::new();
        for (file, src) in SOURCES {
            let mut cur: Option<(String, Vec<Field>)> = None;
            let mut doc = Vec::new();
            let mut rename = None;
            for line in src.lines() {
                let t = line.trim();
                if let Some(rest) = t.strip_prefix("pub struct ") {
                    let name: String = rest
                        .chars()
                        .take_while(|c| c.is_alphanumeric() || *c == '_')
                        .collect();
                    if t.ends_with('{') {
                        cur = Some((name, Vec::new()));
                    }
                    doc.clear();
                    continue;
                }
                let Some((_, fields)) = cur.as_mut() else {
                    continue;
                };
                if t == "}" {
                    let (name, fields) = cur.take().expect("in a struct");
                    by_name.entry(name).or_default().push((file, fields));
                    doc.clear();
                } else if let Some(d) = t.strip_prefix("///") {
                    doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
                } else if let Some(r) = t.strip_prefix("#[serde(rename = \"") {
                    rename = r.split('"').next().map(str::to_string);
                } else if let Some(rest) = t.strip_prefix("pub ")
                    && let Some((name, ty)) = rest.split_once(':')
                {
                    let ty_path = ty.trim().trim_end_matches(',').to_string();
                    fields.push(Field {
                        key: rename.take().unwrap_or_else(|| name.trim().to_string()),
                        doc: std::mem::take(&mut doc),
                        ty: type_name(&ty_path),
                        ty_path,
                    });
                } else if !t.starts_with("#[") && !t.starts_with("//") {
                    doc.clear();
                }
            }
        }
        Structs { by_name }
    }

    /// The struct a field of type `f` (in `file`) names: the only one of
    /// that name, else the one in `file`, else the one whose file the path
    /// names.
    fn of(&self, f: &Field, file: &str) -> Option<(&'static str, &[Field])> {
        let c = self.by_name.get(&f.ty)?;
        let pick = if c.len() == 1 {
            &c[0]
        } else if let Some(s) = c.iter().find(|(p, _)| *p == file) {
            s
        } else {
            let module = f.ty_path.rsplit("::").nth(1)?;
            c.iter().find(|(p, _)| p.contains(module))?
        };
        Some((pick.0, &pick.1))
    }
}

/// The name of a field's type: its last capitalized identifier, inside
/// `Option<..>` or `Vec<..>`.
fn type_name(ty: &str) -> String {
    ty.rsplit(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|t| t.starts_with(|c: char| c.is_ascii_uppercase()))
        .find(|t| !matches!(*t, "Option" | "Vec" | "Box"))
        .unwrap_or("")
        .to_string()
}

/// Every documented key, by dotted path (`mem.timing.CL`), and every section.
fn docs() -> HashMap<String, Vec<String>> {
    let s = Structs::parse();
    let mut out = HashMap::new();
    let root = s
        .by_name
        .get("Config")
        .and_then(|c| c.iter().find(|(p, _)| *p == "config/mod.rs"));
    if let Some((file, fields)) = root {
        walk(&s, file, fields, "", &mut out, 0);
    }
    out
}

fn walk(
    s: &Structs,
    file: &'static str,
    fields: &[Field],
    prefix: &str,
    out: &mut HashMap<String, Vec<String>>,
    depth: usize,
) {
    for f in fields {
        let path = format!("{prefix}{}", f.key);
        let mut doc = f.doc.clone();
        if let Some((sub_file, sub)) = s.of(f, file)
            && depth < 8
        {
            if doc.is_empty() {
                // The struct's own doc comment stands for a field without one.
                doc = struct_doc(sub_file, &f.ty);
            }
            walk(s, sub_file, sub, &format!("{path}."), out, depth + 1);
        }
        out.insert(path, doc);
    }
}

/// The doc comment right above `pub struct name` in `file`.
fn struct_doc(file: &str, name: &str) -> Vec<String> {
    let Some((_, src)) = SOURCES.iter().find(|(p, _)| *p == file) else {
        return Vec::new();
    };
    let lines: Vec<&str> = src.lines().collect();
    let Some(i) = lines.iter().position(|l| {
        l.trim().starts_with(&format!("pub struct {name} "))
            || l.trim() == format!("pub struct {name} {{")
    }) else {
        return Vec::new();
    };
    let mut doc = Vec::new();
    for l in lines[..i].iter().rev() {
        let t = l.trim();
        if let Some(d) = t.strip_prefix("///") {
            doc.push(d.strip_prefix(' ').unwrap_or(d).to_string());
        } else if !t.starts_with("#[") {
            break;
        }
    }
    doc.reverse();
    doc
}

/// `toml` (as `Config::to_toml` writes it) with each key's and each
/// section's doc comment above it; keys without one are listed in the second
/// value.
pub fn commented(toml: &str) -> (String, Vec<String>) {
    let docs = docs();
    let mut out = String::from(PREAMBLE);
    let mut missing = Vec::new();
    let mut section = String::new();
    // Inside a value that spans lines (an array).
    let mut open = 0i32;
    let put = |out: &mut String, path: &str, missing: &mut Vec<String>| match docs.get(path) {
        Some(d) if !d.is_empty() => {
            for l in d {
                out.push_str(if l.is_empty() { "#\n" } else { "# " });
                if !l.is_empty() {
                    out.push_str(l);
                    out.push('\n');
                }
            }
        }
        _ => missing.push(path.to_string()),
    };
    for line in toml.lines() {
        let t = line.trim();
        if open == 0 && t.starts_with('[') && t.ends_with(']') && !t.contains('=') {
            section = t.trim_matches(|c| c == '[' || c == ']').to_string();
            out.push('\n');
            put(&mut out, &section, &mut missing);
        } else if open == 0
            && let Some((key, _)) = t.split_once(" = ")
        {
            let key = key.trim().trim_matches('"');
            let path = if section.is_empty() {
                key.to_string()
            } else {
                format!("{section}.{key}")
            };
            put(&mut out, &path, &mut missing);
        }
        open += t.matches('[').count() as i32 - t.matches(']').count() as i32;
        if t.starts_with('[') && open < 0 {
            open = 0;
        }
        if !t.is_empty() {
            out.push_str(line);
            out.push('\n');
        }
    }
    (out, missing)
}

#[cfg(test)]
mod tests {
    use super::super::Config;
    use super::*;

    #[test]
    fn every_printed_key_has_a_comment() {
        let (_, missing) = commented(&Config::default().to_toml());
        assert!(
            missing.is_empty(),
            "these keys of the configuration have no doc comment in their struct: {missing:?}; add one (meaning, unit, source)"
        );
    }

    #[test]
    fn the_commented_default_parses_back_to_the_default() {
        let (text, _) = commented(&Config::default().to_toml());
        assert!(
            text.contains("# Thread multiprocessors: 128 [DS17 §5.1]"),
            "{text}"
        );
        assert!(text.lines().filter(|l| l.starts_with('#')).count() > 200);
        assert_eq!(Config::from_toml(&text).unwrap(), Config::default());
    }

    #[test]
    fn a_missing_doc_is_noticed() {
        let (_, missing) = commented("[clocks]\ncore_ps = 1000\nno_such_key = 1\n");
        assert_eq!(missing, vec!["clocks.no_such_key".to_string()]);
    }
}
