//! The chip's counts: what one wavefront (or a sampling window's stretch) did,
//! read from the units' probes as snapshots and differenced.

use crate::energy::ShadeUses;
use crate::mem::StreamTag;
use crate::mem::energy::energy_of;
use crate::mem::stats::ChannelStats;
use crate::units::tp::TpStats;

use super::Chip;

/// The GDDR5 model's figures over one wavefront (all zero with `fixed`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DramWave {
    /// Line reads and writes served by the controllers, per stream tag too.
    pub reads: u64,
    pub writes: u64,
    #[serde(serialize_with = "crate::mem::per_stream")]
    pub tag_reads: [u64; StreamTag::COUNT],
    #[serde(serialize_with = "crate::mem::per_stream")]
    pub tag_writes: [u64; StreamTag::COUNT],
    pub row_hits: u64,
    pub row_misses: u64,
    pub row_conflicts: u64,
    pub acts: u64,
    pub refs: u64,
    /// DRAM energy in joules with the `paper` and `physical` presets
    /// (`mem.energy`, docs/memory.md), background and refresh included.
    pub energy_paper_j: f64,
    pub energy_physical_j: f64,
}

impl DramWave {
    pub fn lines(&self) -> u64 {
        self.reads + self.writes
    }
    pub fn row_hit_rate(&self) -> f64 {
        crate::mem::stats::row_hit_rate(self.row_hits, self.row_misses, self.row_conflicts)
    }
    /// Achieved bandwidth in GB/s over `cycles` core cycles of `core_ps`.
    pub fn bandwidth_gbs(&self, line_bytes: u64, cycles: u64, core_ps: u64) -> f64 {
        let s = cycles as f64 * core_ps as f64 * 1e-12;
        if s == 0.0 {
            0.0
        } else {
            (self.lines() * line_bytes) as f64 / s / 1e9
        }
    }
    pub(super) fn sub(&self, b: &DramWave) -> DramWave {
        let mut d = DramWave {
            reads: self.reads - b.reads,
            writes: self.writes - b.writes,
            row_hits: self.row_hits - b.row_hits,
            row_misses: self.row_misses - b.row_misses,
            row_conflicts: self.row_conflicts - b.row_conflicts,
            acts: self.acts - b.acts,
            refs: self.refs - b.refs,
            energy_paper_j: self.energy_paper_j - b.energy_paper_j,
            energy_physical_j: self.energy_physical_j - b.energy_physical_j,
            ..DramWave::default()
        };
        for k in 0..StreamTag::COUNT {
            d.tag_reads[k] = self.tag_reads[k] - b.tag_reads[k];
            d.tag_writes[k] = self.tag_writes[k] - b.tag_writes[k];
        }
        d
    }
    /// Accumulates another wavefront.
    pub fn add(&mut self, o: &DramWave) {
        self.reads += o.reads;
        self.writes += o.writes;
        self.row_hits += o.row_hits;
        self.row_misses += o.row_misses;
        self.row_conflicts += o.row_conflicts;
        self.acts += o.acts;
        self.refs += o.refs;
        self.energy_paper_j += o.energy_paper_j;
        self.energy_physical_j += o.energy_physical_j;
        for k in 0..StreamTag::COUNT {
            self.tag_reads[k] += o.tag_reads[k];
            self.tag_writes[k] += o.tag_writes[k];
        }
    }
}

/// One traced wavefront's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct WaveCycles {
    /// Cycles from the first emitted ray to the last unit going idle.
    pub cycles: u64,
    pub rays_emitted: u64,
    pub duplicates: u64,
    pub segments_loaded: u64,
    pub box_tests: u64,
    pub tri_tests: u64,
    pub exits: u64,
    pub pops: u64,
    pub tri_hits: u64,
    pub l1_lines: u64,
    pub max_stack: u64,
    pub hits_sent: u64,
    #[serde(serialize_with = "crate::mem::per_stream")]
    pub lines_read: [u64; StreamTag::COUNT],
    #[serde(serialize_with = "crate::mem::per_stream")]
    pub lines_written: [u64; StreamTag::COUNT],
    pub hit_merged: u64,
    pub scene_buffer_stalls: u64,
    pub scene_buffer_stall_cycles: u64,
    pub scene_buffer_reads: u64,
    pub evals: u64,
    pub dram: DramWave,
    /// The shading pass before the wavefront (0 for the primary rays): pixels
    /// shaded, rays emitted (shadow ones too), bounce hits, blocked shadow rays,
    /// and its cycles (from the start to the last item's end marker).
    pub shade_items: u64,
    pub shade_rays: u64,
    pub shade_shadow_rays: u64,
    pub shade_hits: u64,
    pub shade_occluded: u64,
    pub shade_cycles: u64,
    /// Cycles from the last finished work (the last end marker of a ray or a
    /// shading item taken by the scheduler) to the run's end (every unit idle):
    /// the pass's drain (hit record writes, retirement, answers in flight),
    /// without the end-of-run L2 flush (`l2.flush_cycles`).
    pub drain_cycles: u64,
    /// Actions of the TPs' shading states, for the energy model.
    pub shade_uses: ShadeUses,
    /// The L2 (zero without): client accesses, hits, misses (merges included),
    /// misses merged into a live MSHR, bank-conflict stall cycles, lines filled
    /// and dirty lines written back (the end-of-run flush included).
    pub l2: L2Wave,
    /// Distribution balance: the most and fewest rays one TM got in this run,
    /// and how many TMs got any (the mean is `rays_traced / tms`).
    pub tm_rays_max: u64,
    pub tm_rays_min: u64,
    pub tms_with_rays: u64,
}

