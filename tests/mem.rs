//! The memory system: timing checker on random traffic, streaming vs random
//! bandwidth, directed timing cases, bad input, and the unit == fast path check.

use dualstream::mem::config::MemCfg;
use dualstream::mem::replay::{ReplayOptions, replay};
use dualstream::mem::trace::{TraceReq, generate};

fn one_channel(mut m: MemCfg) -> MemCfg {
    m.geometry.channels = 1;
    m
}

fn run(m: &MemCfg, tck: u64, reqs: &[TraceReq]) -> dualstream::mem::MemReport {
    let r = replay(
        m,
        tck,
        reqs,
        &ReplayOptions {
            check: true,
            preset: "test".into(),
        },
    )
    .unwrap();
    r.report
}

#[test]
fn random_traffic_has_no_timing_violations() {
    for (m, tck) in [
        (one_channel(MemCfg::paper()), 500),
        (MemCfg::paper(), 500),
        (MemCfg::dramsim3_gddr5(), 667),
    ] {
        for (kind, wf) in [("random", 0.3), ("mixed", 0.0), ("stream", 0.5)] {
            let reqs = generate(kind, 6000, 7, &m, 0, wf).unwrap();
            let rep = run(&m, tck, &reqs);
            let v = rep.violations.as_ref().unwrap();
            assert!(
                v.is_empty(),
                "{kind}: {} violations: {:?}",
                v.len(),
                &v[..v.len().min(5)]
            );
            assert_eq!(rep.total.requests(), 6000);
            assert!(rep.total.refs > 0 || rep.cycles < m.timing.refi as u64);
            println!("{kind}\n{rep}");
        }
    }
}

/// Unthrottled sequential reads on one channel of the paper's memory, spread
/// over bank groups by the default mapping, reach >= 90% of the channel's peak
/// with nearly every request a row hit; uniform random reads reach far less.
#[test]
fn streaming_reaches_peak_and_random_does_not() {
    for (m, tck) in [
        (one_channel(MemCfg::paper()), 500),
        (MemCfg::dramsim3_gddr5(), 667),
    ] {
        let stream = run(&m, tck, &generate("stream", 20_000, 1, &m, 0, 0.0).unwrap());
        let random = run(&m, tck, &generate("random", 5_000, 1, &m, 0, 0.0).unwrap());
        let s = stream.bandwidth_gbs() / stream.peak_gbs();
        let r = random.bandwidth_gbs() / random.peak_gbs();
        println!(
            "{}: stream {:.1}% of peak, hit rate {:.1}%; random {:.1}%, hit rate {:.1}%",
            m.mapping,
            100.0 * s,
            100.0 * stream.total.row_hit_rate(),
            100.0 * r,
            100.0 * random.total.row_hit_rate()
        );
        if m.geometry.line_bytes == 64 {
            assert!(s >= 0.90, "stream reached only {:.1}% of peak", 100.0 * s);
            assert!(stream.total.row_hit_rate() > 0.98);
        }
        assert!(r < 0.5 * s, "random {r} should be far below stream {s}");
        assert!(random.total.row_hit_rate() < 0.1);
    }
}
