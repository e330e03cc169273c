//! The TM testbench, with stand-ins for the global units: a scripted feeder fills
//! the staging buffer with the rays of one treelet (as the functional model
//! enqueues them: primary rays into the root segment, duplicates into children), an
//! ideal memory behind the L1 miss port serves the segment's bytes from the DRAM
//! image after a fixed latency, and two collectors take the ray writes and hit
//! updates.
//!
//! Scoreboard: the multiset of duplicates (child segment, ray, entry) and of hit
//! updates (hit index, hit record bits) equals what `traverse_segment` produces for
//! the same rays on the same segment, and the box and triangle test counts match.

use crate::testbench::TbError;
use std::collections::{HashMap, VecDeque};
use std::time::Instant;

use crate::config::Config;
use crate::contract::{HitRec, LINE_BYTES, RayRec, SegEntry, SparseMem};
use crate::render::traverse::{SegmentView, TraversalCounts, traverse_segment};
use crate::render::{Prepared, RenderCfg, prepare};
use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, PortDecl, PortDir, Sim, SimOptions, Status, TraceSpec,
    Tracer, UnitDecl, UnitStats,
};
use crate::scene::Scene;
use crate::units::l1::{L1, L1Req, L1Resp, Line};
use crate::units::memory::{MemLineReq, MemLineResp};
use crate::units::shade::{next_f32, pixel_seed};
use crate::units::staging_buffer::{SbFill, SbHeader};
use crate::units::tm::{self, TmPorts, TmUnits};
use crate::units::tp::{HitUpdate, RayWrite, Tp};

use super::harness::{Driver, Sink};

/// Ideal memory behind the L1 miss port: every request is answered `latency` cycles
/// after acceptance (response link included), one per cycle, from a snapshot of the
/// DRAM image's lines.
pub struct IdealMem {
    pub req: In<L1Req>,
    pub resp: Out<L1Resp>,
    lines: HashMap<u64, Line>,
    latency: u64,
    out_delay: u64,
    q: VecDeque<(u64, L1Resp)>,
    pub served: u64,
    /// Requests outside the snapshot (answered with zeros; an error for the bench).
    pub strays: u64,
}

impl IdealMem {
    /// Serves the lines of `[base, base + bytes)` of `mem`.
    pub fn new(
        req: In<L1Req>,
        resp: Out<L1Resp>,
        mem: &SparseMem,
        base: u64,
        bytes: u64,
        latency: u32,
        out_delay: u32,
    ) -> Self {
        let mut lines = HashMap::new();
        let mut a = base / LINE_BYTES * LINE_BYTES;
        while a < base + bytes {
            let mut l = Line::default();
            mem.read(a, &mut l.0);
            lines.insert(a, l);
            a += LINE_BYTES;
        }
        IdealMem {
            req,
            resp,
            lines,
            latency: latency as u64,
            out_delay: out_delay as u64,
            q: VecDeque::new(),
            served: 0,
            strays: 0,
        }
    }
}

impl Declared for IdealMem {
    fn decl(&self) -> UnitDecl {
        UnitDecl {
            module: "tb_ideal_mem",
            source: file!(),
            doc: "testbench component",
            params: vec![],
            ports: self.ports(),
            state: StateList::default().items,
        }
    }
    fn ports(&self) -> Vec<PortDecl> {
        vec![
            PortDecl {
                name: "req",
                dir: PortDir::In,
                width: <L1Req as crate::rtl::Payload>::BITS,
                ty: <L1Req as crate::rtl::Payload>::sv_type(),
                fields: <L1Req as crate::rtl::Payload>::field_list(),
                link: self.req.id,
            },
            PortDecl {
                name: "resp",
                dir: PortDir::Out,
                width: <L1Resp as crate::rtl::Payload>::BITS,
                ty: <L1Resp as crate::rtl::Payload>::sv_type(),
                fields: <L1Resp as crate::rtl::Payload>::field_list(),
                link: self.resp.id,
            },
        ]
    }
    fn sample_state(&self, _cycle: u64, _out: &mut Samples) {}
    fn commit_state(&mut self) {}
    fn reset_state(&mut self) {
        self.q.clear();
    }
    fn state_pending(&self) -> bool {
        false
    }
}

