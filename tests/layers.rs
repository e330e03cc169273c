//! The layers point one way (docs/architecture.md, "Layers"): a module may use
//! modules of its own layer or below, never above, and the modules of one layer
//! must not use each other in a cycle. This test reads every source file of the
//! crate (library, testbenches, the command line) and fails on an import against
//! that order, naming the file, the line and the layer it reaches up to.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Bottom to top. A top-level module of the library (`src/<name>.rs` or
/// `src/<name>/`) must appear here; the binary (`src/main.rs`, `src/cli/`,
/// `src/bin/`) is `cli`.
const LAYERS: &[&[&str]] = &[
    &["util"],
    &["rtl"],
    &["geom"],
    &["contract", "scene", "mem", "accel"],
    &["units"],
    &["energy"],
    &["config"],
    &["machine"],
    &["render", "sampling", "report", "testbench"],
    &["bench", "cli"],
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

/// The top-level module a source file belongs to.
fn module_of(root: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(root).expect("under the root");
    let parts: Vec<&str> = rel
        .iter()
        .map(|p| p.to_str().expect("utf-8 path"))
        .collect();
    match parts.as_slice() {
        ["testbench", ..] => "testbench".into(),
        ["src", "main.rs"] | ["src", "cli", ..] | ["src", "bin", ..] => "cli".into(),
        ["src", top] => top.trim_end_matches(".rs").into(),
        ["src", dir, ..] => (*dir).into(),
        _ => panic!("unexpected source file {}", rel.display()),
    }
}

/// One import of another top-level module: file, line, the module used.
#[derive(Debug, Clone, PartialEq)]
struct Use {
    file: String,
    line: usize,
    from: String,
    to: String,
}

/// Every `crate::<m>` (library code) or `dualstream::<m>` (the binary) in code,
/// comments and string literals left out. `crate::{a, b::c}` counts `a` and `b`.
fn uses_in(file: &str, from: &str, text: &str) -> Vec<Use> {
    let root = if from == "cli" { "dualstream" } else { "crate" };
    let mut out = Vec::new();
    let mut in_block_comment = false;
    for (k, raw) in text.lines().enumerate() {
        let line = strip_comments_and_strings(raw, &mut in_block_comment);
        let mut rest = line.as_str();
        while let Some(p) = rest.find(root) {
            let before = rest[..p].chars().next_back();
            let after = &rest[p + root.len()..];
            rest = after;
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
                continue;
            }
            let Some(after) = after.strip_prefix("::") else {
                continue;
            };
            let names: Vec<String> = if let Some(group) = after.strip_prefix('{') {
                // `crate::{a, b::c}` on one line, or opened here and closed below:
                // the first segment of each item.
                let group = group.split('}').next().unwrap_or("");
                group
                    .split(',')
                    .map(|s| s.trim().split("::").next().unwrap_or("").to_string())
                    .collect()
            } else {
                let name: String = after
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                // `crate::payload_struct!`: an exported macro, not a module.
                if after[name.len()..].starts_with('!') {
                    continue;
                }
                vec![name]
            };
            for to in names {
                if !to.is_empty()
                    && to != from
                    && to.chars().next().is_some_and(|c| c.is_lowercase())
                {
                    out.push(Use {
                        file: file.to_string(),
                        line: k + 1,
                        from: from.to_string(),
                        to,
                    });
                }
            }
        }
    }
    out
}

/// The line with `//` comments, `/* */` comments and string literals blanked, so
/// a doc comment naming `crate::render` is not an import.
fn strip_comments_and_strings(line: &str, in_block: &mut bool) -> String {
    let b = line.as_bytes();
    let mut out = String::new();
    let mut i = 0;
    while i < b.len() {
        if *in_block {
            if b[i..].starts_with(b"*/") {
                *in_block = false;
                i += 2;
            } else {
                i += 1;
            }
            continue;
        }
        if b[i..].starts_with(b"//") {
            break;
        }
        if b[i..].starts_with(b"/*") {
            *in_block = true;
            i += 2;
            continue;
        }
        if b[i] == b'"' {
            i += 1;
            while i < b.len() && b[i] != b'"' {
                i += if b[i] == b'\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
            continue;
        }
        out.push(b[i] as char);
        i += 1;
    }
    out
}

/// The imports against the order: to a higher layer, to a module that is in no
/// layer, and cycles among the modules of one layer.
fn violations(uses: &[Use]) -> Vec<String> {
    let mut bad = Vec::new();
    let mut graph: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for u in uses {
        let (Some(a), Some(b)) = (layer_of(&u.from), layer_of(&u.to)) else {
            let which = if layer_of(&u.from).is_none() {
                &u.from
            } else {
                &u.to
            };
            if u.to != "self" {
                bad.push(format!(
                    "{}:{}: module `{which}` is in no layer: add it to LAYERS in tests/layers.rs and to docs/architecture.md",
                    u.file, u.line
                ));
            }
            continue;
        };
        if b > a {
            bad.push(format!(
                "{}:{}: `{}` (layer {a}) uses `{}` (layer {b}, above it): move what both need down to `{}`'s layer or below",
                u.file, u.line, u.from, u.to, u.from
            ));
        } else if a == b {
            graph.entry(&u.from).or_default().insert(&u.to);
        }
    }
    // A cycle among same-layer modules: depth-first search.
    fn visit<'a>(
        n: &'a str,
        g: &BTreeMap<&'a str, BTreeSet<&'a str>>,
        path: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
        bad: &mut Vec<String>,
    ) {
        if let Some(k) = path.iter().position(|m| *m == n) {
            let mut cyc = path[k..].to_vec();
            cyc.push(n);
            bad.push(format!(
                "modules of one layer use each other in a cycle: {}",
                cyc.join(" -> ")
            ));
            return;
        }
        if !done.insert(n) {
            return;
        }
        path.push(n);
        for m in g.get(n).into_iter().flatten() {
            visit(m, g, path, done, bad);
        }
        path.pop();
    }
    let mut done = BTreeSet::new();
    for n in graph.keys() {
        visit(n, &graph, &mut Vec::new(), &mut done, &mut bad);
    }
    bad
}

