//! What the rest of the crate reads of a simulator between runs: the time, the
//! units and their statistics, evaluations by unit kind, link statistics and
//! transfer logs, and the VCD tracer that samples registers during a run.

use super::{Clock, ClockId, NO_CHECK, Sim, SimError, Time, UnitId};
use crate::rtl::decl::UnitDecl;
use crate::rtl::link::{LinkEvent, LinkId, LinkStats};
use crate::rtl::trace::{CapUnit, CaptureFile, CaptureSpec, TraceError, TraceStats, Tracer};
use crate::rtl::unit::{self, Unit};

/// Evaluations of the units of one kind (see [`Sim::evals_by_module`]).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ModuleEvals {
    pub module: &'static str,
    pub units: usize,
    pub evals: u64,
}

/// Statistics of one unit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitStats {
    pub path: String,
    pub module: &'static str,
    /// Cycles (of the unit's clock) spent in each [`Status`](unit::Status), indexed
    /// by its value.
    pub status_cycles: [u64; 4],
    pub counters: Vec<(&'static str, u64)>,
}

impl Sim {
    pub fn now(&self) -> Time {
        self.now
    }

    /// Current cycle of a clock.
    pub fn cycle(&self, clock: ClockId) -> u64 {
        self.now / self.clocks[clock.0 as usize].period_ps
    }

    /// Evaluations so far by unit kind (Verilog module name): units of the kind
    /// and their evaluations, most evaluated first (ties by name). Where a
    /// simulation's time goes: an evaluation costs about the same whatever the
    /// unit (docs/kernel.md).
    pub fn evals_by_module(&self) -> Vec<ModuleEvals> {
        let mut m: std::collections::BTreeMap<&'static str, ModuleEvals> = Default::default();
        for s in &self.slots {
            let module = s.unit.decl().module;
            let e = m.entry(module).or_insert(ModuleEvals {
                module,
                units: 0,
                evals: 0,
            });
            e.units += 1;
            e.evals += s.evals;
        }
        let mut v: Vec<ModuleEvals> = m.into_values().collect();
        v.sort_by(|a, b| b.evals.cmp(&a.evals).then(a.module.cmp(b.module)));
        v
    }

    pub fn unit_count(&self) -> usize {
        self.slots.len()
    }

    pub fn unit_path(&self, u: UnitId) -> &str {
        &self.slots[u.0 as usize].path
    }

    pub fn unit_id(&self, path: &str) -> Option<UnitId> {
        self.slots
            .iter()
            .position(|s| s.path == path)
            .map(|i| UnitId(i as u32))
    }

    pub fn unit(&self, u: UnitId) -> &dyn Unit {
        &*self.slots[u.0 as usize].unit
    }

    /// Typed access to a unit between steps (testbenches). Wake it after changing it.
    pub fn unit_mut<U: Unit>(&mut self, u: UnitId) -> &mut U {
        let slot = &mut self.slots[u.0 as usize];
        slot.commit_all = true;
        unit::downcast_mut::<U>(&mut *slot.unit).expect("unit type matches")
    }

    pub fn unit_ref<U: Unit>(&self, u: UnitId) -> &U {
        unit::downcast_ref::<U>(&*self.slots[u.0 as usize].unit).expect("unit type matches")
    }

    pub fn unit_clock(&self, u: UnitId) -> ClockId {
        self.slots[u.0 as usize].clock
    }

    /// Status cycles integrated up to now, and the unit's counters.
    pub fn unit_stats(&self, u: UnitId) -> UnitStats {
        let s = &self.slots[u.0 as usize];
        let mut ps = s.status_ps;
        match s.ahead {
            // A status from the next cycle on, not begun yet.
            Some(a) if self.now < s.since => ps[a as usize] -= s.since - self.now,
            _ => ps[s.status as usize] += self.now - s.since,
        }
        UnitStats {
            path: s.path.clone(),
            module: s.unit.decl().module,
            status_cycles: ps.map(|x| x / s.period),
            counters: s.unit.counters(),
        }
    }

    pub fn all_stats(&self) -> Vec<UnitStats> {
        (0..self.slots.len())
            .map(|i| self.unit_stats(UnitId(i as u32)))
            .collect()
    }

    pub fn link_stats(&self) -> Vec<(String, LinkStats)> {
        self.links
            .iter()
            .map(|l| (l.name().to_string(), l.stats()))
            .collect()
    }

    /// A link's configured depth and delay (its producer's cycles), as the
    /// netlists' `ds_link` instances take them.
    pub fn link_cfg(&self, id: LinkId) -> crate::rtl::LinkCfg {
        self.links[id.0 as usize].cfg()
    }

    /// How many links the netlist has.
    pub fn link_count(&self) -> usize {
        self.links.len()
    }

    pub fn link_occupancy(&self, id: LinkId) -> u32 {
        self.links[id.0 as usize].occupancy()
    }

