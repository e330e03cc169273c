//! Which lane evaluates each unit: partitions set by hand or by a lane plan,
//! load balancing between neighbouring lanes, the automatic lane count, and the
//! parallel part of a step that hands the worker lanes their due units (the
//! threads themselves are in `lanes`).

use std::time::Instant;

use super::lanes::{self, Crew, LanePlan, Lanes, Phase, run_lane};
use super::network::Net;
use super::{Sim, SimError, Time, UnitId};

impl Sim {
    /// Puts a unit in evaluation partition 0 (the default: evaluated by the
    /// caller's thread after the others) or 1..=N for N = `threads` (evaluated
    /// concurrently with the other lanes; N on the caller's thread). Links may
    /// join any partitions: each end changes only its own half of a link. A lane
    /// plan ([`Sim::set_lane_plan`]) replaces these.
    pub fn set_part(&mut self, u: UnitId, part: u8) -> Result<(), SimError> {
        let max = self.opts.threads.max(2);
        if part as usize > max {
            return Err(SimError::Elaboration(format!(
                "unit '{}' put in partition {part}; with {} thread(s) the partitions are 0 to {max}",
                self.slots[u.0 as usize].path, self.opts.threads
            )));
        }
        self.parts[u.0 as usize] = part;
        self.elaborated = false;
        Ok(())
    }

    /// Spreads the units over the lanes by groups (a TM each, moved between
    /// lanes together by load balancing, in order and evenly spread) and a
    /// list of units for the first lane (a worker's); every other unit goes to
    /// the last lane, the caller's thread. Re-applied whenever the lane count
    /// changes (`SimOptions::auto_lanes`).
    pub fn set_lane_plan(&mut self, groups: Vec<Vec<UnitId>>, first: Vec<UnitId>) {
        self.plan = Some(LanePlan {
            groups: groups
                .into_iter()
                .map(|g| g.into_iter().map(|u| u.0).collect())
                .collect(),
            first: first.into_iter().map(|u| u.0).collect(),
        });
        self.apply_plan();
    }

    /// Partitions from the lane plan for the current lane count.
    fn apply_plan(&mut self) {
        let Some(plan) = &self.plan else { return };
        let l = if self.parallel() { self.lanes } else { 1 };
        if l < 2 {
            self.parts.iter_mut().for_each(|p| *p = 0);
        } else {
            self.parts.iter_mut().for_each(|p| *p = l as u8);
            let n = plan.groups.len().max(1);
            for (k, g) in plan.groups.iter().enumerate() {
                let part = 1 + (k * l / n) as u8;
                for &u in g {
                    self.parts[u as usize] = part;
                }
            }
            for &u in &plan.first {
                self.parts[u as usize] = 1;
            }
        }
        self.balance.lane_ns = vec![0; l.max(1)];
        self.balance.steps = 0;
        if !self.local.is_empty() {
            self.relocal();
        }
    }

    /// Whether a step may evaluate partitions on several threads.
    pub(super) fn parallel(&self) -> bool {
        self.opts.threads >= 2 && self.opts.sleep && !self.opts.shadow
    }

    /// Lanes in use now (1 when the run is on one thread).
    pub fn lanes(&self) -> usize {
        if self.parallel() { self.lanes } else { 1 }
    }

    /// Steps taken so far with each lane count (index: lanes - 1).
    pub fn steps_by_lanes(&self) -> &[u64] {
        &self.steps_by_lanes
    }

    /// Times the automatic lane choice changed the count.
    pub fn lane_switches(&self) -> u64 {
        self.auto.switches
    }

