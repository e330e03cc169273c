//! The thread multiprocessor against the functional model: it computes from the
//! bytes in memory, traverses in the reference order, has closed-form timing on one
//! TP, shows real contention with 16, and sleeping or evaluation order change
//! nothing.

use dualstream::config::Config;
use dualstream::contract::{
    HitRec, NODE_BYTES, RayRec, Ref, SEG_SAME, SEGMENT_HEADER_BYTES, SegEntry, TRI_BYTES,
};
use dualstream::geom::cull;
use dualstream::geom::{Aabb, Triangle, inverse_dir, ray_box, ray_triangle};
use dualstream::render::traverse::SegmentView;
use dualstream::render::{Prepared, RenderCfg, prepare};
use dualstream::rtl::{LinkCfg, SimOptions, TraceSpec, Tracer};
use dualstream::scene::Scene;
use dualstream::testbench::tm_tb::{
    self, RunOptions, TmJob, TmRun, TmTbOptions, expected, run_job, scoreboard, treelet_rays,
};

struct Setup {
    p: Prepared,
    rays: Vec<Vec<RayRec>>,
}

fn setup(name: &str, res: u32, upto: u32) -> Setup {
    let mut scene: Scene = dualstream::scene::load(name).unwrap();
    scene.settings.width = res;
    scene.settings.height = res;
    let p = prepare(&scene, &RenderCfg::default()).unwrap();
    let rays = treelet_rays(&p, &scene, upto);
    Setup { p, rays }
}

fn entry(p: &Prepared, s: u32) -> SegEntry {
    SegEntry::read(&p.mem, p.map.seg_entry_addr(s))
}

fn view(mem: &dualstream::contract::SparseMem, e: &SegEntry, s: u32) -> SegmentView {
    SegmentView::load(mem, e.base, s, e.nodes, e.tris)
}

fn run(cfg: &Config, s: &Setup, seg: u32, rays: Vec<RayRec>, opts: &RunOptions) -> TmRun {
    let job = TmJob {
        mem: &s.p.mem,
        seg,
        entry: entry(&s.p, seg),
        rays,
    };
    run_job(cfg, &job, opts, None).unwrap()
}

/// The plain traversal of one segment, written out again with a log of what it
/// loads (an independent oracle for the TP's request order and work counts).
#[derive(Default, Debug)]
struct Visit {
    pops: u64,
    exits: u64,
    nodes: u64,
    tris: u64,
    /// Line addresses in load order (nodes, and each triangle's one or two lines).
    lines: Vec<u64>,
    node_addrs: Vec<u64>,
}

fn plain_traversal(v: &SegmentView, e: &SegEntry, ray: &RayRec) -> Visit {
    let mut out = Visit::default();
    let inv = inverse_dir(ray.dir);
    let t_ray = ray.t_max();
    let mut best = HitRec::NONE;
    let mut stack = vec![(ray.entry, SEG_SAME, 0.0f32)];
    let node_base = e.base + SEGMENT_HEADER_BYTES as u64;
    let tri_base = node_base + e.nodes as u64 * NODE_BYTES as u64;
    loop {
        out.pops += 1;
        let Some((r, s, te)) = stack.pop() else { break };
        if te > cull(best.t.min(t_ray)) {
            continue;
        }
        if s != SEG_SAME {
            out.exits += 1;
            continue;
        }
        match Ref::decode(r) {
            Ref::Node(i) => {
                out.nodes += 1;
                let a = node_base + i as u64 * NODE_BYTES as u64;
                out.node_addrs.push(a);
                out.lines.push(a);
                let n = &v.nodes[i as usize];
                let lim = cull(best.t.min(t_ray));
                let hit = [0, 1].map(|k| {
                    let b = Aabb {
                        min: n.bmin[k],
                        max: n.bmax[k],
                    };
                    ray_box(ray.origin, inv, 0.0, lim, &b)
                });
                let order = match (hit[0], hit[1]) {
                    (Some(a), Some(b)) if b < a => [0, 1],
                    _ => [1, 0],
                };
                for k in order {
                    if let Some(t) = hit[k] {
                        stack.push((n.child[k], n.seg[k], t));
                    }
                }
            }
            Ref::Leaf { first, count } => {
                for k in first..first + count {
                    out.tris += 1;
                    let a = tri_base + k as u64 * TRI_BYTES as u64;
                    out.lines.push(a & !63);
                    if (a + TRI_BYTES as u64 - 1) & !63 != a & !63 {
                        out.lines.push((a + TRI_BYTES as u64 - 1) & !63);
                    }
                    let tr = &v.tris[k as usize];
                    let tri = Triangle {
                        v0: tr.v[0],
                        v1: tr.v[1],
                        v2: tr.v[2],
                    };
                    if let Some(h) = ray_triangle(ray.origin, ray.dir, 0.0, best.t.min(t_ray), &tri)
                    {
                        let c = HitRec {
                            t: h.t,
                            tri_id: tr.tri_id,
                            u: h.u,
                            v: h.v,
                        };
                        if c.closer_than(&best) {
                            best = c;
                        }
                    }
                }
            }
            Ref::None => {}
        }
    }
    out
}