    /// Turns on the transfer log of a link (testbenches check latencies with it).
    pub fn log_link(&mut self, id: LinkId, on: bool) {
        self.links[id.0 as usize].set_log(on);
    }

    pub fn link_log(&self, id: LinkId) -> &[LinkEvent] {
        self.links[id.0 as usize].log()
    }

    /// Attaches a VCD tracer (see [`crate::rtl::trace`]).
    pub fn attach_tracer(&mut self, mut tracer: Tracer) -> Result<(), SimError> {
        self.bind_tracer(&mut tracer)?;
        self.tracer = Some(tracer);
        Ok(())
    }

    /// Captures vectors (docs/rtl.md, "Vectors") of the units whose instance
    /// paths match `spec.filter`: one file per unit, written when the run's
    /// trace finishes ([`Sim::finish_trace`]). Capturing changes no result.
    pub fn attach_capture(&mut self, spec: &CaptureSpec) -> Result<(), SimError> {
        self.elaborate()?;
        let pick = crate::rtl::TraceSpec {
            filter: spec.filter.clone(),
            ..crate::rtl::TraceSpec::all()
        };
        let units: Vec<CapUnit> = self
            .slots
            .iter()
            .filter(|s| pick.matches(&s.path))
            .map(|s| {
                let c = &self.clocks[s.clock.0 as usize];
                CapUnit {
                    path: s.path.clone(),
                    decl: s.unit.decl(),
                    clock: c.name.clone(),
                    period: c.period_ps,
                }
            })
            .collect();
        if units.is_empty() {
            return Err(SimError::TraceBind(TraceError::NoUnit {
                filter: spec.filter.clone(),
                units: self.slots.iter().map(|s| s.path.clone()).collect(),
            }));
        }
        if let Some(to) = spec.to
            && to < spec.from
        {
            return Err(SimError::TraceBind(TraceError::Window {
                from: spec.from,
                to,
            }));
        }
        let mut t =
            Tracer::capture(spec, units, self.captured.clone()).map_err(SimError::TraceBind)?;
        self.bind_tracer(&mut t)?;
        self.capture = Some(t);
        Ok(())
    }

    /// The vector files the last finished capture wrote.
    pub fn captured(&self) -> Vec<CaptureFile> {
        self.captured.lock().expect("not poisoned").clone()
    }

    fn bind_tracer(&mut self, tracer: &mut Tracer) -> Result<(), SimError> {
        self.elaborate()?;
        let units: Vec<(&str, &dyn Unit, &Clock)> = self
            .slots
            .iter()
            .map(|s| (s.path.as_str(), &*s.unit, &self.clocks[s.clock.0 as usize]))
            .collect();
        if let Err(e) = tracer.bind(&units, &self.links, &self.clocks) {
            tracer.discard();
            return Err(SimError::TraceBind(e));
        }
        if let Err(e) = tracer.check_estimate() {
            tracer.discard();
            return Err(SimError::Trace(e));
        }
        self.watch(tracer);
        Ok(())
    }

    /// Marks what a tracer samples: its units' registers and readiness, its
    /// links' last payloads.
    fn watch(&mut self, tracer: &Tracer) {
        let (from, to) = tracer.window();
        for i in tracer.unit_indices() {
            let s = &mut self.slots[i];
            s.watched = true;
            if s.check_ready == NO_CHECK {
                s.check_ready = (from, to);
            }
        }
        for l in tracer.traced_links() {
            self.links[l.0 as usize].set_keep_last(true);
        }
    }

    /// Named markers (time, name) for the waveform's save file, written when
    /// the trace finishes (no tracer: nothing).
    pub fn set_trace_markers(&mut self, markers: Vec<(Time, String)>) {
        if let Some(t) = &mut self.tracer {
            t.set_markers(markers);
        }
    }

    /// Detaches the tracer and the capture, flushing their output: the
    /// waveform's counts (`None`: no waveform), or the first error of
    /// either. The capture's files are then [`Sim::captured`].
    pub fn finish_trace(&mut self) -> Option<std::io::Result<TraceStats>> {
        let now = self.now;
        let check = if self.opts.check_ready {
            (0, Time::MAX)
        } else {
            NO_CHECK
        };
        for s in &mut self.slots {
            s.watched = false;
            s.check_ready = check;
        }
        for l in &mut self.links {
            l.set_keep_last(false);
        }
        let cap = self.capture.take().map(|t| t.finish(now));
        let wave = self.tracer.take().map(|t| t.finish(now));
        match cap {
            Some(Err(e)) => Some(Err(e)),
            _ => wave,
        }
    }

    /// Every unit's declaration with its instance path (for hdl emission and reports).
    pub fn decls(&self) -> Vec<(String, UnitDecl)> {
        self.slots
            .iter()
            .map(|s| (s.path.clone(), s.unit.decl()))
            .collect()
    }
}