    /// Tests: with `auto_lanes`, switch among the candidate lane counts every
    /// `steps` steps instead of measuring (results must not change).
    pub fn force_lane_switches(&mut self, steps: u64) {
        self.auto.forced_every = Some(steps.max(1));
    }
    /// One step of the automatic lane choice: at the end of a phase, measure
    /// it and go on to the next (see `AutoLanes`).
    pub(super) fn auto_tick(&mut self) {
        let a = &mut self.auto;
        let steps = self.steps - a.phase_steps;
        if let Some(every) = a.forced_every {
            if steps >= every {
                a.phase_steps = self.steps;
                let next = (a.chosen + 1) % a.candidates.len();
                a.chosen = next;
                a.switches += 1;
                self.set_lanes(self.auto.candidates[next]);
            }
            return;
        }
        let Some(t0) = a.since else { return };
        // Phases are measured in wall time (a probe of a much slower lane count
        // must end after its time, not after a number of its slow steps); a
        // look at the clock every 16 steps is free beside the steps.
        if steps < lanes::PROBE_STEPS || !steps.is_multiple_of(16) {
            return;
        }
        let now = Instant::now();
        let ns = a.phase_ns + (now - t0).as_nanos() as u64;
        let min_ns = match a.phase {
            Phase::Run => lanes::PROBE.as_nanos() as u64 * a.epoch as u64,
            _ => lanes::PROBE.as_nanos() as u64,
        };
        if ns < min_ns {
            return;
        }
        let evals = (self.evals - a.phase_evals).max(1);
        let per_eval = ns as f64 / evals as f64;
        let next_lanes = match a.phase {
            Phase::Run => {
                a.phase = Phase::Base;
                None
            }
            Phase::Base => {
                a.base_ns = per_eval;
                let k = a.neighbour();
                a.phase = Phase::Probe(k);
                Some(a.candidates[k])
            }
            Phase::Probe(k) => {
                a.phase = Phase::Run;
                if per_eval < a.base_ns * lanes::PROBE_MARGIN {
                    a.chosen = k;
                    a.epoch = lanes::EPOCH_MIN;
                    a.switches += 1;
                } else {
                    a.epoch = (a.epoch * 2).min(lanes::EPOCH_MAX);
                }
                Some(a.candidates[a.chosen])
            }
        };
        a.phase_steps = self.steps;
        a.phase_evals = self.evals;
        a.phase_ns = 0;
        a.since = Some(now);
        if let Some(l) = next_lanes {
            self.set_lanes(l);
        }
    }

    /// Changes the lane count between steps (with a lane plan).
    fn set_lanes(&mut self, l: usize) {
        if l != self.lanes && self.plan.is_some() {
            self.lanes = l;
            self.apply_plan();
        }
    }

    /// Evaluates and commits the due units of the worker lanes on their
    /// workers and those of the last lane on this thread, at the same time.
    pub(super) fn run_lanes(&mut self, crew: &Crew, t: Time) -> Result<(), SimError> {
        let l = self.lanes;
        let net = Net::of(
            &mut self.links,
            &mut self.heads,
            &mut self.space,
            &mut self.nonempty,
        );
        let lanes = Lanes {
            slots: self.slots.as_mut_ptr(),
            n_slots: self.slots.len(),
            net,
            local: self.local.as_ptr(),
            sched: self.sched.as_mut_ptr(),
            parts: self.parts.as_ptr(),
            main_cal: &mut self.cal,
            lane_cals: self.lane_cals.as_mut_ptr(),
            lanes: l as u8,
        };
        self.lane_seq += 1;
        self.parallel_steps += 1;
        let seq = self.lane_seq;
        // Worker k evaluates lane k + 1.
        let mut started = std::mem::take(&mut self.lane_started);
        started.clear();
        for k in 0..l - 1 {
            if self.lane_due[k].is_empty() {
                continue;
            }
            {
                // SAFETY: the worker is waiting for `go` and does not touch the job.
                let job = unsafe { &mut *crew.workers[k].job.get() };
                job.now = t;
                job.part = (k + 1) as u8;
                job.lanes = lanes;
                std::mem::swap(&mut job.due, &mut self.lane_due[k]);
            }
            crew.start(k, seq);
            started.push(k);
        }
        // From here until every `done`, this thread reaches slots and links only
        // through `lanes`, and only those of the last lane.
        let t0 = Instant::now();
        // SAFETY: the last lane is this thread's; each worker takes its own.
        let mut result =
            unsafe { run_lane(lanes, l as u8, &self.lane_due[l - 1], t, &mut self.out) };
        let main_ns = t0.elapsed().as_nanos() as u64;
        for &k in &started {
            crew.wait(k, seq);
            // SAFETY: the worker is done with this step and waits for the next `go`.
            let job = unsafe { &mut *crew.workers[k].job.get() };
            std::mem::swap(&mut job.due, &mut self.lane_due[k]);
            self.out.append(&mut job.out);
            self.balance.lane_ns[k] += job.lane_ns;
            result = result.and(std::mem::replace(&mut job.result, Ok(())));
        }
        self.lane_started = started;
        self.balance.lane_ns[l - 1] += main_ns;
        self.balance.steps += 1;
        if self.balance.steps >= self.balance.window {
            self.rebalance();
        }
        result
    }

