//! Parallel evaluation lanes: the worker threads of a multi-threaded run, their
//! hand-over with the caller's thread, and the state of load balancing between
//! lanes and of the automatic choice of the lane count (`SimOptions::auto_lanes`;
//! the decisions themselves are in `partition.rs`).
//!
//! A step with work in two or more lanes hands each worker lane its due units
//! (`Job`), evaluates the last lane on the caller's thread, and waits for the
//! workers. A waiting thread spins for a few tens of microseconds (a step is a
//! few microseconds) and then parks: on a busy machine the other lane may be
//! descheduled for a whole time slice, and a spinning waiter would only keep it
//! from getting a core.

use std::cell::UnsafeCell;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::Thread;
use std::time::{Duration, Instant};

use super::context::{LaneOut, eval_commit_slot};
use super::network::Net;
use super::scheduling::Sched;
use super::{SimError, Slot, Time};
use crate::rtl::calendar::Calendar;

/// `Worker::go` value that ends the worker.
pub(super) const QUIT: u64 = u64::MAX;
/// `Worker::done` value of a worker that panicked.
const PANICKED: u64 = u64::MAX;

/// How long a waiting thread spins before it parks: longer than the typical
/// imbalance of a step between lanes on an idle machine (so parking, whose
/// wake-up costs several microseconds, is rare there), far shorter than a
/// scheduler time slice (milliseconds).
const SPIN: Duration = Duration::from_micros(50);

/// One worker thread of a run: it evaluates the lane its job names.
pub(super) struct Worker {
    /// The step the worker is to run next (`QUIT`: stop).
    pub go: AtomicU64,
    /// The last step the worker finished (`PANICKED`: it panicked).
    pub done: AtomicU64,
    /// The worker is parked, or about to park, waiting for `go`.
    parked: AtomicBool,
    pub job: UnsafeCell<Job>,
}

/// The workers of a run and what they need to wake the caller's thread.
pub(super) struct Crew {
    pub workers: Vec<Worker>,
    /// The caller's thread (the one running the step loop).
    main: Thread,
    /// The caller's thread is parked, or about to park, waiting for a `done`.
    main_parked: AtomicBool,
    /// The workers' threads, set once they are spawned (only the caller's thread
    /// reads them, to unpark a worker).
    pub threads: OnceLock<Vec<Thread>>,
}

/// One step's work for a worker and what it produced.
pub(super) struct Job {
    pub now: Time,
    /// The lane (partition) this job evaluates.
    pub part: u8,
    pub lanes: Lanes,
    pub due: Vec<(u32, bool)>,
    pub out: LaneOut,
    pub result: Result<(), SimError>,
    /// Wall time of the worker's part of the step (load balancing only).
    pub lane_ns: u64,
}

// SAFETY: a worker's `job` is accessed by the caller's thread only while that
// worker waits for `go` and by the worker only between `go` and `done`
// (release/acquire on the two atomics hand it over); the slots and links it points
// to are reached by a worker only for units of its own partition and their links
// (see `Net`), and units and payloads are `Send`.
unsafe impl Sync for Worker {}
// SAFETY: as for `Worker`; the caller's thread owns the `Vec`s and reads
// `threads` only.
unsafe impl Sync for Crew {}

impl Crew {
    pub fn new(n: usize) -> Crew {
        Crew {
            workers: (0..n).map(|_| Worker::new()).collect(),
            main: std::thread::current(),
            main_parked: AtomicBool::new(false),
            threads: OnceLock::new(),
        }
    }

    /// Hands worker `k` the step `seq` (its job is filled in).
    pub fn start(&self, k: usize, seq: u64) {
        let w = &self.workers[k];
        w.go.store(seq, Ordering::SeqCst);
        // A worker that decided to park re-checks `go` after raising `parked`
        // (both SeqCst), so either it sees `seq` or this thread sees `parked`.
        if w.parked.load(Ordering::SeqCst) {
            self.threads.get().expect("workers spawned")[k].unpark();
        }
    }

