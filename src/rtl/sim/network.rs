//! The links as flat arrays that the evaluation threads share: every link, its
//! head visibility time, whether it can take a push and whether it holds an
//! entry. Each array element is written by one end of its link only, which is
//! what lets two lanes reach the same array at once (the `unsafe` here says how).

use std::any::Any;

use super::Time;
use crate::rtl::bits::Payload;
use crate::rtl::link::{Link, LinkDyn, LinkId};

/// The netlist's shared arrays as raw pointers, so that the two evaluation threads
/// (see [`SimOptions::threads`](super::SimOptions::threads)) can each reach the links of their own partition
/// while the other does the same: elaboration checks that no link joins units of
/// two different partitions, so no element is ever reached from both threads.
#[derive(Clone, Copy)]
pub(super) struct Net {
    links: *mut Box<dyn LinkDyn>,
    heads: *mut Time,
    space: *mut bool,
    /// One byte per link: whether its FIFO holds an entry (`heads` is not
    /// `Time::MAX`), written with `heads`. A byte, not a bit: links of one word
    /// may have consumers on both threads, and a bit would need an atomic
    /// read-modify-write, a fence in this memory-bound loop
    /// (docs/results/2026-11-25-kernel-where-a-cycle-goes-and-two-small-gains.md).
    nonempty: *mut u8,
    pub(super) len: usize,
}

impl Net {
    pub(super) fn null() -> Net {
        Net {
            links: std::ptr::null_mut::<Box<dyn LinkDyn>>(),
            heads: std::ptr::null_mut(),
            space: std::ptr::null_mut(),
            nonempty: std::ptr::null_mut(),
            len: 0,
        }
    }
    pub(super) fn of(
        links: &mut [Box<dyn LinkDyn>],
        heads: &mut [Time],
        space: &mut [bool],
        nonempty: &mut [u8],
    ) -> Net {
        assert!(
            links.len() == heads.len()
                && links.len() == space.len()
                && links.len() == nonempty.len()
        );
        Net {
            links: links.as_mut_ptr(),
            heads: heads.as_mut_ptr(),
            space: space.as_mut_ptr(),
            nonempty: nonempty.as_mut_ptr(),
            len: links.len(),
        }
    }
    /// Links `first..first + n` (n <= 64) that hold an entry, as a bit mask.
    #[inline]
    pub(super) fn nonempty_bits(&self, first: usize, n: usize) -> u64 {
        assert!(n <= 64 && first + n <= self.len);
        // SAFETY: in bounds (checked above); the caller passes the links of one port
        // array of the unit being evaluated, so this thread is their only writer.
        let bytes = unsafe { std::slice::from_raw_parts(self.nonempty.add(first), n) };
        let words = n / 8;
        let mut b = 0u64;
        for w in 0..words {
            // Eight 0/1 bytes to eight bits in one multiply: byte i lands on bit
            // 56 + i and every other product on a distinct lower or dropped bit, in
            // place of a load, shift and or per port (docs/results/2026-11-26-kernel-the-paper-frame-s-profile-and-what-did-not-help.md).
            // SAFETY: bytes `8w..8w + 8` of `bytes` (in bounds: `w < n / 8`), read
            // unaligned; one plain load, as `chunks_exact` and `try_into` cost
            // instructions here (docs/results/2026-11-27-kernel-internal-states-run-through-and-the-l2-under-a-miss-storm.md).
            let x =
                u64::from_le(unsafe { bytes.as_ptr().add(8 * w).cast::<u64>().read_unaligned() });
            b |= (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * w);
        }
        for (k, &v) in bytes.iter().enumerate().skip(8 * words) {
            b |= ((v != 0) as u64) << k;
        }
        b
    }
    /// A shared reference to link `i`: each end changes only its own half of a
    /// link (`Link::cons`, `Link::prod`), so producer and consumer may be on two
    /// threads. The lifetime is the evaluation's (the caller's to respect).
    #[inline]
    pub(super) fn link_ref<'x>(&self, i: usize) -> &'x dyn LinkDyn {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); the array outlives every evaluation (it is
        // the simulator's and is not resized after elaboration), and no `&mut` to a
        // link exists while units are evaluated (only the edge takes one, on one
        // thread, after every evaluation of the step).
        unsafe { &**self.links.add(i) }
    }
    /// Link `i` for its clock edge.
    /// SAFETY: the caller's thread evaluates both ends of the link and no other
    /// reference to it is alive.
    #[inline]
    pub(super) unsafe fn link_mut<'x>(&self, i: usize) -> &'x mut dyn LinkDyn {
        assert!(i < self.len);
        // SAFETY: in bounds; exclusive by the function's contract.
        unsafe { &mut **self.links.add(i) }
    }
    #[inline]
    pub(super) fn typed<'x, T: Payload>(&self, id: LinkId) -> &'x Link<T> {
        let l: &'x dyn LinkDyn = self.link_ref(id.0 as usize);
        (l as &dyn Any)
            .downcast_ref::<Link<T>>()
            .expect("link payload type matches its handle")
    }
    #[inline]
    pub(super) fn head(&self, i: usize) -> Time {
        assert!(i < self.len);
        // SAFETY: in bounds; read by the consumer, the only writer during a step.
        unsafe { *self.heads.add(i) }
    }
    #[inline]
    pub(super) fn space(&self, i: usize) -> bool {
        assert!(i < self.len);
        // SAFETY: in bounds; read by the producer, the only writer during a step.
        unsafe { *self.space.add(i) }
    }
    /// Only the link's producer writes its `space` during a step.
    #[inline]
    pub(super) fn set_space(&mut self, i: usize, space: bool) {
        assert!(i < self.len);
        // SAFETY: in bounds; one element, written only by the producer's thread.
        unsafe { *self.space.add(i) = space }
    }
    /// Only the link's consumer writes its `head` during a step.
    #[inline]
    pub(super) fn set_head(&mut self, i: usize, head: Time) {
        assert!(i < self.len);
        // SAFETY: in bounds; one element, written only by the consumer's thread.
        unsafe {
            *self.heads.add(i) = head;
            *self.nonempty.add(i) = (head != Time::MAX) as u8;
        }
    }
}