#[test]
fn scoreboard_passes_on_every_cornell_treelet() {
    let s = setup("cornell", 24, 3);
    let cfg = Config::default();
    for seg in 0..4u32 {
        let rays = s.rays[seg as usize].clone();
        assert!(!rays.is_empty());
        let r = run(&cfg, &s, seg, rays.clone(), &RunOptions::default());
        let v = view(&s.p.mem, &entry(&s.p, seg), seg);
        let (errors, counts) = scoreboard(&r, &v, &rays);
        assert!(errors.is_empty(), "treelet {seg}: {errors:?}");
        assert!(counts.box_tests > 0 && counts.tri_tests > 0);
        if seg == 0 {
            assert!(!r.writes.is_empty(), "the root segment exits into children");
        }
    }
}

#[test]
fn it_computes_from_memory_not_from_the_host_scene() {
    let s = setup("cornell", 16, 1);
    let seg = 1;
    let e = entry(&s.p, seg);
    let rays = s.rays[seg as usize].clone();
    let original = view(&s.p.mem, &e, seg);
    let (_, want_orig, _) = expected(&original, &rays);
    // The triangle most rays hit: move it far away inside the image.
    let mut ids: Vec<u32> = want_orig.iter().map(|h| h.hit.tri_id).collect();
    ids.sort_unstable();
    let id = *ids
        .chunk_by(|a, b| a == b)
        .max_by_key(|c| c.len())
        .unwrap()
        .first()
        .unwrap();
    let mut mem = dualstream::contract::SparseMem::new(s.p.mem.capacity());
    let mut bytes = vec![0u8; e.bytes as usize];
    s.p.mem.read(e.base, &mut bytes);
    mem.write(e.base, &bytes);
    let ti = s.p.mem.read_u32(s.p.map.tri_index + id as u64 * 4);
    let ta = s.p.map.scene + ti as u64 * 16;
    assert!(
        ta >= e.base && ta < e.base + e.bytes as u64,
        "the triangle is in the segment"
    );
    for k in 0..9 {
        let a = ta + 4 * k;
        mem.write_f32(a, mem.read_f32(a) + 1000.0);
    }
    let job = TmJob {
        mem: &mem,
        seg,
        entry: e,
        rays: rays.clone(),
    };
    let r = run_job(&Config::default(), &job, &RunOptions::default(), None).unwrap();
    let corrupted = view(&mem, &e, seg);
    let (errors, _) = scoreboard(&r, &corrupted, &rays);
    assert!(
        errors.is_empty(),
        "TM follows the corrupted bytes: {errors:?}"
    );
    let key = |h: &dualstream::units::tp::HitUpdate| (h.index, h.hit.tri_id, h.hit.t.to_bits());
    let mut got: Vec<_> = r.hits.iter().map(key).collect();
    let mut orig: Vec<_> = want_orig.iter().map(key).collect();
    got.sort_unstable();
    orig.sort_unstable();
    assert_ne!(got, orig, "the reference on the original scene differs");
    assert!(
        !got.iter().any(|h| h.1 == id),
        "nothing hits the moved triangle"
    );
}