fn sources(root: &Path) -> Vec<PathBuf> {
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        let mut es: Vec<_> = std::fs::read_dir(d)
            .unwrap_or_else(|e| panic!("read {}: {e}", d.display()))
            .map(|e| e.expect("dir entry").path())
            .collect();
        es.sort();
        for p in es {
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let mut out = Vec::new();
    walk(&root.join("src"), &mut out);
    walk(&root.join("testbench"), &mut out);
    out
}

fn tree_uses(root: &Path) -> Vec<Use> {
    let mut all = Vec::new();
    for f in sources(root) {
        let from = module_of(root, &f);
        let text = std::fs::read_to_string(&f).expect("read source");
        let name = f
            .strip_prefix(root)
            .expect("under root")
            .display()
            .to_string();
        all.extend(uses_in(&name, &from, &text));
    }
    all
}

#[test]
fn every_import_points_down_the_layers() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let uses = tree_uses(root);
    assert!(
        uses.len() > 100,
        "the scan found only {} imports: it is not reading the sources",
        uses.len()
    );
    // Every top-level module of the library has a layer.
    for f in sources(root) {
        let m = module_of(root, &f);
        assert!(
            layer_of(&m).is_some() || m == "lib",
            "{}: module `{m}` is in no layer (tests/layers.rs LAYERS)",
            f.display()
        );
    }
    let bad = violations(&uses);
    assert!(
        bad.is_empty(),
        "imports against the layers:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_check_catches_an_upward_import_and_a_cycle() {
    // A unit reaching up into render, in code: caught, with file and line.
    let src = "use crate::rtl::Sim;\n// crate::render in a comment is fine\nfn f() { crate::render::traverse::reference_trace(); }\nconst S: &str = \"crate::machine\";\n";
    let u = uses_in("src/units/tp.rs", "units", src);
    assert_eq!(
        u.iter()
            .map(|u| (u.line, u.to.as_str()))
            .collect::<Vec<_>>(),
        vec![(1, "rtl"), (3, "render")]
    );
    let bad = violations(&u);
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert!(
        bad[0].starts_with("src/units/tp.rs:3: `units` (layer 4) uses `render`"),
        "{}",
        bad[0]
    );
    // Grouped imports count each module.
    let u = uses_in(
        "src/geom/x.rs",
        "geom",
        "use crate::{util::div, mem::MemCfg};",
    );
    assert_eq!(
        u.iter().map(|u| u.to.as_str()).collect::<Vec<_>>(),
        ["util", "mem"]
    );
    assert_eq!(violations(&u).len(), 1);
    // Two modules of one layer using each other: a cycle.
    let mut u = uses_in("src/mem/a.rs", "mem", "use crate::accel::Bvh;");
    u.extend(uses_in(
        "src/accel/b.rs",
        "accel",
        "use crate::mem::MemCfg;",
    ));
    let bad = violations(&u);
    assert!(
        bad.iter()
            .any(|b| b.contains("cycle: accel -> mem -> accel")),
        "{bad:?}"
    );
    // The binary is checked through `dualstream::`.
    let u = uses_in("src/main.rs", "cli", "use dualstream::render::render;");
    assert!(violations(&u).is_empty());
    // A module outside every layer is named.
    let u = uses_in("src/units/x.rs", "units", "use crate::gizmo::X;");
    assert!(violations(&u)[0].contains("module `gizmo` is in no layer"));
}