impl Logic for IdealMem {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let mut worked = false;
        if let Some((due, r)) = self.q.front()
            && *due <= c
        {
            if ctx.offer(&self.resp, r.clone()) {
                self.q.pop_front();
                self.served += 1;
                worked = true;
            } else {
                ctx.set_status(Status::OutputBlocked);
                return Next::Idle;
            }
        }
        if let Some(r) = ctx.pop(&self.req) {
            let line = match self.lines.get(&r.addr) {
                Some(l) => l.clone(),
                None => {
                    self.strays += 1;
                    Line::default()
                }
            };
            let due = c + self.latency - self.out_delay;
            self.q.push_back((due, L1Resp { addr: r.addr, line }));
            worked = true;
        }
        ctx.set_status(if worked || !self.q.is_empty() {
            Status::Busy
        } else {
            Status::WaitInput
        });
        match self.q.front() {
            _ if worked => Next::Cycle,
            Some((due, _)) => Next::AtCycle((*due).max(c + 1)),
            None => Next::Idle,
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("served", self.served), ("strays", self.strays)]
    }
}

/// Rays entering each segment in wavefront 0 (primary rays), as the functional
/// model enqueues them: camera rays into the root segment, then each segment's
/// duplicates into its children, segments in id order (parents first). Computed up
/// to and including segment `upto`.
pub fn treelet_rays(p: &Prepared, scene: &Scene, upto: u32) -> Vec<Vec<RayRec>> {
    let (w, h) = (scene.settings.width, scene.settings.height);
    let mut lists: Vec<Vec<RayRec>> = vec![Vec::new(); p.seg.segments.len()];
    let root = p.image.root_entry.encode();
    for pix in 0..w * h {
        let mut rng = pixel_seed(scene.settings.seed, pix);
        let jitter = (next_f32(&mut rng), next_f32(&mut rng));
        let (o, d) = scene.camera.ray(pix % w, pix / w, w, h, jitter);
        lists[0].push(RayRec {
            origin: o,
            dir: d,
            ray_id: pix,
            entry: root,
        });
    }
    let mut stack = Vec::new();
    for s in 0..upto {
        let view = load_view(p, s);
        let rays = std::mem::take(&mut lists[s as usize]);
        let mut counts = TraversalCounts::default();
        for ray in &rays {
            traverse_segment(&view, ray, &mut stack, &mut counts, |cs, entry, _| {
                lists[cs as usize].push(RayRec { entry, ..*ray })
            });
        }
        lists[s as usize] = rays;
    }
    lists
}

fn load_view(p: &Prepared, s: u32) -> SegmentView {
    let e = SegEntry::read(&p.mem, p.map.seg_entry_addr(s));
    SegmentView::load(&p.mem, e.base, s, e.nodes, e.tris)
}

/// What the functional model does with `rays` in segment `view`: duplicates,
/// hit updates, and work counts.
pub fn expected(
    view: &SegmentView,
    rays: &[RayRec],
) -> (Vec<RayWrite>, Vec<HitUpdate>, TraversalCounts) {
    let (mut writes, mut hits) = (Vec::new(), Vec::new());
    let mut counts = TraversalCounts::default();
    let mut stack = Vec::new();
    for ray in rays {
        let best = traverse_segment(view, ray, &mut stack, &mut counts, |seg, entry, _| {
            writes.push(RayWrite {
                seg,
                ray: RayRec { entry, ..*ray },
                done: false,
            })
        });
        if best.is_hit() {
            hits.push(HitUpdate {
                index: ray.hit_index() as u32,
                hit: best,
            });
        }
    }
    (writes, hits, counts)
}

/// One TM run on one segment.
pub struct TmJob<'a> {
    pub mem: &'a SparseMem,
    pub seg: u32,
    pub entry: SegEntry,
    pub rays: Vec<RayRec>,
}

/// How to run a job.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Ideal memory latency (cycles from acceptance to the line visible at the L1).
    pub mem_latency: u32,
    pub sim: SimOptions,
    pub trace: TraceSpec,
    /// Record each TP's and the L1's address sequence.
    pub log: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            mem_latency: 20,
            sim: SimOptions::default(),
            trace: TraceSpec::all(),
            log: false,
        }
    }
}