#[test]
fn a_single_ray_loads_nodes_in_the_reference_visit_order() {
    let s = setup("cornell", 16, 0);
    let cfg = Config::default();
    let e = entry(&s.p, 0);
    let v = view(&s.p.mem, &e, 0);
    let opts = RunOptions {
        log: true,
        ..RunOptions::default()
    };
    let mut checked = 0;
    for ray in s.rays[0].iter().step_by(37).take(6) {
        let r = run(&cfg, &s, 0, vec![*ray], &opts);
        let want = plain_traversal(&v, &e, ray);
        let log: Vec<u64> = r.tp_logs.iter().flatten().copied().collect();
        assert_eq!(log, want.lines, "line request order of ray {}", ray.ray_id);
        let node_end = e.base + SEGMENT_HEADER_BYTES as u64 + e.nodes as u64 * 64;
        let nodes: Vec<u64> = log.iter().copied().filter(|&a| a < node_end).collect();
        assert_eq!(nodes, want.node_addrs);
        let l1: Vec<u64> = r.l1_log.iter().map(|x| x.1).collect();
        assert_eq!(l1, want.lines, "the L1 sees the same order");
        checked += want.nodes;
    }
    assert!(checked > 20);
}

/// Predicted cycles of one TP with ideal memory: state costs, round trips, and a
/// direct-mapped cache model of the L1 for each line load.
fn predict(
    cfg: &Config,
    mem_latency: u64,
    e: &SegEntry,
    v: &SegmentView,
    rays: &[RayRec],
) -> (u64, [u64; 5]) {
    let c = &cfg.tm.costs;
    let d = cfg.links.tm.delay as u64;
    let rt = |p: &dualstream::rtl::PipeCfg| p.latency as u64 + 3 * d;
    let r_hit = d + cfg.tm.l1.hit_latency as u64;
    let r_miss = 3 * d + mem_latency;
    let lines = (cfg.tm.l1.bytes / 64) as u64;
    let banks = cfg.tm.l1.banks as u64;
    let mut tags = vec![u64::MAX; lines as usize];
    let (mut total, mut pops, mut nodes, mut tris, mut hits, mut misses) = (0, 0, 0, 0, 0, 0);
    for ray in rays {
        let w = plain_traversal(v, e, ray);
        let mut t = c.fetch.cycles as u64 + rt(&cfg.divider) + c.init.cycles as u64;
        t += w.pops * c.pop.cycles as u64 + w.exits * c.exit.cycles as u64;
        t += w.nodes
            * (c.node_fetch.cycles as u64
                + c.box_issue.cycles as u64
                + 1
                + rt(&cfg.box_pipe)
                + c.node_push.cycles as u64);
        t += w.tris
            * (c.tri_fetch.cycles as u64
                + c.tri_issue.cycles as u64
                + rt(&cfg.tri_pipe)
                + c.tri_result.cycles as u64);
        for a in &w.lines {
            let i = a / 64;
            let slot = ((i % banks) * (lines / banks) + (i / banks) % (lines / banks)) as usize;
            if tags[slot] == *a {
                t += r_hit;
                hits += 1;
            } else {
                tags[slot] = *a;
                t += r_miss;
                misses += 1;
            }
        }
        t += c.finish.cycles as u64 + 1; // the next ray is taken the cycle after
        total += t;
        pops += w.pops;
        nodes += w.nodes;
        tris += w.tris;
    }
    (total, [pops, nodes, tris, hits, misses])
}

