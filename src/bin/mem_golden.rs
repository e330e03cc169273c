//! Equivalence evidence for changes to the memory controller's speed: prints the
//! replay report and FNV hashes of every command and completion for fixed traces
//! (random, stream, mixed, writes, throttled) on the paper and DRAMsim3 presets,
//! tiny queues with a 2-entry response buffer, FR-FCFS on 16 banks in one group,
//! and the flat mapping. Run it before and after a change and diff the outputs:
//! `cargo run --release --bin mem_golden [requests] > before.txt`.
use dualstream::mem::config::{CtrlPolicy, MemCfg};
use dualstream::mem::replay::{ReplayOptions, replay};
use dualstream::mem::trace::generate;

fn fnv(h: &mut u64, x: u64) {
    for b in x.to_le_bytes() {
        *h ^= b as u64;
        *h = h.wrapping_mul(0x100000001b3);
    }
}

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .map_or(100_000, |s| s.parse().unwrap());
    let mut cfgs = vec![];
    for p in ["paper", "dramsim3-gddr5"] {
        let (m, t) = MemCfg::preset(p).unwrap();
        cfgs.push((p.to_string(), m.clone(), t));
        let mut s = m.clone();
        s.ctrl.resp_buffer = 2;
        s.ctrl.read_queue = 8;
        s.ctrl.write_queue = 12;
        s.ctrl.write_high = 8;
        s.ctrl.write_low = 3;
        if s.ctrl.policy == CtrlPolicy::Dramsim3 {
            // DRAMsim3 drains a full write buffer; 2-deep bank queues.
            s.ctrl.write_high = s.ctrl.write_queue;
            s.ctrl.cmd_queue = 2;
        }
        cfgs.push((format!("{p}-small"), s, t));
    }
    // FR-FCFS on DRAMsim3's device: 16 banks in one group.
    let (mut f, t) = MemCfg::preset("dramsim3-gddr5").unwrap();
    f.ctrl.policy = CtrlPolicy::Frfcfs;
    cfgs.push(("dramsim3-flat".into(), f, t));
    let mut m1 = MemCfg::paper();
    m1.mapping = "row:bank:channel:column".into();
    cfgs.push(("paper-map1".into(), m1, 500));
    for (name, m, tck) in &cfgs {
        for (kind, wf, iv) in [
            ("random", 0.0, 0),
            ("stream", 0.0, 0),
            ("random", 0.3, 0),
            ("mixed", 0.0, 0),
            ("stream", 0.5, 0),
            ("mixed", 0.0, 3),
            ("random", 0.2, 40),
        ] {
            let reqs = generate(kind, n, 11, m, iv, wf).unwrap();
            let r = replay(
                m,
                *tck,
                &reqs,
                &ReplayOptions {
                    check: true,
                    preset: name.clone(),
                    ..ReplayOptions::default()
                },
            )
            .unwrap();
            let mut h = 0xcbf29ce484222325u64;
            let mut nc = 0;
            for log in &r.commands {
                for c in log {
                    nc += 1;
                    for x in [
                        c.cycle,
                        c.kind as u64,
                        c.bank_group as u64,
                        c.bank as u64,
                        c.row as u64,
                        c.column as u64,
                    ] {
                        fnv(&mut h, x);
                    }
                }
            }
            let mut hc = 0xcbf29ce484222325u64;
            for (id, cy) in &r.completions {
                fnv(&mut hc, *id as u64);
                fnv(&mut hc, *cy);
            }
            println!(
                "=== {name} {kind} wf={wf} interval={iv} n={n}: commands {nc} hash {h:016x}, completions {} hash {hc:016x}",
                r.completions.len()
            );
            print!("{}", r.report);
            assert!(r.report.violations.as_ref().unwrap().is_empty());
        }
    }
}