/// The L2's counters over one run.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct L2Wave {
    pub accesses: u64,
    pub hits: u64,
    pub misses: u64,
    pub merges: u64,
    pub bank_conflicts: u64,
    pub fills: u64,
    pub writebacks: u64,
    /// Cycles of the end-of-run flush (part of the run's cycles).
    pub flush_cycles: u64,
    /// Reads served by a bank already reading their line (`chip.l2.combine_reads`):
    /// accesses, but no array read of their own.
    pub combined: u64,
}

impl L2Wave {
    pub fn hit_rate(&self) -> f64 {
        if self.accesses == 0 {
            0.0
        } else {
            self.hits as f64 / self.accesses as f64
        }
    }
    /// Data-array accesses (client accesses but combined reads, fills,
    /// writebacks), for the energy.
    pub fn array_accesses(&self) -> u64 {
        self.accesses - self.combined + self.fills + self.writebacks
    }
    pub(super) fn sub(&self, b: &L2Wave) -> L2Wave {
        L2Wave {
            accesses: self.accesses - b.accesses,
            hits: self.hits - b.hits,
            misses: self.misses - b.misses,
            merges: self.merges - b.merges,
            bank_conflicts: self.bank_conflicts - b.bank_conflicts,
            fills: self.fills - b.fills,
            writebacks: self.writebacks - b.writebacks,
            flush_cycles: self.flush_cycles - b.flush_cycles,
            combined: self.combined - b.combined,
        }
    }
    pub fn add(&mut self, o: &L2Wave) {
        self.accesses += o.accesses;
        self.hits += o.hits;
        self.misses += o.misses;
        self.merges += o.merges;
        self.bank_conflicts += o.bank_conflicts;
        self.fills += o.fills;
        self.writebacks += o.writebacks;
        self.flush_cycles += o.flush_cycles;
        self.combined += o.combined;
    }
}

impl WaveCycles {
    /// The counts between two snapshots of one run (`self` the later).
    pub(super) fn since(&self, b: &WaveCycles) -> WaveCycles {
        let d = |a: u64, b: u64| a - b;
        WaveCycles {
            cycles: d(self.cycles, b.cycles),
            rays_emitted: 0,
            duplicates: d(self.duplicates, b.duplicates),
            segments_loaded: d(self.segments_loaded, b.segments_loaded),
            box_tests: d(self.box_tests, b.box_tests),
            tri_tests: d(self.tri_tests, b.tri_tests),
            exits: d(self.exits, b.exits),
            pops: d(self.pops, b.pops),
            tri_hits: d(self.tri_hits, b.tri_hits),
            l1_lines: d(self.l1_lines, b.l1_lines),
            max_stack: 0,
            hits_sent: d(self.hits_sent, b.hits_sent),
            lines_read: std::array::from_fn(|k| d(self.lines_read[k], b.lines_read[k])),
            lines_written: std::array::from_fn(|k| d(self.lines_written[k], b.lines_written[k])),
            hit_merged: d(self.hit_merged, b.hit_merged),
            scene_buffer_stalls: d(self.scene_buffer_stalls, b.scene_buffer_stalls),
            scene_buffer_stall_cycles: d(
                self.scene_buffer_stall_cycles,
                b.scene_buffer_stall_cycles,
            ),
            scene_buffer_reads: d(self.scene_buffer_reads, b.scene_buffer_reads),
            evals: d(self.evals, b.evals),
            dram: self.dram.sub(&b.dram),
            shade_items: d(self.shade_items, b.shade_items),
            shade_rays: d(self.shade_rays, b.shade_rays),
            shade_shadow_rays: d(self.shade_shadow_rays, b.shade_shadow_rays),
            shade_hits: d(self.shade_hits, b.shade_hits),
            shade_occluded: d(self.shade_occluded, b.shade_occluded),
            shade_cycles: 0,
            drain_cycles: 0,
            shade_uses: self.shade_uses.since(&b.shade_uses),
            l2: self.l2.sub(&b.l2),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        }
    }