    /// Waits until worker `k` finished step `seq` (panics if the worker panicked).
    pub fn wait(&self, k: usize, seq: u64) {
        let done = &self.workers[k].done;
        wait_park(
            || {
                let x = done.load(Ordering::SeqCst);
                if x == PANICKED {
                    panic!("a simulator worker thread panicked (see its message above)");
                }
                x == seq
            },
            &self.main_parked,
        );
    }

    /// Ends every worker.
    pub fn quit(&self) {
        for k in 0..self.workers.len() {
            self.start(k, QUIT);
        }
    }

    /// The body of worker thread `k`.
    pub fn worker_loop(&self, k: usize) {
        let w = &self.workers[k];
        /// Tells the caller's thread if this thread unwinds, so that it does not
        /// wait forever.
        struct Alarm<'a>(&'a AtomicU64, &'a Crew);
        impl Drop for Alarm<'_> {
            fn drop(&mut self) {
                if std::thread::panicking() {
                    self.0.store(PANICKED, Ordering::SeqCst);
                    self.1.main.unpark();
                }
            }
        }
        let _alarm = Alarm(&w.done, self);
        let mut last = 0;
        loop {
            let mut go = last;
            wait_park(
                || {
                    go = w.go.load(Ordering::SeqCst);
                    go != last
                },
                &w.parked,
            );
            if go == QUIT {
                return;
            }
            last = go;
            // SAFETY: the caller's thread handed the job over with `go` and waits
            // for `done`.
            let job = unsafe { &mut *w.job.get() };
            let t0 = Instant::now();
            // SAFETY: the job's partition is this worker's alone in this step.
            job.result = unsafe { run_lane(job.lanes, job.part, &job.due, job.now, &mut job.out) };
            job.lane_ns = t0.elapsed().as_nanos() as u64;
            w.done.store(last, Ordering::SeqCst);
            if self.main_parked.load(Ordering::SeqCst) {
                self.main.unpark();
            }
        }
    }
}

impl Worker {
    fn new() -> Worker {
        Worker {
            go: AtomicU64::new(0),
            done: AtomicU64::new(0),
            parked: AtomicBool::new(false),
            job: UnsafeCell::new(Job {
                now: 0,
                part: 0,
                lanes: Lanes::null(),
                due: Vec::new(),
                out: LaneOut::default(),
                result: Ok(()),
                lane_ns: 0,
            }),
        }
    }
}

/// Spins until `ready` holds for up to [`SPIN`], then parks between looks,
/// raising `parked` while it may sleep so that the thread that makes `ready`
/// true knows to unpark it.
fn wait_park(mut ready: impl FnMut() -> bool, parked: &AtomicBool) {
    let t0 = Instant::now();
    let mut spins = 0u32;
    while !ready() {
        spins += 1;
        if !spins.is_multiple_of(64) || t0.elapsed() < SPIN {
            std::hint::spin_loop();
            continue;
        }
        parked.store(true, Ordering::SeqCst);
        if !ready() {
            // Spurious wake-ups are fine: the loop looks again.
            std::thread::park_timeout(Duration::from_millis(50));
        }
        parked.store(false, Ordering::SeqCst);
    }
}

/// The simulator's arrays as the evaluation threads reach them.
#[derive(Clone, Copy)]
pub(super) struct Lanes {
    pub slots: *mut Slot,
    pub n_slots: usize,
    pub net: Net,
    pub local: *const u8,
    /// Every unit's scheduling record: a lane reaches those of its own units only.
    pub sched: *mut Sched,
    /// Every unit's partition (read only while the lanes run).
    pub parts: *const u8,
    /// The calendar of the last lane (the caller's thread): `Sim::cal`.
    pub main_cal: *mut Calendar,
    /// The calendars of worker lanes 1.. (`Sim::lane_cals`, lane k at k - 1).
    pub lane_cals: *mut Calendar,
    /// Lanes in this step (the last is the caller's thread).
    pub lanes: u8,
}

