//! Distribution to the TMs (paper §4.1): each waiting ray bucket (or, when
//! none waits, a bucket's worth of shading items) goes to the free TM (no bucket
//! in progress) with the fewest outstanding rays, ties broken round-robin from
//! `next_tm`; its rays go into the TM's staging buffer one per cycle.

use crate::contract::RayRec;
use crate::rtl::Ctx;

use super::super::follow::FollowKind;
use super::super::staging_buffer::{SbFill, SbHeader};
use super::super::tp_shade::SHADE_SEG;
use super::StreamScheduler;

impl StreamScheduler {
    /// The free TM (no bucket in progress) with the fewest outstanding rays,
    /// the first from `next_tm` on a tie.
    fn pick_tm(&self) -> Option<usize> {
        let s = self.st.r();
        let n = s.tms.len();
        let mut best: Option<(u32, usize)> = None;
        for j in 0..n {
            let k = (s.next_tm as usize + j) % n;
            let t = &s.tms[k];
            if t.cur.is_none() && best.is_none_or(|(o, _)| t.outstanding < o) {
                best = Some((t.outstanding, k));
            }
        }
        best.map(|(_, k)| k)
    }

    /// Hands each waiting ray bucket, else a bucket's worth of shading items,
    /// to a free TM.
    pub(super) fn hand_out(&mut self, c: u64) -> bool {
        let n = self.tms_n as usize;
        let mut worked = false;
        loop {
            let shade_left = self.st.r().shade.as_ref().is_some_and(|p| p.next < p.end);
            if self.st.r().ready.is_empty() && !shade_left {
                break;
            }
            let Some(k) = self.pick_tm() else { break };
            let st = self.st.m();
            st.next_tm = ((k + 1) % n) as u32;
            if st.ready.is_empty() {
                // Shading items (pixels, a bucket's worth at a time).
                let rpb = self.rays_per_bucket;
                let p = st.shade.as_mut().expect("shading");
                let m = rpb.min(p.end - p.next);
                let items = (p.next..p.next + m)
                    .map(|pix| RayRec {
                        origin: glam::Vec3::ZERO,
                        dir: glam::Vec3::ZERO,
                        ray_id: pix,
                        entry: 0,
                    })
                    .collect();
                p.next += m;
                p.out += m as u64;
                self.stats.shade_items += m as u64;
                st.tms[k].outstanding += m;
                st.tms[k].cur = Some((SHADE_SEG, items, 0));
            } else {
                // A bucket of the segment the TM had last (L1 reuse, §4.1), else
                // the oldest.
                let last = st.tms[k].last_seg;
                let pick = last
                    .and_then(|s| st.ready.iter().position(|(rs, _)| *rs == s))
                    .inspect(|_| self.stats.same_segment_picks += 1)
                    .unwrap_or(0);
                let (seg, rays) = st.ready.remove(pick).expect("picked");
                let w = st.ws.iter_mut().find(|w| w.seg == seg).expect("ws");
                w.rays_fwd += rays.len() as u64;
                self.stats.buckets_forwarded += 1;
                self.tm_rays[k] += rays.len() as u64;
                st.tms[k].outstanding += rays.len() as u32;
                if let Some(f) = &mut self.follow {
                    for r in &rays {
                        if f.wants(r.ray_id) {
                            let tm = k as u32;
                            f.log(c, r.ray_id, FollowKind::HandedOut { seg, tm });
                        }
                    }
                }
                st.tms[k].cur = Some((seg, rays, 0));
                st.tms[k].last_seg = Some(seg);
            }
            worked = true;
        }
        worked
    }

    /// Pushes each TM's next ray (or shading item) into its staging buffer.
    pub(super) fn fill_staging_buffers(&mut self, ctx: &mut Ctx) -> bool {
        let n = self.tms_n as usize;
        let mut worked = false;
        for k in 0..n {
            let shade_item = self.st.r().tms[k]
                .cur
                .as_ref()
                .is_some_and(|c| c.0 == SHADE_SEG);
            if shade_item && ctx.can_push(&self.fill.at(k)) {
                let st = self.st.m();
                let hdr = SbHeader {
                    seg: SHADE_SEG,
                    base: 0,
                    nodes: 0,
                };
                let (_, items, pos) = st.tms[k].cur.as_mut().expect("cur");
                let last = *pos + 1 == items.len();
                let ray = items[*pos];
                *pos += 1;
                if last {
                    st.tms[k].cur = None;
                }
                ctx.push(&self.fill.at(k), SbFill { ray, hdr, last });
                worked = true;
            } else if self.st.r().tms[k].cur.is_some() && ctx.can_push(&self.fill.at(k)) {
                let st = self.st.m();
                let seg = st.tms[k].cur.as_ref().expect("cur").0;
                let w = st.ws.iter_mut().find(|w| w.seg == seg).expect("ws");
                let hdr = SbHeader {
                    seg,
                    base: w.entry.base,
                    nodes: w.entry.nodes,
                };
                let (_, rays, pos) = st.tms[k].cur.as_mut().expect("cur");
                let last = *pos + 1 == rays.len();
                let ray = rays[*pos];
                *pos += 1;
                if last {
                    st.tms[k].cur = None;
                    w.buckets_on_chip -= 1;
                }
                if let Some(f) = &mut self.follow
                    && f.wants(ray.ray_id)
                {
                    let (seg, tm) = (hdr.seg, k as u32);
                    f.log(ctx.cycle(), ray.ray_id, FollowKind::Filled { seg, tm });
                }
                ctx.push(&self.fill.at(k), SbFill { ray, hdr, last });
                self.stats.rays_forwarded += 1;
                worked = true;
            }
        }
        worked
    }
}