    /// Rays handed to the TMs in this run (duplicates included).
    pub fn rays_traced(&self) -> u64 {
        self.rays_emitted + self.duplicates
    }
    /// Most rays on one TM over the mean per TM (1 = perfectly balanced; 0 when
    /// no ray was traced).
    pub fn tm_imbalance(&self, tms: u64) -> f64 {
        let n = self.rays_traced();
        if n == 0 || tms == 0 {
            0.0
        } else {
            self.tm_rays_max as f64 * tms as f64 / n as f64
        }
    }
}

impl Chip {
    /// Every TP's counters added up, in one pass over the TPs: a snapshot needs
    /// a dozen of them, and looking each up by name would build every TP's
    /// counter list a dozen times (docs/results/2026-11-27-kernel-internal-states-run-through-and-the-l2-under-a-miss-storm.md).
    fn tp_totals(&self) -> TpStats {
        let mut t = TpStats::default();
        for u in self.tps() {
            t.add(self.tp(u).probe());
        }
        t
    }

    /// The controllers' statistics up to now, all channels merged.
    pub fn dram_stats(&self) -> Option<ChannelStats> {
        let d = self.dram.as_ref()?;
        let end = self.sim.cycle(d.clock);
        let mut t = ChannelStats::default();
        for &u in &d.ctrls {
            t.merge(&self.ctrl(u).stats_at(end));
        }
        Some(t)
    }

    /// Timing-checker violations on every channel's command log so far (needs
    /// `chip.memory.check_timing`; empty otherwise and with `fixed`).
    pub fn dram_violations(&self) -> Vec<String> {
        let Some(d) = self.dram.as_ref() else {
            return Vec::new();
        };
        let end = self.sim.cycle(d.clock);
        let mut v = Vec::new();
        for (k, &u) in d.ctrls.iter().enumerate() {
            let log = self.ctrl(u).commands_until(end);
            for x in crate::mem::checker::check(&log, &d.cfg.timing, &d.cfg.geometry, end) {
                v.push(format!("channel {k}: {x}"));
            }
        }
        v
    }

    fn dram_snapshot(&self) -> DramWave {
        let (Some(d), Some(t)) = (self.dram.as_ref(), self.dram_stats()) else {
            return DramWave::default();
        };
        let mut w = DramWave {
            reads: t.reads,
            writes: t.writes,
            row_hits: t.row_hits,
            row_misses: t.row_misses,
            row_conflicts: t.row_conflicts,
            acts: t.acts,
            refs: t.refs,
            energy_paper_j: energy_of(&t, &d.paper).total(),
            energy_physical_j: energy_of(&t, &d.physical).total(),
            ..DramWave::default()
        };
        for k in 0..StreamTag::COUNT {
            w.tag_reads[k] = t.per_tag[k].reads;
            w.tag_writes[k] = t.per_tag[k].writes;
        }
        w
    }

    pub(super) fn snapshot(&self) -> WaveCycles {
        let s = &self.sim;
        let mem = self.memory_unit().probe();
        let sb = self.scene_buffer_unit().probe();
        let sched = self.sched().probe();
        let hru = self.hit_updater_unit().probe();
        let tp = self.tp_totals();
        WaveCycles {
            cycles: s.cycle(self.clock),
            rays_emitted: 0,
            duplicates: sched.stats.enqueues,
            segments_loaded: sched.stats.segments_loaded,
            box_tests: tp.box_tests,
            tri_tests: tp.tri_tests,
            exits: tp.exits,
            pops: tp.uses_of("pop"),
            tri_hits: tp.tri_hits,
            l1_lines: tp.l1_loads,
            max_stack: 0,
            hits_sent: tp.hits,
            lines_read: mem.lines_read,
            lines_written: mem.lines_written,
            hit_merged: hru.merged,
            scene_buffer_stalls: sb.stalls,
            scene_buffer_stall_cycles: sb.stall_cycles,
            scene_buffer_reads: sb.reads,
            evals: s.evals,
            dram: self.dram_snapshot(),
            shade_items: tp.shade_items,
            shade_rays: tp.shade_rays,
            shade_shadow_rays: tp.shade_shadow_rays,
            shade_hits: tp.shade_hits,
            shade_occluded: tp.shade_occluded,
            // The cycle the last shading pass ended (see `run_wave`).
            shade_cycles: sched.last_shade_end,
            drain_cycles: 0,
            shade_uses: ShadeUses::of(|n| tp.uses_of(n)),
            l2: self.l2_unit().map_or(L2Wave::default(), |u| {
                let st = u.probe().stats;
                L2Wave {
                    accesses: st.accesses,
                    hits: st.hits,
                    misses: st.misses,
                    merges: st.merges,
                    bank_conflicts: st.bank_conflicts,
                    fills: st.fills,
                    writebacks: st.writebacks,
                    flush_cycles: self.flush_cycles,
                    combined: st.combined,
                }
            }),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        }
    }