impl Lanes {
    fn null() -> Lanes {
        Lanes {
            slots: std::ptr::null_mut(),
            n_slots: 0,
            net: Net::null(),
            local: std::ptr::null(),
            sched: std::ptr::null_mut(),
            parts: std::ptr::null(),
            main_cal: std::ptr::null_mut(),
            lane_cals: std::ptr::null_mut(),
            lanes: 0,
        }
    }
    /// The calendar lane `part` schedules its units in.
    fn cal(&self, part: u8) -> *mut Calendar {
        if part == self.lanes {
            self.main_cal
        } else {
            // SAFETY: worker lanes are 1..lanes, and `lane_cals` has an entry for each.
            unsafe { self.lane_cals.add(part as usize - 1) }
        }
    }
}

/// Evaluates and commits `due`, units of partition `part`, then takes the clock
/// edge of the links whose both ends are in `part` (the others are left in
/// `out.touched` for the edge after every lane), and schedules the next
/// evaluations of its own units in its calendar (`Lanes::cal`): those its units
/// asked for, and the wake-ups that its pushes and pops sent to them (a wake-up
/// of another partition's unit is left in `out.wakes` for after every lane).
/// SAFETY: no other thread reaches a unit of `part`, its scheduling record, its
/// calendar or a link local to it, and every unit in `due` is in `part`.
pub(super) unsafe fn run_lane(
    l: Lanes,
    part: u8,
    due: &[(u32, bool)],
    t: Time,
    out: &mut LaneOut,
) -> Result<(), SimError> {
    for &(u, d) in due {
        assert!((u as usize) < l.n_slots);
        // SAFETY: in bounds; a unit of `part` (the function's contract).
        let slot = unsafe { &mut *l.slots.add(u as usize) };
        eval_commit_slot(slot, u, t, l.net, out, d, false)?;
    }
    let mut net = l.net;
    let mut k = 0;
    while k < out.touched.len() {
        let i = out.touched[k].0 as usize;
        assert!(i < net.len);
        // SAFETY: in bounds; `local` has an entry per link.
        if unsafe { *l.local.add(i) } != part {
            k += 1;
            continue;
        }
        out.touched.swap_remove(k);
        // SAFETY: both ends of the link are in `part`, evaluated by this thread.
        let link = unsafe { net.link_mut(i) };
        // Listed by both of its ends: edge it once.
        if !link.touched() {
            continue;
        }
        let e = link.edge(&mut out.violations);
        net.set_head(i, e.head);
        net.set_space(i, e.space);
        if e.wake_producer {
            let (p, _) = link.ends();
            out.wakes
                .push((p.expect("elaborated link has a producer"), t + 1));
        }
    }
    // SAFETY: this lane's calendar is its own (the function's contract).
    let cal = unsafe { &mut *l.cal(part) };
    for &(u, n, cycle) in &out.nexts {
        assert!((u as usize) < l.n_slots);
        // SAFETY: in bounds; `u` was evaluated here, so it is in `part`.
        let (s, path) = unsafe {
            (
                &mut *l.sched.add(u as usize),
                &(*l.slots.add(u as usize)).path,
            )
        };
        s.next(cal, u, n, cycle, path);
    }
    out.nexts.clear();
    out.wakes.retain(|&(u, w)| {
        let u = u.0;
        assert!((u as usize) < l.n_slots);
        // SAFETY: in bounds; partitions change only between steps.
        let p = unsafe { *l.parts.add(u as usize) };
        if p != part {
            return true;
        }
        // SAFETY: a unit of `part`, whose record only this lane reaches.
        unsafe { &mut *l.sched.add(u as usize) }.at_time(cal, u, w);
        false
    });
    Ok(())
}

/// Parallel steps between two load-balancing decisions (`Sim::set_lane_plan`).
pub(super) const BALANCE_STEPS: u64 = 4096;