#[test]
fn one_tp_timing_is_closed_form() {
    let s = setup("cornell", 16, 1);
    let seg = 1;
    let e = entry(&s.p, seg);
    let v = view(&s.p.mem, &e, seg);
    let rays: Vec<RayRec> = s.rays[seg as usize].iter().copied().take(40).collect();
    let mut cfg = Config::default();
    cfg.tm.tps = 1;
    let opts = RunOptions::default();
    let measure = |cfg: &Config, opts: &RunOptions| {
        let r = run(cfg, &s, seg, rays.clone(), opts);
        let (errors, _) = scoreboard(&r, &v, &rays);
        assert!(errors.is_empty(), "{errors:?}");
        r.cycles - r.tp_first_ray[0].unwrap()
    };
    let base = measure(&cfg, &opts);
    let (want, [pops, nodes, tris, hits, misses]) =
        predict(&cfg, opts.mem_latency as u64, &e, &v, &rays);
    assert_eq!(
        base, want,
        "1 TP, ideal memory: cycles = sum of costs and round trips"
    );
    assert!(nodes > 0 && tris > 0 && hits > 0 && misses > 0);
    // Raising one latency by k raises the total by k x its uses.
    let k = 3u64;
    let mut c2 = cfg.clone();
    c2.tm.costs.pop.cycles += k as u32;
    assert_eq!(measure(&c2, &opts), base + k * pops, "pop cost");
    let mut c2 = cfg.clone();
    c2.tri_pipe.latency += k as u32;
    assert_eq!(
        measure(&c2, &opts),
        base + k * tris,
        "triangle pipeline latency"
    );
    let mut c2 = cfg.clone();
    c2.box_pipe.latency += k as u32;
    assert_eq!(
        measure(&c2, &opts),
        base + k * nodes,
        "box pipeline latency"
    );
    let mut c2 = cfg.clone();
    c2.tm.l1.hit_latency += k as u32;
    assert_eq!(measure(&c2, &opts), base + k * hits, "L1 hit latency");
    let o2 = RunOptions {
        mem_latency: opts.mem_latency + k as u32,
        ..opts.clone()
    };
    assert_eq!(measure(&cfg, &o2), base + k * misses, "memory latency");
}

#[test]
fn sixteen_tps_contend_and_triangles_bound_throughput() {
    let s = setup("cornell", 64, 1);
    let cfg = Config::default();
    let seg = 1;
    let rays = s.rays[seg as usize].clone();
    let r = run(&cfg, &s, seg, rays.clone(), &RunOptions::default());
    let v = view(&s.p.mem, &entry(&s.p, seg), seg);
    let (errors, counts) = scoreboard(&r, &v, &rays);
    assert!(errors.is_empty(), "{errors:?}");
    let u = &r.units;
    assert!(
        r.counter(&[u.l1], "bank_conflicts") > 0,
        "L1 bank conflicts"
    );
    assert!(
        r.counter(&[u.xbar], "tri_conflicts") > 0,
        "triangle arbitration"
    );
    assert!(r.counter(&[u.xbar], "box_conflicts") > 0, "box arbitration");
    assert!(
        r.counter(&u.tps, "stall_tri") > 0,
        "TPs stall on the triangle pipelines"
    );
    // Two pipelines accepting one test per interval bound the TM from below...
    let ii = cfg.tri_pipe.interval as u64;
    let bound = counts.tri_tests * ii / cfg.tm.tri_pipes as u64;
    assert!(r.cycles >= bound, "{} cycles < {bound}", r.cycles);
    // ... and on this triangle-heavy treelet they are what limits it.
    let busy: u64 = u
        .tri_pipes
        .iter()
        .map(|&t| r.unit(t).status_cycles[dualstream::rtl::Status::Busy as usize])
        .sum();
    let one_tp = {
        let mut c1 = cfg.clone();
        c1.tm.tps = 1;
        run(&c1, &s, seg, rays.clone(), &RunOptions::default()).cycles
    };
    assert!(
        (r.cycles as f64) < 1.5 * bound as f64 && one_tp > 8 * r.cycles,
        "16 TPs ({} cycles) come close to the triangle bound {bound} (1 TP: {one_tp})",
        r.cycles
    );
    let util = busy as f64 / (cfg.tm.tri_pipes as u64 * r.cycles) as f64;
    assert!(util > 0.75, "triangle pipelines busy {util:.2} of the time");
}

fn outcome(opts: SimOptions) -> (u64, Vec<dualstream::rtl::UnitStats>, u64, usize) {
    outcome_with(&Config::default(), opts)
}

fn outcome_with(
    cfg: &Config,
    opts: SimOptions,
) -> (u64, Vec<dualstream::rtl::UnitStats>, u64, usize) {
    let s = setup("cornell", 12, 1);
    let seg = 1;
    let rays = s.rays[seg as usize].clone();
    let buf = dualstream::rtl::SharedBuf::default();
    let job = TmJob {
        mem: &s.p.mem,
        seg,
        entry: entry(&s.p, seg),
        rays,
    };
    let o = RunOptions {
        sim: opts,
        trace: TraceSpec::all(),
        ..RunOptions::default()
    };
    let tracer = Tracer::new(Box::new(buf.clone()), o.trace.clone()).unwrap();
    let r = run_job(cfg, &job, &o, Some(tracer)).unwrap();
    let vcd = buf.0.lock().unwrap().clone();
    (r.end_ps, r.stats, dualstream::util::fnv1a(&vcd), vcd.len())
}

