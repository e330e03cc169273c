//! The controller's FR-FCFS decision: which command may issue in a cycle (or
//! the earliest cycle one may), by refresh, per bank, or by the plain scan.

use super::{ChannelCtrl, Choice};

impl ChannelCtrl {
    /// The command to issue in cycle `c`, or the earliest cycle one may become legal.
    pub(super) fn pick(&self, c: u64) -> Result<Choice, u64> {
        if self.refresh_pending {
            return self.pick_refresh(c);
        }
        if self.resp.len() >= self.resp_cap {
            return self.pick_scan(c);
        }
        let r = self.pick_banks(c);
        #[cfg(debug_assertions)]
        {
            let want = self.pick_scan(c);
            debug_assert_eq!(
                r, want,
                "scheduler per-bank path vs plain scan at cycle {c}"
            );
        }
        r
    }

    /// FR-FCFS over the banks that hold requests of the served queue (the
    /// response buffer has room): the oldest row hit whose column command is legal
    /// goes first, else the oldest request whose ACT (closed bank) or PRE (open
    /// bank that no queued request hits) is legal. Within a bank the oldest hit and
    /// the oldest request are the only candidates, so this equals the plain scan.
    fn pick_banks(&self, c: u64) -> Result<Choice, u64> {
        let t = &self.timing;
        let writes = self.serving_writes();
        let q = writes as usize;
        let base = q * self.nbanks as usize;
        let act_floor = t.act_floor();
        let mut wake = u64::MAX;
        // (seq, slot) of the best column command and of the best ACT/PRE.
        let mut col = (u64::MAX, 0usize);
        let mut other = (u64::MAX, Choice::Ref);
        let mut m = self.nonempty[q];
        while m != 0 {
            let b = m.trailing_zeros();
            m &= m - 1;
            let list = &self.bank_q[base + b as usize];
            match t.open_row(b) {
                Some(open) if self.hits[base + b as usize] > 0 => {
                    let x = t.earliest_col(b, writes);
                    if x > c {
                        wake = wake.min(x);
                        continue;
                    }
                    let s = list
                        .iter()
                        .map(|&s| s as usize)
                        .find(|&s| self.slots[s].row == open)
                        .expect("counted hit");
                    let seq = self.slots[s].seq;
                    if seq < col.0 {
                        col = (seq, s);
                    }
                }
                open => {
                    let (x, ch) = match open {
                        None => (t.earliest_act_after(b, act_floor), Choice::Act(0)),
                        Some(_) => (t.earliest_pre(b), Choice::Pre(0)),
                    };
                    if x > c {
                        wake = wake.min(x);
                        continue;
                    }
                    let s = list[0] as usize;
                    let seq = self.slots[s].seq;
                    if seq < other.0 {
                        other = (
                            seq,
                            match ch {
                                Choice::Act(_) => Choice::Act(s),
                                _ => Choice::Pre(s),
                            },
                        );
                    }
                }
            }
        }
        if col.0 != u64::MAX {
            Ok(Choice::Col(col.1))
        } else if other.0 != u64::MAX {
            Ok(other.1)
        } else {
            Err(wake)
        }
    }

    /// A refresh is due: precharge every open bank, then REF.
    fn pick_refresh(&self, c: u64) -> Result<Choice, u64> {
        let t = &self.timing;
        let mut wake = u64::MAX;
        if t.open_banks() == 0 {
            let e = t.earliest_ref();
            return if e <= c { Ok(Choice::Ref) } else { Err(e) };
        }
        for b in 0..self.nbanks {
            if t.open_row(b).is_some() {
                let e = t.earliest_pre(b);
                if e <= c {
                    return Ok(Choice::PreForRefresh(b));
                }
                wake = wake.min(e);
            }
        }
        Err(wake)
    }

    /// The plain FR-FCFS scan over every request of the served queue in age
    /// order: the reference `pick_banks` must agree with (checked in debug
    /// builds), and the decision while the response buffer is full.
    fn pick_scan(&self, c: u64) -> Result<Choice, u64> {
        let t = &self.timing;
        let mut wake = u64::MAX;
        let writes = self.serving_writes();
        let q = &self.order[writes as usize];
        // Per bank, once: its open row and when its next command may go (the
        // column command if open, else ACT). The PRE time is asked only for a
        // conflict.
        let nb = self.nbanks as usize;
        let mut open = [u32::MAX; 64];
        let mut ready = [0u64; 64];
        for b in 0..nb {
            match t.open_row(b as u32) {
                Some(r) => {
                    open[b] = r;
                    ready[b] = t.earliest_col(b as u32, writes);
                }
                None => ready[b] = t.earliest_act(b as u32),
            }
        }
        // Banks whose open row some request of the served queue still hits.
        let mut hit_banks = 0u64;
        for &s in q {
            let e = &self.slots[s as usize];
            if open[e.bank as usize] == e.row {
                hit_banks |= 1 << e.bank;
            }
        }
        let resp_full = self.resp.len() >= self.resp_cap;
        let mut other: Option<Choice> = None;
        for &s in q {
            let (i, e) = (s as usize, &self.slots[s as usize]);
            let b = e.bank as usize;
            if open[b] == e.row {
                if resp_full && e.bursts_done + 1 == self.bursts_per_line {
                    continue; // woken by the next pop_response
                }
                if ready[b] <= c {
                    return Ok(Choice::Col(i));
                }
                wake = wake.min(ready[b]);
            } else if other.is_some() {
                continue;
            } else if open[b] == u32::MAX {
                if ready[b] <= c {
                    other = Some(Choice::Act(i));
                } else {
                    wake = wake.min(ready[b]);
                }
            } else if hit_banks & (1 << b) == 0 {
                let x = t.earliest_pre(b as u32);
                if x <= c {
                    other = Some(Choice::Pre(i));
                } else {
                    wake = wake.min(x);
                }
            }
        }
        other.ok_or(wake)
    }
}
