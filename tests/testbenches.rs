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