/// Sleep off under the shadow check, a shuffled order, and both: a result must
/// not depend on any of them.
fn other_orders() -> [SimOptions; 3] {
    let o = |sleep, shuffle_seed| SimOptions {
        sleep,
        shadow: !sleep,
        shuffle_seed,
        threads: 1,
        auto_lanes: false,
        check_ready: true,
        capture: None,
    };
    [o(false, None), o(true, Some(7)), o(false, Some(8))]
}

#[test]
fn sleeping_and_evaluation_order_change_nothing() {
    let base = outcome(SimOptions::default());
    assert!(base.3 > 10_000);
    for m in other_orders() {
        let o = outcome(m.clone());
        assert_eq!(o.0, base.0, "{m:?}: end time");
        assert_eq!(o.1, base.1, "{m:?}: statistics");
        assert_eq!((o.2, o.3), (base.2, base.3), "{m:?}: VCD");
    }
}

/// The ray-box pipeline inside the crossbar wakes it for its own steps: with
/// one-entry links, an initiation interval of 2 and two-cycle links (results
/// held back, the pipeline frozen, grants refused), sleeping and the order must
/// still change nothing, and the shadow check must find no step it slept through.
#[test]
fn a_stalling_box_pipeline_sleeps_exactly() {
    for (depth, delay, latency, interval) in [(1, 1, 5, 2), (2, 2, 9, 3)] {
        let mut cfg = Config::default();
        cfg.links.tm = LinkCfg { depth, delay };
        cfg.box_pipe.latency = latency;
        cfg.box_pipe.interval = interval;
        cfg.tm.l1.hit_latency = cfg.tm.l1.hit_latency.max(delay + 1);
        let base = outcome_with(&cfg, SimOptions::default());
        let def = outcome(SimOptions::default());
        assert_ne!(base.0, def.0, "the stressed pipeline changes the timing");
        for m in other_orders() {
            let o = outcome_with(&cfg, m.clone());
            assert_eq!(o.0, base.0, "{depth}/{delay}/{interval} {m:?}: end time");
            assert_eq!(o.1, base.1, "{depth}/{delay}/{interval} {m:?}: statistics");
            assert_eq!((o.2, o.3), (base.2, base.3), "{m:?}: VCD");
        }
    }
}