/// Everything a run produced.
pub struct TmRun {
    /// Cycles from reset to the last TP finishing its last ray.
    pub cycles: u64,
    pub end_ps: u64,
    pub writes: Vec<RayWrite>,
    pub hits: Vec<HitUpdate>,
    pub stats: Vec<UnitStats>,
    pub links: Vec<(String, crate::rtl::link::LinkStats)>,
    pub units: TmUnits,
    pub tp_logs: Vec<Vec<u64>>,
    pub l1_log: Vec<(u16, u64)>,
    pub tp_first_ray: Vec<Option<u64>>,
    pub evals: u64,
    pub wall_s: f64,
    pub strays: u64,
}

impl TmRun {
    pub fn unit(&self, u: crate::rtl::UnitId) -> &UnitStats {
        &self.stats[u.0 as usize]
    }
    /// A counter summed over the units whose path ends with `suffix` pattern match.
    pub fn counter(&self, units: &[crate::rtl::UnitId], name: &str) -> u64 {
        units
            .iter()
            .map(|&u| {
                self.unit(u)
                    .counters
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map_or(0, |(_, v)| *v)
            })
            .sum()
    }
}

/// Runs one job on a fresh TM; `tracer` writes the waveform if given.
pub fn run_job(
    cfg: &Config,
    job: &TmJob,
    opts: &RunOptions,
    tracer: Option<Tracer>,
) -> Result<TmRun, TbError> {
    cfg.validate()?;
    let t0 = Instant::now();
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", cfg.clocks.core_ps)?;
    let l = cfg.links.tm;
    let (fill_o, fill_i) = sim.link::<SbFill>("tb.fill", l);
    let (mq_o, mq_i) = sim.link::<L1Req>("tb.miss_req", l);
    let (mr_o, mr_i) = sim.link::<L1Resp>("tb.miss_resp", l);
    let (rw_o, rw_i) = sim.link::<RayWrite>("tb.ray_write", l);
    let (hit_o, hit_i) = sim.link::<HitUpdate>("tb.hit", l);
    let feeder = sim.add("tb.feeder", clk, Driver::new(fill_o));
    if opts.mem_latency < l.delay {
        return Err(TbError::Invalid(format!(
            "--mem-latency {} is shorter than the response link delay ({}); give at least {}",
            opts.mem_latency, l.delay, l.delay
        )));
    }
    let mem = sim.add(
        "tb.memory",
        clk,
        IdealMem::new(
            mq_i,
            mr_o,
            job.mem,
            job.entry.base,
            job.entry.bytes as u64,
            opts.mem_latency,
            l.delay,
        ),
    );
    let wsink = sim.add("tb.ray_writes", clk, Sink::new(rw_i, 1.0, 1));
    let hsink = sim.add("tb.hits", clk, Sink::new(hit_i, 1.0, 2));
    // The bench traces treelets only: the shading port has an idle driver and sink.
    let (gmem_req, gq_i) = sim.link::<MemLineReq>("tb.gmem_req", l);
    let (gr_o, gmem_resp) = sim.link::<MemLineResp>("tb.gmem_resp", l);
    sim.add("tb.gmem_sink", clk, Sink::new(gq_i, 1.0, 3));
    sim.add("tb.gmem_driver", clk, Driver::new(gr_o));
    let units = tm::build(
        &mut sim,
        clk,
        &cfg.tm_spec(),
        "tb.tm",
        TmPorts {
            fill: fill_i,
            miss_req: mq_o,
            miss_resp: mr_i,
            ray_write: rw_o,
            hit: hit_o,
            gmem_req,
            gmem_resp,
        },
    );
    if opts.log {
        for &t in &units.tps {
            sim.unit_mut::<Tp>(t).enable_log();
        }
        sim.unit_mut::<L1>(units.l1).enable_log();
    }
    if let Some(t) = tracer {
        sim.attach_tracer(t)?;
    } else {
        sim.elaborate()?;
    }
    // The feeder: one ray per cycle, buckets of `rays_per_bucket`, `last` closing each.
    let per_bucket = cfg.memory.rays_per_bucket().min(cfg.tm.half_rays()) as usize;
    let hdr = SbHeader {
        seg: job.seg,
        base: job.entry.base,
        nodes: job.entry.nodes,
    };
    {
        let d = sim.unit_mut::<Driver<SbFill>>(feeder);
        for (i, r) in job.rays.iter().enumerate() {
            let last = (i + 1) % per_bucket == 0 || i + 1 == job.rays.len();
            d.send(
                0,
                SbFill {
                    ray: *r,
                    hdr: hdr.clone(),
                    last,
                },
            );
        }
    }
    sim.wake(feeder);
    sim.run_to_idle(u64::MAX / 2)?;
    if let Some(r) = sim.finish_trace() {
        r.map_err(|source| TbError::Vcd {
            what: "cannot write the VCD",
            source,
        })?;
    }
    let wall_s = t0.elapsed().as_secs_f64();
    for (k, &t) in units.tps.iter().enumerate() {
        if sim.unit_ref::<Tp>(t).overflowed() {
            return Err(TbError::StackOverflow(format!(
                "TP {k} overflowed its stack ({} entries in tm.scratchpad_bytes = {}); the segment is deeper than the scratchpad allows: raise tm.scratchpad_bytes",
                cfg.tm.stack_entries(),
                cfg.tm.scratchpad_bytes
            )));
        }
    }
    let tps: Vec<&Tp> = units.tps.iter().map(|&t| sim.unit_ref::<Tp>(t)).collect();
    let cycles = tps
        .iter()
        .filter(|t| t.stats.rays > 0)
        .map(|t| t.stats.last_finish + 1)
        .max()
        .unwrap_or(0);
    let tp_logs = tps.iter().map(|t| t.request_log().to_vec()).collect();
    let tp_first_ray = tps.iter().map(|t| t.stats.first_ray).collect();
    let l1_log = sim.unit_ref::<L1>(units.l1).log.clone().unwrap_or_default();
    // End-of-ray markers are the scheduler's bookkeeping, not duplicates.
    let writes = sim
        .unit_ref::<Sink<RayWrite>>(wsink)
        .got
        .iter()
        .filter(|(_, v)| !v.done)
        .map(|(_, v)| v.clone())
        .collect();
    let hits = sim
        .unit_ref::<Sink<HitUpdate>>(hsink)
        .got
        .iter()
        .map(|(_, v)| v.clone())
        .collect();
    let strays = sim.unit_ref::<IdealMem>(mem).strays;
    Ok(TmRun {
        cycles,
        end_ps: sim.now(),
        writes,
        hits,
        stats: sim.all_stats(),
        links: sim.link_stats(),
        units,
        tp_logs,
        l1_log,
        tp_first_ray,
        evals: sim.evals,
        wall_s,
        strays,
    })
}