    pub(super) fn sched_tm_rays(&self) -> Vec<u64> {
        self.sched().tm_rays().to_vec()
    }
}

impl WaveCycles {
    /// A wavefront's figures from the snapshots `before` and `after` its run:
    /// `rays` emitted by the host, a shading pass over `shade_pixels` first (0:
    /// none), the last end marker at cycle `last_marker`. The distribution over
    /// the TMs and the deepest stack are added by `Chip::add_distribution`.
    pub(super) fn of_wave(
        before: &WaveCycles,
        after: &WaveCycles,
        rays: u64,
        shade_pixels: u32,
        last_marker: u64,
    ) -> WaveCycles {
        let mut w = WaveCycles {
            cycles: after.cycles - before.cycles,
            rays_emitted: rays + after.shade_rays - before.shade_rays,
            duplicates: after.duplicates
                - before.duplicates
                - rays
                - (after.shade_rays - before.shade_rays),
            shade_items: after.shade_items - before.shade_items,
            shade_rays: after.shade_rays - before.shade_rays,
            shade_shadow_rays: after.shade_shadow_rays - before.shade_shadow_rays,
            shade_hits: after.shade_hits - before.shade_hits,
            shade_occluded: after.shade_occluded - before.shade_occluded,
            shade_uses: after.shade_uses.since(&before.shade_uses),
            shade_cycles: if shade_pixels > 0 {
                after.shade_cycles - before.cycles
            } else {
                0
            },
            segments_loaded: after.segments_loaded - before.segments_loaded,
            box_tests: after.box_tests - before.box_tests,
            tri_tests: after.tri_tests - before.tri_tests,
            exits: after.exits - before.exits,
            pops: after.pops - before.pops,
            tri_hits: after.tri_hits - before.tri_hits,
            l1_lines: after.l1_lines - before.l1_lines,
            max_stack: 0,
            hits_sent: after.hits_sent - before.hits_sent,
            lines_read: [0; StreamTag::COUNT],
            lines_written: [0; StreamTag::COUNT],
            hit_merged: after.hit_merged - before.hit_merged,
            scene_buffer_stalls: after.scene_buffer_stalls - before.scene_buffer_stalls,
            scene_buffer_stall_cycles: after.scene_buffer_stall_cycles
                - before.scene_buffer_stall_cycles,
            scene_buffer_reads: after.scene_buffer_reads - before.scene_buffer_reads,
            evals: after.evals - before.evals,
            dram: after.dram.sub(&before.dram),
            l2: after.l2.sub(&before.l2),
            // The end-of-run L2 flush is not the pass draining: it is counted
            // apart (`l2.flush_cycles`).
            drain_cycles: after.cycles
                - (after.l2.flush_cycles - before.l2.flush_cycles)
                - last_marker.max(before.cycles),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        };
        for k in 0..StreamTag::COUNT {
            w.lines_read[k] = after.lines_read[k] - before.lines_read[k];
            w.lines_written[k] = after.lines_written[k] - before.lines_written[k];
        }
        w
    }
}

impl Chip {
    /// The wavefront's distribution over the TMs (`tm_before`: the scheduler's
    /// rays per TM at its start) and the deepest TP stack so far, into `w`.
    pub(super) fn add_distribution(&self, w: &mut WaveCycles, tm_before: &[u64]) {
        let per_tm: Vec<u64> = self
            .sched_tm_rays()
            .iter()
            .zip(tm_before)
            .map(|(a, b)| a - b)
            .collect();
        w.tm_rays_max = per_tm.iter().copied().max().unwrap_or(0);
        w.tm_rays_min = per_tm.iter().copied().min().unwrap_or(0);
        w.tms_with_rays = per_tm.iter().filter(|&&r| r > 0).count() as u64;
        w.max_stack = self
            .tps()
            .map(|u| self.tp(u).probe().max_stack)
            .max()
            .unwrap_or(0);
    }
}