#[test]
fn vcd_has_a_scope_per_tp_matching_its_verilog() {
    let s = setup("cornell", 8, 1);
    let buf = dualstream::rtl::SharedBuf::default();
    let job = TmJob {
        mem: &s.p.mem,
        seg: 1,
        entry: entry(&s.p, 1),
        rays: s.rays[1].clone(),
    };
    run_job(
        &Config::default(),
        &job,
        &RunOptions::default(),
        Some(Tracer::new(Box::new(buf.clone()), RunOptions::default().trace).unwrap()),
    )
    .unwrap();
    let vcd = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
    for k in 0..16 {
        assert!(
            vcd.contains(&format!("$scope module tp{k} $end")),
            "scope tp{k}"
        );
    }
    for sig in [" state ", " ray_index ", " node_addr ", " stack_depth "] {
        assert!(vcd.contains(sig), "TP signal{sig}");
    }
    let tp_v = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/hdl/tp.v")).unwrap();
    for sig in ["state", "ray_index", "node_addr", "stack_depth"] {
        assert!(tp_v.contains(&format!(" {sig};")), "tp.v declares {sig}");
    }
    let tm_v = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/hdl/tm.v")).unwrap();
    assert!(
        tm_v.contains(") tp15 (") && tm_v.contains("l1 #(") && tm_v.contains("staging_buffer #(")
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let opts = |treelet, config| TmTbOptions {
        scene: "builtin:tiny".into(),
        treelet,
        res: Some((8, 8)),
        max_rays: None,
        run: RunOptions::default(),
        vcd: None,
        config,
    };
    let e = tm_tb::run(&opts(5, Config::default()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("treelet 5 does not exist"), "{e}");
    let mut c = Config::default();
    c.tm.tps = 0;
    let e = tm_tb::run(&opts(0, c)).unwrap_err().to_string();
    assert!(e.contains("tm.tps = 0"), "{e}");
    let mut c = Config::default();
    c.tm.scratchpad_bytes = 12;
    let e = tm_tb::run(&opts(0, c)).unwrap_err().to_string();
    assert!(e.contains("tm.scratchpad_bytes"), "{e}");
    let mut c = Config::default();
    c.tm.scratchpad_bytes = 24;
    let e = tm_tb::run(&opts(0, c)).unwrap_err().to_string();
    assert!(
        e.contains("stack entries") && e.contains("raise tm.scratchpad_bytes"),
        "{e}"
    );
    let e = Config::from_toml("[tm.costs.pop]\ncycles = 2\nint = 5\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("single-issue"), "{e}");
}

/// The energy model charges a functional run with the TP work it implies
/// (`energy::tm_activity`); that work must equal what the cycle-level TPs do.
#[test]
fn functional_counts_imply_the_tps_state_uses() {
    let s = setup("cornell", 32, 3);
    let cfg = Config::default();
    for seg in 0..=3u32 {
        let rays = s.rays[seg as usize].clone();
        if rays.is_empty() {
            continue;
        }
        let e = entry(&s.p, seg);
        let v =
            dualstream::render::traverse::SegmentView::load(&s.p.mem, e.base, seg, e.nodes, e.tris);
        let (_, _, counts) = expected(&v, &rays);
        let r = run(&cfg, &s, seg, rays.clone(), &RunOptions::default());
        let tps = &r.units.tps;
        assert_eq!(r.counter(tps, "fetch"), rays.len() as u64, "segment {seg}");
        assert_eq!(r.counter(tps, "pop"), counts.pops, "segment {seg}: pops");
        assert_eq!(
            r.counter(tps, "node_fetch"),
            counts.nodes,
            "segment {seg}: nodes"
        );
        assert_eq!(
            r.counter(tps, "tri_fetch"),
            counts.tri_tests,
            "segment {seg}: triangles"
        );
        assert_eq!(r.counter(tps, "exit"), counts.exits, "segment {seg}: exits");
        assert_eq!(
            r.counter(tps, "l1_loads"),
            counts.l1_lines,
            "segment {seg}: L1 loads"
        );
    }
}

/// The L1 answers one fill per cycle, in arrival order. A line that arrives
/// behind a fill that must wait (its TP's response link is full) has had its
/// wake-up by the time the first fill goes; the L1 must still answer it the next
/// cycle (testbench/l1_tb.rs), sleeping or not, in any evaluation order.
#[test]
fn l1_answers_a_line_that_waited_behind_a_blocked_fill() {
    use dualstream::testbench::l1_tb::{
        FillBehindCfg, LINE_A, LINE_C, LINE_D, fill_behind_blocked_fill, line_of,
    };
    let b = FillBehindCfg::default();
    let base = fill_behind_blocked_fill(SimOptions::default(), b).unwrap();
    // Port 0 takes A when its sink starts; the freed link wakes the L1 the next
    // cycle, which answers C (visible one cycle later); D goes the cycle after
    // (one fill per cycle) and is visible one cycle after that.
    let r = b.ready_from;
    assert_eq!(
        base.port0,
        vec![
            (r, LINE_A, line_of(LINE_A)),
            (r + 2, LINE_C, line_of(LINE_C))
        ],
        "port 0"
    );
    assert_eq!(
        base.port1,
        vec![(r + 3, LINE_D, line_of(LINE_D))],
        "port 1: the line behind the blocked fill"
    );
    let mut asked = base.miss_reqs.clone();
    asked.sort_unstable();
    assert_eq!(asked, vec![LINE_A, LINE_C, LINE_D], "one miss per line");
    assert_eq!((base.fills, base.accesses), (3, 3));
    // C and D were both waiting on the miss port before port 0 was ready.
    assert!(b.c_back + 2 < r);
    for m in other_orders() {
        let o = fill_behind_blocked_fill(m.clone(), b).unwrap();
        assert_eq!(o, base, "{m:?}");
    }
}