fn write_key(w: &RayWrite) -> (u32, u32, u32, [u32; 6]) {
    let r = &w.ray;
    (
        w.seg,
        r.ray_id,
        r.entry,
        [
            r.origin.x.to_bits(),
            r.origin.y.to_bits(),
            r.origin.z.to_bits(),
            r.dir.x.to_bits(),
            r.dir.y.to_bits(),
            r.dir.z.to_bits(),
        ],
    )
}

fn hit_key(h: &HitUpdate) -> (u32, [u32; 4]) {
    let x: &HitRec = &h.hit;
    (
        h.index,
        [x.t.to_bits(), x.tri_id, x.u.to_bits(), x.v.to_bits()],
    )
}

/// Compares a run with the functional model; returns the mismatches.
pub fn scoreboard(
    run: &TmRun,
    view: &SegmentView,
    rays: &[RayRec],
) -> (Vec<String>, TraversalCounts) {
    let (ew, eh, counts) = expected(view, rays);
    let mut errors = Vec::new();
    let mut a: Vec<_> = run.writes.iter().map(write_key).collect();
    let mut b: Vec<_> = ew.iter().map(write_key).collect();
    a.sort_unstable();
    b.sort_unstable();
    if a != b {
        let first = a.iter().zip(&b).position(|(x, y)| x != y);
        errors.push(format!(
            "duplicates differ: TM {} vs functional {} (first difference at sorted index {:?})",
            a.len(),
            b.len(),
            first
        ));
    }
    let mut a: Vec<_> = run.hits.iter().map(hit_key).collect();
    let mut b: Vec<_> = eh.iter().map(hit_key).collect();
    a.sort_unstable();
    b.sort_unstable();
    if a != b {
        let first = a.iter().zip(&b).position(|(x, y)| x != y);
        errors.push(format!(
            "hit updates differ: TM {} vs functional {} (first difference at sorted index {:?})",
            a.len(),
            b.len(),
            first
        ));
    }
    let box_tests = run.counter(&[run.units.xbar], "box_tests");
    let tri_tests = run.counter(&run.units.tri_pipes, "tests");
    if box_tests != counts.box_tests {
        errors.push(format!(
            "box tests: TM {box_tests}, functional {}",
            counts.box_tests
        ));
    }
    if tri_tests != counts.tri_tests {
        errors.push(format!(
            "triangle tests: TM {tri_tests}, functional {}",
            counts.tri_tests
        ));
    }
    if run.strays > 0 {
        errors.push(format!(
            "{} line requests outside the segment reached the memory",
            run.strays
        ));
    }
    (errors, counts)
}

