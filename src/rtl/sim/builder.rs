//! Building a netlist: clock domains, links and unit instances, then
//! elaboration (every link bound to exactly one producer and one consumer, the
//! netlist checked) and the synchronous reset that starts every run.

use super::scheduling::{EdgeOf, Sched};
use super::{Clock, ClockId, LaneOut, NO_CHECK, Sim, SimError, Slot, Time, UnitId};
use crate::rtl::bits::Payload;
use crate::rtl::decl::PortDir;
use crate::rtl::link::{In, Link, LinkCfg, LinkId, Out};
use crate::rtl::unit::{Status, Unit};

impl Sim {
    /// Adds a clock domain. Its edges are at every multiple of `period_ps`.
    pub fn clock(&mut self, name: &str, period_ps: Time) -> Result<ClockId, SimError> {
        if period_ps == 0 {
            return Err(SimError::Elaboration(format!(
                "clock '{name}' has period 0 ps; give a positive period"
            )));
        }
        self.cal.add_domain(period_ps);
        for c in &mut self.lane_cals {
            c.add_domain(period_ps);
        }
        self.clocks.push(Clock {
            name: name.into(),
            period_ps,
        });
        Ok(ClockId(self.clocks.len() as u16 - 1))
    }

    pub fn clocks(&self) -> &[Clock] {
        &self.clocks
    }

    /// Creates a link; hand its ends to the producer and the consumer.
    pub fn link<T: Payload>(&mut self, name: &str, cfg: LinkCfg) -> (Out<T>, In<T>) {
        let id = LinkId(self.links.len() as u32);
        self.links
            .push(Box::new(Link::<T>::new(name.to_string(), cfg)));
        self.heads.push(Time::MAX);
        self.space.push(true);
        self.nonempty.push(0);
        self.edged.push(Time::MAX);
        self.elaborated = false;
        (Out::new(id), In::new(id))
    }

    /// `n` links named `name(k)`, made one after the other: the producer and the
    /// consumer side of an array port, whose consecutive links let an arbiter
    /// read the non-empty flags of all its inputs at once (`Ctx::visible_mask`).
    pub fn links<T: Payload>(
        &mut self,
        n: usize,
        name: impl Fn(usize) -> String,
        cfg: LinkCfg,
    ) -> (Vec<Out<T>>, Vec<In<T>>) {
        (0..n).map(|k| self.link::<T>(&name(k), cfg)).unzip()
    }

    /// Adds a unit instance under a hierarchical path such as `chip.tm3.box_pipe`.
    pub fn add<U: Unit>(&mut self, path: &str, clock: ClockId, mut unit: U) -> UnitId {
        let period = self.clocks[clock.0 as usize].period_ps;
        unit.number_state();
        self.slots.push(Slot {
            unit: Box::new(unit),
            path: path.to_string(),
            clock,
            period,
            status: Status::WaitInput,
            since: 0,
            status_ps: [0; 4],
            evals: 0,
            out_links: Vec::new(),
            in_links: Vec::new(),
            check_ready: if self.opts.check_ready {
                (0, Time::MAX)
            } else {
                NO_CHECK
            },
            ready_pre: Vec::new(),
            ready_at: Time::MAX,
            popped: Vec::new(),
            stalled_outs: Vec::new(),
            commit_all: true,
            ahead: None,
            watched: false,
        });
        self.sched.push(Sched {
            edge: EdgeOf::new(period),
            last_wake: Time::MAX,
            clock: clock.0,
        });
        self.parts.push(0);
        self.last_eval.push(Time::MAX);
        self.elaborated = false;
        UnitId(self.slots.len() as u32 - 1)
    }

    /// Binds every link to its producer and consumer and checks the netlist.
    pub fn elaborate(&mut self) -> Result<(), SimError> {
        if self.elaborated {
            return Ok(());
        }
        let mut seen = std::collections::HashSet::new();
        for s in &self.slots {
            if !seen.insert(s.path.clone()) {
                return Err(SimError::Elaboration(format!(
                    "two units are named '{}'; instance paths must be unique",
                    s.path
                )));
            }
        }
        let mut ends: Vec<(Option<UnitId>, Option<UnitId>)> = vec![(None, None); self.links.len()];
        for (i, s) in self.slots.iter_mut().enumerate() {
            s.out_links.clear();
            s.in_links.clear();
            for p in s.unit.ports() {
                let e = &mut ends[p.link.0 as usize];
                let lname = self.links[p.link.0 as usize].name().to_string();
                let (slot, role) = match p.dir {
                    PortDir::Out => (&mut e.0, "producer"),
                    PortDir::In => (&mut e.1, "consumer"),
                };
                if let Some(other) = slot {
                    return Err(SimError::Elaboration(format!(
                        "link '{lname}' has two {role}s ('{}' and unit #{}); a link connects exactly one producer to one consumer",
                        s.path, other.0
                    )));
                }
                *slot = Some(UnitId(i as u32));
                match p.dir {
                    PortDir::Out => s.out_links.push(p.link),
                    PortDir::In => s.in_links.push(p.link),
                }
            }
        }
        for (l, (p, c)) in self.links.iter_mut().zip(&ends) {
            l.cfg()
                .validate(&format!("link '{}'", l.name()))
                .map_err(|e| SimError::Elaboration(e.to_string()))?;
            let (Some(p), Some(_)) = (p, c) else {
                return Err(SimError::Elaboration(format!(
                    "link '{}' has no {}; connect it to a unit (a testbench driver or sink if nothing else)",
                    l.name(),
                    if p.is_none() { "producer" } else { "consumer" }
                )));
            };
            l.set_ends(Some(*p), *c);
            l.set_delay_ps(l.cfg().delay as Time * self.slots[p.0 as usize].period);
        }
        self.local = vec![0; self.links.len()];
        self.relocal();
        // A lane's time per balancing window (the plan's partitions or `set_part`'s).
        self.balance.lane_ns = vec![0; self.lanes];
        self.elaborated = true;
        self.reset();
        Ok(())
    }

    /// Synchronous reset: every register to its reset value, links empty, time 0,
    /// every unit evaluated at time 0.
    pub fn reset(&mut self) {
        self.now = 0;
        self.stepped = false;
        self.cal.clear();
        for c in &mut self.lane_cals {
            c.clear();
        }
        self.evals = 0;
        self.steps = 0;
        self.parallel_steps = 0;
        for l in &mut self.links {
            l.reset();
        }
        self.heads.iter_mut().for_each(|h| *h = Time::MAX);
        self.nonempty.iter_mut().for_each(|b| *b = 0);
        self.edged.iter_mut().for_each(|h| *h = Time::MAX);
        for (s, l) in self.space.iter_mut().zip(&self.links) {
            *s = l.has_space();
        }
        self.out = LaneOut::default();
        for (i, s) in self.slots.iter_mut().enumerate() {
            s.unit.reset();
            s.status = Status::WaitInput;
            s.ahead = None;
            s.since = 0;
            s.status_ps = [0; 4];
            s.evals = 0;
            s.stalled_outs.clear();
            let sc = &mut self.sched[i];
            sc.last_wake = 0;
            self.last_eval[i] = Time::MAX;
            self.cal.push(sc.clock as usize, i as u32, 0);
        }
    }
}
