//! Every testbench in the registry (`testbench::BENCHES`, which `dualstream tb`
//! lists and runs) runs briefly and passes; a name outside it is refused with the
//! list.

use dualstream::testbench::{self, Runner, TbOptions};

#[test]
fn every_registered_bench_runs_briefly_and_passes() {
    let mut ran = Vec::new();
    for b in testbench::BENCHES {
        let Runner::Unit(run) = b.runner else {
            continue; // tm: tests/tm.rs runs it on treelets
        };
        let opts = TbOptions {
            cycles: 400,
            config: testbench::bench_config(b.name, &Default::default()),
            ..TbOptions::default()
        };
        let rep = run(&opts).unwrap_or_else(|e| panic!("{}: {e}", b.name));
        assert!(rep.passed(), "{}: {rep}", b.name);
        assert!(rep.results > 0, "{}: no results", b.name);
        ran.push(b.name);
        for a in b.aliases {
            assert_eq!(testbench::find(a).unwrap().name, b.name);
        }
    }
    assert!(ran.contains(&"l1") && ran.len() >= 9, "{ran:?}");
    let e = testbench::find("nope").err().unwrap();
    assert!(
        matches!(&e, testbench::TbError::UnknownUnit { name } if name == "nope"),
        "{e:?}"
    );
    let e = e.to_string();
    for b in testbench::BENCHES {
        assert!(e.contains(b.name), "{e}");
    }
}

/// The `unit!` declarations under `src/units/`: (module name, file, whether the
/// file has tests of its own).
fn declared_units() -> Vec<(String, String, bool)> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).expect("src/units reads") {
            let p = e.expect("a directory entry").path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    walk(&root.join("src/units"), &mut files);
    files.sort();
    let mut units = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).expect("a source file reads");
        let tested = text.contains("#[cfg(test)]");
        for block in text.split("crate::unit! {").skip(1) {
            // `pub struct Name : "module" {`
            let module = block
                .split_once(" : \"")
                .and_then(|(_, rest)| rest.split_once('"'))
                .map(|(m, _)| m.to_string())
                .unwrap_or_else(|| panic!("{}: a unit! without a module name", f.display()));
            let rel = f.strip_prefix(root).expect("under the root");
            units.push((module, rel.display().to_string(), tested));
        }
    }
    units
}

/// Every unit is tested on its own: named by a registered bench (which the
/// test above runs briefly; the TM bench runs in `tests/tm.rs`) or by a test
/// in its own file. A unit added without either fails here.
#[test]
fn every_unit_has_a_bench_or_a_test_in_its_file() {
    let units = declared_units();
    assert!(units.len() >= 13, "{units:?}");
    let benched = |m: &str| testbench::BENCHES.iter().any(|b| b.units.contains(&m));
    let untested: Vec<_> = units
        .iter()
        .filter(|(m, _, tested)| !benched(m) && !tested)
        .collect();
    assert!(
        untested.is_empty(),
        "units with no bench (testbench::BENCHES) and no test in their file: {untested:?}"
    );
    // The registry names real units only.
    for b in testbench::BENCHES {
        for u in b.units {
            assert!(
                units.iter().any(|(m, _, _)| m == u),
                "bench {} names '{u}', which no unit! declares",
                b.name
            );
        }
    }
}