/// The CLI's `tb tm` options.
#[derive(Clone, Debug)]
pub struct TmTbOptions {
    /// Builtin scene name (optionally `builtin:NAME`), scene description or .obj.
    pub scene: String,
    pub treelet: u32,
    /// Resolution override (fewer primary rays, faster).
    pub res: Option<(u32, u32)>,
    /// Use only the first N rays of the treelet.
    pub max_rays: Option<usize>,
    pub run: RunOptions,
    pub vcd: Option<std::path::PathBuf>,
    pub config: Config,
}

/// A TM testbench report.
#[derive(Clone, Debug)]
pub struct TmReport {
    pub scene: String,
    pub treelet: u32,
    pub rays: u64,
    pub cycles: u64,
    pub duplicates: u64,
    pub hit_updates: u64,
    pub box_tests: u64,
    pub tri_tests: u64,
    pub errors: Vec<String>,
    pub wall_s: f64,
    pub evals: u64,
    /// (name, value) lines of the stall breakdown and unit statistics.
    pub breakdown: Vec<(String, u64)>,
}

impl TmReport {
    pub fn passed(&self) -> bool {
        self.errors.is_empty()
    }
}

impl std::fmt::Display for TmReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "testbench tm ({} treelet {}): {}",
            self.scene,
            self.treelet,
            if self.passed() { "PASS" } else { "FAIL" }
        )?;
        writeln!(
            f,
            "  rays {}  duplicates {}  hit updates {}  box tests {}  triangle tests {}",
            self.rays, self.duplicates, self.hit_updates, self.box_tests, self.tri_tests
        )?;
        writeln!(
            f,
            "  TM cycles {}  ({:.1} cycles/ray)  evaluations {}  ({:.2} M evals/s, {:.3} s)",
            self.cycles,
            self.cycles as f64 / self.rays.max(1) as f64,
            self.evals,
            self.evals as f64 / self.wall_s.max(1e-9) / 1e6,
            self.wall_s
        )?;
        for (k, v) in &self.breakdown {
            writeln!(f, "  {k:<34} {v}")?;
        }
        for e in &self.errors {
            writeln!(f, "  ERROR {e}")?;
        }
        Ok(())
    }
}