    /// Load balancing every `window` parallel steps (default `BALANCE_STEPS`);
    /// `always_move` moves a group at every decision, from the partition with more
    /// groups, whatever the times (tests: a deterministic exercise of the moves).
    pub fn set_balance(&mut self, window: u64, always_move: bool) {
        self.balance.window = window.max(1);
        self.balance.always_move = always_move;
    }

    /// Groups moved between the partitions so far (see `set_lane_plan`).
    pub fn balance_moves(&self) -> u64 {
        self.balance.moves
    }

    /// Moves one group between two neighbouring lanes: every `BALANCE_STEPS`
    /// parallel steps, the boundary group of the slower lane of the pair whose
    /// times differ most goes to the other, when the gap exceeds a group's
    /// share. Wall-clock driven, and so not reproducible in speed, but results
    /// do not depend on the partition (see `set_part`).
    fn rebalance(&mut self) {
        let l = self.lanes;
        let ns = std::mem::replace(&mut self.balance.lane_ns, vec![0; l]);
        self.balance.steps = 0;
        let Some(plan) = &self.plan else { return };
        if l < 2 {
            return;
        }
        let parts = &self.parts;
        let part_of = |g: &Vec<u32>| g.first().map(|&u| parts[u as usize]);
        let count = |p: u8| plan.groups.iter().filter(|g| part_of(g) == Some(p)).count();
        // Lane k (1-based) against lane k + 1.
        let (from, to) = if self.balance.always_move {
            let k = 1 + (self.balance.moves as usize) % (l - 1);
            let (a, b) = (k as u8, k as u8 + 1);
            if count(a) >= count(b) { (a, b) } else { (b, a) }
        } else {
            let Some(k) = (1..l).max_by_key(|&k| ns[k - 1].abs_diff(ns[k])) else {
                return;
            };
            let (a, b) = (k as u8, k as u8 + 1);
            let (from, to, slow, fast) = if ns[k - 1] > ns[k] {
                (a, b, ns[k - 1], ns[k])
            } else {
                (b, a, ns[k], ns[k - 1])
            };
            // Move when the gap exceeds the cost of one group of the slower side.
            if (slow - fast) as f64 <= slow as f64 / count(from).max(1) as f64 {
                return;
            }
            (from, to)
        };
        if count(from) < 2 {
            return;
        }
        // The group at the boundary between the two lanes (TMs stay contiguous).
        let pick = if from < to {
            plan.groups.iter().rposition(|g| part_of(g) == Some(from))
        } else {
            plan.groups.iter().position(|g| part_of(g) == Some(from))
        };
        let Some(k) = pick else { return };
        for &u in &plan.groups[k].clone() {
            self.parts[u as usize] = to;
        }
        self.balance.moves += 1;
        self.relocal();
    }

    /// Recomputes which partition takes each link's edge.
    pub(super) fn relocal(&mut self) {
        for (i, l) in self.links.iter().enumerate() {
            let (p, c) = l.ends();
            let pp = p.map_or(0, |p| self.parts[p.0 as usize]);
            let cp = c.map_or(0, |c| self.parts[c.0 as usize]);
            self.local[i] = if pp == cp { pp } else { 0 };
        }
    }
}
