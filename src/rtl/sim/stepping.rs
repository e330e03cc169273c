//! Running: the step loop up to a time limit or until idle, and one step (the
//! due units evaluated, each committed as it goes, or all before the edge when a
//! tracer samples them; then the edge of every link they touched and the next
//! wake-ups put in the calendar).

use std::time::Instant;

use super::context::{eval_commit_slot, eval_slot};
use super::lanes::Crew;
use super::network::Net;
use super::{ClockId, RunEnd, Sim, SimError, Time};
use crate::rtl::trace::Activity;
use crate::rtl::trace::TraceError;

impl Sim {
    /// Runs until time `limit` (ps), which becomes the current time even if every
    /// unit went to sleep before (so statistics do not depend on which edges
    /// happened to be processed). Returns `Idle` if nothing is scheduled any more.
    pub fn run(&mut self, limit: Time) -> Result<RunEnd, SimError> {
        self.run_inner(limit, false)
    }

    fn run_inner(&mut self, limit: Time, stop_when_idle: bool) -> Result<RunEnd, SimError> {
        self.elaborate()?;
        if let Some(spec) = self.opts.capture.take() {
            self.attach_capture(&spec)?;
        }
        if !self.parallel() || self.tracer.is_some() || self.capture.is_some() {
            return self.run_loop(limit, stop_when_idle, None);
        }
        let crew = Crew::new(self.opts.threads - 1);
        self.lane_seq = 0;
        std::thread::scope(|s| {
            let crew = &crew;
            let handles: Vec<_> = (0..crew.workers.len())
                .map(|k| s.spawn(move || crew.worker_loop(k)).thread().clone())
                .collect();
            crew.threads
                .set(handles)
                .expect("a run's workers are spawned once");
            // Ends the workers however the loop ends: a panic on this thread
            // would otherwise leave the scope waiting for them forever.
            struct Quit<'c>(&'c Crew);
            impl Drop for Quit<'_> {
                fn drop(&mut self) {
                    self.0.quit();
                }
            }
            let _quit = Quit(crew);
            self.run_loop(limit, stop_when_idle, Some(crew))
        })
    }

    fn run_loop(
        &mut self,
        limit: Time,
        stop_when_idle: bool,
        crew: Option<&Crew>,
    ) -> Result<RunEnd, SimError> {
        if self.auto.on && crew.is_some() {
            self.auto.since = Some(Instant::now());
        }
        let r = self.run_steps(limit, stop_when_idle, crew);
        if let Some(t0) = self.auto.since.take() {
            self.auto.phase_ns += t0.elapsed().as_nanos() as u64;
        }
        r
    }

    fn run_steps(
        &mut self,
        limit: Time,
        stop_when_idle: bool,
        crew: Option<&Crew>,
    ) -> Result<RunEnd, SimError> {
        loop {
            match self.next_time() {
                None => {
                    if !stop_when_idle && limit > self.now {
                        self.now = limit;
                        self.stepped = false;
                    }
                    return Ok(RunEnd::Idle);
                }
                Some(t) if t > limit => {
                    if limit > self.now {
                        self.now = limit;
                        self.stepped = false;
                    }
                    return Ok(RunEnd::Limit);
                }
                Some(t) => {
                    self.step_at(t, crew)?;
                    if crew.is_some() {
                        self.steps_by_lanes[self.lanes - 1] += 1;
                        if self.auto.on {
                            self.auto_tick();
                        }
                    }
                }
            }
        }
    }

    /// Runs `n` cycles of `clock` from now.
    pub fn run_cycles(&mut self, clock: ClockId, n: u64) -> Result<RunEnd, SimError> {
        let p = self.clocks[clock.0 as usize].period_ps;
        let limit = (self.now / p + n) * p;
        self.run(limit)
    }

    /// Runs until every unit sleeps with nothing scheduled or until `limit`,
    /// whichever comes first (a run cut into pieces gives the same result).
    pub fn run_until(&mut self, limit: Time) -> Result<RunEnd, SimError> {
        self.run_inner(limit, true)
    }

    /// Runs until idle, failing if that takes longer than `limit` ps.
    pub fn run_to_idle(&mut self, limit: Time) -> Result<Time, SimError> {
        match self.run_inner(limit, true)? {
            RunEnd::Idle => Ok(self.now),
            RunEnd::Limit => Err(SimError::Busy { limit }),
        }
    }

    fn step_at(&mut self, t: Time, crew: Option<&Crew>) -> Result<(), SimError> {
        self.now = t;
        self.stepped = true;
        self.steps += 1;
        // Units that are due (scheduled for t).
        self.due.clear();
        self.cal.take(t, &mut self.taken);
        for c in &mut self.lane_cals {
            c.take(t, &mut self.taken);
        }
        for &u in &self.taken {
            let e = &mut self.last_eval[u as usize];
            if *e != t {
                *e = t;
                self.due.push((u, true));
            }
        }
        self.taken.clear();
        // Sleep off: every unit whose clock has an edge now, due or not.
        if !self.opts.sleep {
            for (i, s) in self.sched.iter().enumerate() {
                if t.is_multiple_of(s.edge.period) && self.last_eval[i] != t {
                    self.due.push((i as u32, false));
                }
            }
        }
        if let Some(rng) = &mut self.rng {
            rng.shuffle(&mut self.due);
        }
        let mut due = std::mem::take(&mut self.due);
        if let Some(crew) = crew
            && self.lanes >= 2
        {
            // Partitions 1..=lanes on their threads, each unit committed by its
            // thread right after its evaluation (see `eval_commit`); partition 0
            // after, below.
            let parts = &self.parts;
            let lane_due = &mut self.lane_due[..self.lanes];
            lane_due.iter_mut().for_each(Vec::clear);
            due.retain(|&(u, d)| match parts[u as usize] {
                0 => true,
                p => {
                    lane_due[p as usize - 1].push((u, d));
                    false
                }
            });
            let busy = lane_due.iter().filter(|l| !l.is_empty()).count();
            if busy >= 2 {
                self.run_lanes(crew, t)?;
            } else {
                // Only one partition has work: no hand-over.
                let mut l = std::mem::take(&mut self.lane_due);
                for &(u, d) in l[..self.lanes].iter().flatten() {
                    self.eval_commit(u, d)?;
                }
                std::mem::swap(&mut l, &mut self.lane_due);
            }
        }
        if self.tracer.is_some() || self.capture.is_some() {
            for &(u, is_due) in &due {
                self.eval_unit(u, is_due)?;
            }
            // The waveform samples every register before the edge.
            let slots = &self.slots;
            for tr in self.tracer.iter_mut().chain(&mut self.capture) {
                let activity = Activity {
                    due: &due,
                    touched: &self.out.touched,
                    heads: &self.heads,
                };
                let unit_at = |i: usize| {
                    let s = &slots[i];
                    let pre = (s.ready_at == t).then_some(&s.ready_pre[..]);
                    (&*s.unit, pre)
                };
                tr.sample(t, &unit_at, &self.links, activity);
                if let Some(why) = tr.stopped() {
                    return Err(SimError::Trace(TraceError::Oversized(why.to_string())));
                }
            }
            // Clock edge.
            for &(u, _) in &due {
                self.slots[u as usize].unit.commit();
            }
        } else {
            for &(u, is_due) in &due {
                self.eval_commit(u, is_due)?;
            }
        }
        self.due = due;
        self.evals += std::mem::take(&mut self.out.evals);
        let mut violations = std::mem::take(&mut self.out.violations);
        for &l in &self.out.touched {
            // Producer and consumer each list a link they touched: edge it once.
            if self.edged[l.0 as usize] == t {
                continue;
            }
            self.edged[l.0 as usize] = t;
            let link = &mut self.links[l.0 as usize];
            debug_assert!(link.touched());
            let e = link.edge(&mut violations);
            self.heads[l.0 as usize] = e.head;
            self.nonempty[l.0 as usize] = (e.head != Time::MAX) as u8;
            self.space[l.0 as usize] = e.space;
            if e.wake_producer {
                let (p, _) = link.ends();
                let p = p.expect("elaborated link has a producer");
                self.out.wakes.push((p, t + 1));
            }
        }
        self.out.touched.clear();
        if !violations.is_empty() {
            return Err(SimError::Protocol(violations));
        }
        for &(u, n, cycle) in &self.out.nexts {
            let path = &self.slots[u as usize].path;
            self.sched[u as usize].next(&mut self.cal, u, n, cycle, path);
        }
        self.out.nexts.clear();
        for (u, w) in self.out.wakes.drain(..) {
            self.sched[u.0 as usize].at_time(&mut self.cal, u.0, w);
        }
        Ok(())
    }

    /// Evaluates a unit and commits it at once: no unit reads another's registers,
    /// so that is the clock edge's result, reached while the unit's state is still
    /// in the cache. Only a tracer, which samples every register before the edge,
    /// needs the edge as a separate phase.
    fn eval_commit(&mut self, u: u32, is_due: bool) -> Result<(), SimError> {
        let (net, shadow) = self.net_for(is_due);
        let slot = &mut self.slots[u as usize];
        eval_commit_slot(slot, u, self.now, net, &mut self.out, is_due, shadow)
    }

    fn eval_unit(&mut self, u: u32, is_due: bool) -> Result<(), SimError> {
        let (net, shadow) = self.net_for(is_due);
        let slot = &mut self.slots[u as usize];
        eval_slot(slot, u, self.now, net, &mut self.out, is_due, shadow)
    }

    /// The links as an evaluation on the caller's thread sees them, and whether
    /// a unit evaluated while not due is checked as a shadow.
    fn net_for(&mut self, is_due: bool) -> (Net, bool) {
        let net = Net::of(
            &mut self.links,
            &mut self.heads,
            &mut self.space,
            &mut self.nonempty,
        );
        (net, !is_due && self.opts.shadow)
    }
}