/// Loads the scene, picks the treelet's rays and runs the scoreboarded bench.
pub fn run(opts: &TmTbOptions) -> Result<TmReport, TbError> {
    let name = opts.scene.strip_prefix("builtin:").unwrap_or(&opts.scene);
    let mut scene = crate::scene::load(name)?;
    if let Some((w, h)) = opts.res {
        scene.settings.width = w;
        scene.settings.height = h;
    }
    let cfg = &opts.config;
    cfg.validate()?;
    let rcfg = RenderCfg {
        accel: cfg.accel.clone(),
        memory: cfg.memory.clone(),
        ..RenderCfg::default()
    };
    let p = prepare(&scene, &rcfg)?;
    let nseg = p.seg.segments.len() as u32;
    if opts.treelet >= nseg {
        return Err(TbError::Invalid(format!(
            "treelet {} does not exist: scene '{}' has {nseg} segments (0..{})",
            opts.treelet,
            scene.name,
            nseg - 1
        )));
    }
    let mut rays = treelet_rays(&p, &scene, opts.treelet).swap_remove(opts.treelet as usize);
    if let Some(n) = opts.max_rays {
        rays.truncate(n);
    }
    let view = load_view(&p, opts.treelet);
    let (_, _, want) = expected(&view, &rays);
    if want.max_stack > cfg.tm.stack_entries() as u64 {
        return Err(TbError::Invalid(format!(
            "treelet {} needs {} stack entries but tm.scratchpad_bytes = {} holds {}: raise tm.scratchpad_bytes",
            opts.treelet,
            want.max_stack,
            cfg.tm.scratchpad_bytes,
            cfg.tm.stack_entries()
        )));
    }
    let job = TmJob {
        mem: &p.mem,
        seg: opts.treelet,
        entry: SegEntry::read(&p.mem, p.map.seg_entry_addr(opts.treelet)),
        rays,
    };
    let tracer = match &opts.vcd {
        Some(path) => Some(Tracer::to_file(path, opts.run.trace.clone())?),
        None => None,
    };
    let r = run_job(cfg, &job, &opts.run, tracer).inspect_err(|_| {
        // No partial waveform (e.g. one the size guard stopped).
        if let Some(p) = &opts.vcd {
            let _ = std::fs::remove_file(p);
        }
    })?;
    let (errors, counts) = scoreboard(&r, &view, &job.rays);
    Ok(TmReport {
        scene: scene.name.clone(),
        treelet: opts.treelet,
        rays: job.rays.len() as u64,
        cycles: r.cycles,
        duplicates: r.writes.len() as u64,
        hit_updates: r.hits.len() as u64,
        box_tests: counts.box_tests,
        tri_tests: counts.tri_tests,
        errors,
        wall_s: r.wall_s,
        evals: r.evals,
        breakdown: breakdown(&r, cfg),
    })
}

/// The stall breakdown: where the TPs' and the shared units' cycles went.
pub fn breakdown(r: &TmRun, cfg: &Config) -> Vec<(String, u64)> {
    let u = &r.units;
    let mut v = Vec::new();
    let mut st = [0u64; 4];
    for &t in &u.tps {
        for (k, x) in r.unit(t).status_cycles.iter().enumerate() {
            st[k] += x;
        }
    }
    for (k, s) in crate::rtl::Status::ALL.iter().enumerate() {
        v.push((format!("TP cycles {}", s.name()), st[k]));
    }
    for name in [
        "stall_div",
        "stall_box",
        "stall_tri",
        "wait_l1",
        "blocked",
        "l1_loads",
    ] {
        v.push((format!("TP {name}"), r.counter(&u.tps, name)));
    }
    for (name, _) in cfg.tm.costs.all() {
        v.push((format!("TP uses {name}"), r.counter(&u.tps, name)));
    }
    for name in ["hits", "misses", "merged", "bank_conflicts", "mshr_stalls"] {
        v.push((format!("L1 {name}"), r.counter(&[u.l1], name)));
    }
    for name in ["div_conflicts", "box_conflicts", "tri_conflicts"] {
        v.push((format!("xbar {name}"), r.counter(&[u.xbar], name)));
    }
    let rb = crate::rtl::Status::ResourceBusy as usize;
    let busy = crate::rtl::Status::Busy as usize;
    v.push((
        "box pipe occupied cycles".into(),
        r.counter(&[u.xbar], "box_occupied_cycles"),
    ));
    let tri_busy: u64 = u
        .tri_pipes
        .iter()
        .map(|&t| r.unit(t).status_cycles[busy])
        .sum();
    let tri_ii: u64 = u
        .tri_pipes
        .iter()
        .map(|&t| r.unit(t).status_cycles[rb])
        .sum();
    v.push(("tri pipes busy cycles (sum)".into(), tri_busy));
    v.push(("tri pipes interval-blocked cycles (sum)".into(), tri_ii));
    v.push((
        "staging buffer swaps".into(),
        r.counter(&[u.staging_buffer], "swaps"),
    ));
    v
}
