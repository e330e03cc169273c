//! What the chip reports when a run goes wrong: the units holding work, the
//! cause of a stuck chip, and the end-of-wavefront drain check.

use super::{Chip, ChipError};

impl Chip {
    /// Units holding work, and what they wait for (the watchdog's report).
    pub fn holding(&self) -> Vec<String> {
        let mut v = Vec::new();
        let sch = self.sched();
        if !sch.idle() {
            v.push(format!("chip.scheduler: {}", sch.holding()));
        }
        if self.scene_buffer_unit().busy() {
            v.push("chip.scene_buffer: L1 misses wait for lines not streamed in, or responses in flight".into());
        }
        let h = self.hit_updater_unit();
        if h.busy() {
            let p = h.probe();
            v.push(format!(
                "chip.hit_updater: {} queued, {} read-compare-writes in flight",
                p.queued, p.in_flight
            ));
        }
        if let Some(l2) = self.l2_unit()
            && l2.busy()
        {
            let p = l2.probe();
            v.push(format!(
                "chip.l2: {} MSHRs live, {} memory requests queued, {} at the memory",
                p.live_mshrs, p.mem_queued, p.at_memory
            ));
        }
        let m = self.memory_unit().probe();
        if m.in_flight > 0 {
            v.push(format!("chip.memory: {} requests in flight", m.in_flight));
        }
        for (k, t) in self.tms.iter().enumerate() {
            let busy = t.tps.iter().filter(|&&u| self.tp(u).holds_work()).count();
            if busy > 0 {
                v.push(format!("chip.tm{k}: {busy} TPs hold a ray"));
            }
        }
        v
    }

    /// The error of a stuck chip: the overflowed stack when a TP's did (the
    /// cause), else `kind` of `why` and the units holding work.
    pub(super) fn stuck(&self, why: &str, kind: fn(String) -> ChipError) -> ChipError {
        // A TP whose stack overflowed stops for good; the chip then starves.
        // That is the cause to report, not the starvation.
        let overflowed: Vec<String> = self
            .tms
            .iter()
            .enumerate()
            .flat_map(|(k, t)| {
                t.tps
                    .iter()
                    .enumerate()
                    .filter(|&(_, &u)| self.tp(u).overflowed())
                    .map(move |(j, _)| format!("chip.tm{k}.tp{j}"))
            })
            .collect();
        if let Some(first) = overflowed.first() {
            let (pad, entry) = self.stack_cfg;
            let need = match self.stack_need {
                Some(n) => format!(
                    "; this scene's segments can need up to {n} entries: tm.scratchpad_bytes = {} holds them",
                    n * entry
                ),
                None => String::new(),
            };
            return ChipError::StackOverflow(format!(
                "the traversal stack of {first} overflowed at cycle {} ({} TPs overflowed): \
                 tm.scratchpad_bytes = {pad} holds {} entries of tm.stack_entry_bytes = {entry}; \
                 raise tm.scratchpad_bytes{need}",
                self.sim.cycle(self.clock),
                overflowed.len(),
                pad / entry.max(1),
            ));
        }
        let mut msg = format!(
            "the chip is stuck at cycle {}: {why}",
            self.sim.cycle(self.clock)
        );
        let sch = self.sched();
        if sch.dest_blocked() {
            msg.push_str(&format!(
                "; the destination table is full (chip.scheduler.dest_entries = {}): raise it",
                sch.dest_entries()
            ));
        }
        msg.push_str("; units holding work:");
        for h in self.holding() {
            msg.push_str("\n  ");
            msg.push_str(&h);
        }
        kind(msg)
    }

    /// Nothing is lost: asserted after every wavefront.
    pub(super) fn check_drained(&self) -> Result<(), ChipError> {
        let s = &self.sim;
        let sch = self.sched();
        let held = self.holding();
        if !held.is_empty() {
            return Err(self.stuck(
                "every unit sleeps but work is left (a deadlock)",
                ChipError::Deadlock,
            ));
        }
        for seg in 0..self.segments {
            let (enq, done) = (sch.enqueued_by_segment()[seg], sch.done_by_segment()[seg]);
            if enq != done {
                return Err(ChipError::Lost(format!(
                    "segment {seg}: {enq} rays enqueued but {done} processed in this wavefront"
                )));
            }
        }
        if sch.live_buckets() != 0 {
            return Err(ChipError::Lost(format!(
                "{} ray buckets were not freed at the end of the wavefront",
                sch.live_buckets()
            )));
        }
        let m = self.memory_unit().probe();
        if m.requests != m.responses {
            return Err(ChipError::Lost("a memory request was not answered".into()));
        }
        for (i, (name, _)) in s.link_stats().into_iter().enumerate() {
            if s.link_occupancy(crate::rtl::LinkId(i as u32)) > 0 {
                return Err(ChipError::Lost(format!(
                    "link '{name}' still holds data at the end of the wavefront"
                )));
            }
        }
        Ok(())
    }

    /// With `chip.memory.check_timing`: the channels' command logs obey the
    /// DRAM timing (checked after every wavefront).
    pub(super) fn check_dram_timing(&self) -> Result<(), ChipError> {
        if self.dram.as_ref().is_some_and(|d| d.check) {
            let v = self.dram_violations();
            if !v.is_empty() {
                return Err(ChipError::DramTiming(format!(
                    "{} DRAM timing violations (chip.memory.check_timing), first: {}",
                    v.len(),
                    v[0]
                )));
            }
        }
        Ok(())
    }
}