/// How units are spread over the lanes (`Sim::set_lane_plan`).
#[derive(Clone, Debug, Default)]
pub(super) struct LanePlan {
    /// Groups of units that move between lanes together (a TM each), spread in
    /// order and evenly over the lanes.
    pub groups: Vec<Vec<u32>>,
    /// Units of the first lane (a worker's): global units with much work.
    pub first: Vec<u32>,
}

/// Load balancing between neighbouring lanes.
pub(super) struct Balance {
    pub window: u64,
    pub always_move: bool,
    /// Wall time of each lane's partition since the last decision.
    pub lane_ns: Vec<u64>,
    pub steps: u64,
    /// Groups moved so far.
    pub moves: u64,
}

impl Default for Balance {
    fn default() -> Self {
        Balance {
            window: BALANCE_STEPS,
            always_move: false,
            lane_ns: Vec::new(),
            steps: 0,
            moves: 0,
        }
    }
}

/// The automatic lane count: the run measures its own wall time per evaluation
/// over short probes of the current count and of a neighbouring one, and keeps
/// the faster; probes come rarer while the choice stands.
pub(super) struct AutoLanes {
    pub on: bool,
    /// The lane counts it chooses from, ascending (1 first).
    pub candidates: Vec<usize>,
    /// Index into `candidates` of the chosen count.
    pub chosen: usize,
    pub phase: Phase,
    /// The phase's start (in steps and evaluations) and its wall time so far.
    pub phase_steps: u64,
    pub phase_evals: u64,
    pub phase_ns: u64,
    /// Wall time of the current stretch of stepping (`Sim::run_loop`).
    pub since: Option<Instant>,
    /// The chosen count's time per evaluation in its last probe.
    pub base_ns: f64,
    /// Length of the next stretch on the chosen count, in probe lengths.
    pub epoch: u32,
    /// Which neighbour the next probe tries (alternates when there are two).
    pub probe_up: bool,
    /// Tests: switch among the candidates every this many steps instead.
    pub forced_every: Option<u64>,
    /// Decisions that changed the lane count.
    pub switches: u64,
}

/// Where the automatic choice is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Phase {
    /// Running on the chosen count for `epoch` probe lengths.
    Run,
    /// Measuring the chosen count.
    Base,
    /// Measuring candidate `k`.
    Probe(usize),
}

/// A probe lasts this long (and at least `PROBE_STEPS` steps): long enough to
/// average over the scheduler's time slices, short enough that a probe of a
/// much slower lane count costs little.
pub(super) const PROBE: Duration = Duration::from_millis(30);
pub(super) const PROBE_STEPS: u64 = 16;
/// A probe must be this much faster to change the choice (noise margin).
pub(super) const PROBE_MARGIN: f64 = 0.95;
/// Stretches on the chosen count grow from `EPOCH_MIN` to `EPOCH_MAX` probe
/// lengths while the choice stands, so that probing costs a few percent at most
/// when the other count is much slower.
pub(super) const EPOCH_MIN: u32 = 8;
pub(super) const EPOCH_MAX: u32 = 256;

impl AutoLanes {
    pub fn new(on: bool, max: usize) -> AutoLanes {
        // 1, 2, 4, ... up to `max`, and `max` itself.
        let mut candidates = vec![1];
        let mut n = 2;
        while n < max {
            candidates.push(n);
            n *= 2;
        }
        if max > 1 {
            candidates.push(max);
        }
        AutoLanes {
            on: on && max > 1,
            candidates,
            chosen: 0,
            phase: Phase::Base,
            phase_steps: 0,
            phase_evals: 0,
            phase_ns: 0,
            since: None,
            base_ns: 0.0,
            epoch: EPOCH_MIN,
            probe_up: true,
            forced_every: None,
            switches: 0,
        }
    }

    /// The neighbour of the chosen count the next probe tries.
    pub fn neighbour(&mut self) -> usize {
        let (c, n) = (self.chosen, self.candidates.len());
        let up = if c == 0 {
            true
        } else if c + 1 == n {
            false
        } else {
            {
                self.probe_up = !self.probe_up;
                !self.probe_up
            }
        };
        if up { c + 1 } else { c - 1 }
    }
}
