//! Following rays through the chip (`render --follow-ray`): arms the units
//! that see a ray (stream scheduler, each TM's staging buffer and TPs, the hit
//! record updater) with a probe of one shared log (`units/follow.rs`).

use crate::units::follow::FollowLog;
use crate::units::hit_record_updater::HitRecordUpdater;
use crate::units::staging_buffer::StagingBuffer;

use super::Chip;

impl Chip {
    /// Follows the rays `targets` ((wavefront, ray id): chip run k traces
    /// wavefront k) from the next run on; returns the log. Changes no result.
    pub fn follow(&mut self, targets: Vec<(u32, u32)>) -> FollowLog {
        let log = FollowLog::new(targets);
        let probe = |c: &Chip, u: crate::rtl::UnitId| log.follower(u.0, c.sim.unit_path(u));
        let f = probe(self, self.scheduler);
        self.sched_mut().follow(f);
        let f = probe(self, self.hit_updater);
        self.sim
            .unit_mut::<HitRecordUpdater>(self.hit_updater)
            .follow(f);
        for k in 0..self.tms.len() {
            let sb = self.tms[k].staging_buffer;
            let f = probe(self, sb);
            self.sim.unit_mut::<StagingBuffer>(sb).follow(f);
            for j in 0..self.tms[k].tps.len() {
                let tp = self.tms[k].tps[j];
                let f = probe(self, tp);
                self.tp_mut(tp).follow(f);
            }
        }
        self.follow = Some(log.clone());
        log
    }
}
