//! The simulated DRAM image: sparse, as a page table. Nothing is sized to the
//! capacity; a 64 KB page is allocated when first written. Unwritten bytes read 0.
//!
//! Pages are shared copy-on-write, so `clone` is a snapshot that costs the page
//! table alone: a time-sampling window runs the chip on a snapshot of the
//! functional model's image (on a worker thread, while the functional model goes
//! on), and a page is copied only when one side writes it.

use std::sync::Arc;

const PAGE_BITS: u32 = 16;
const PAGE: usize = 1 << PAGE_BITS;

/// The page of address `a` and its offset in it.
#[inline(always)]
fn locate(a: u64) -> (usize, usize) {
    ((a >> PAGE_BITS) as usize, (a as usize) & (PAGE - 1))
}

#[derive(Clone)]
pub struct SparseMem {
    capacity: u64,
    /// `None`: never written, reads 0.
    pages: Vec<Option<Arc<[u8]>>>,
    allocated: usize,
}

impl SparseMem {
    /// A memory of `capacity` bytes (addresses beyond it are a modelling error).
    pub fn new(capacity: u64) -> Self {
        let n = capacity.div_ceil(PAGE as u64) as usize;
        SparseMem {
            capacity,
            pages: vec![None; n],
            allocated: 0,
        }
    }

    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Bytes of the pages this image has written (a page shared with a snapshot
    /// counts in both).
    pub fn resident_bytes(&self) -> u64 {
        (self.allocated * PAGE) as u64
    }

    #[inline]
    fn check(&self, a: u64, len: usize) {
        assert!(
            a + len as u64 <= self.capacity,
            "DRAM access at {a:#x}+{len} beyond the capacity {:#x}",
            self.capacity
        );
    }

    /// The page and offset of an access of `len` bytes at `a` that lies within
    /// one page and the capacity (the fast path of `read` and `write`); `None`
    /// sends it the slow way. The page index is checked too: an empty access at
    /// the capacity's end is on no page.
    #[inline(always)]
    fn within_page(&self, a: u64, len: usize) -> Option<(usize, usize)> {
        let (p, off) = locate(a);
        (off + len <= PAGE && a + len as u64 <= self.capacity && p < self.pages.len())
            .then_some((p, off))
    }

    /// Reads `out.len()` bytes at `a`. An access within one page (nearly every
    /// one: records are aligned to their size) takes the inlined fast path; the
    /// functional model makes hundreds of millions of them a frame.
    #[inline]
    pub fn read(&self, a: u64, out: &mut [u8]) {
        if let Some((p, off)) = self.within_page(a, out.len()) {
            match &self.pages[p] {
                Some(pg) => out.copy_from_slice(&pg[off..off + out.len()]),
                None => out.fill(0),
            }
            return;
        }
        self.read_pages(a, out);
    }

    /// `read` across pages (and the capacity check's panic).
    #[cold]
    fn read_pages(&self, a: u64, out: &mut [u8]) {
        self.check(a, out.len());
        let mut done = 0;
        while done < out.len() {
            let addr = a + done as u64;
            let (p, off) = locate(addr);
            let n = (PAGE - off).min(out.len() - done);
            match &self.pages[p] {
                Some(pg) => out[done..done + n].copy_from_slice(&pg[off..off + n]),
                None => out[done..done + n].fill(0),
            }
            done += n;
        }
    }

    /// Writes `data` at `a`; the same fast path as `read`.
    #[inline]
    pub fn write(&mut self, a: u64, data: &[u8]) {
        if let Some((p, off)) = self.within_page(a, data.len()) {
            let pg = self.page_mut(p);
            pg[off..off + data.len()].copy_from_slice(data);
            return;
        }
        self.write_pages(a, data);
    }

    /// Page `p`, allocated if never written, copied if a snapshot shares it.
    #[inline]
    fn page_mut(&mut self, p: usize) -> &mut [u8] {
        let pg = self.pages[p].get_or_insert_with(|| {
            self.allocated += 1;
            Arc::from(vec![0u8; PAGE])
        });
        Arc::make_mut(pg)
    }

    /// `write` across pages (and the capacity check's panic).
    #[cold]
    fn write_pages(&mut self, a: u64, data: &[u8]) {
        self.check(a, data.len());
        let mut done = 0;
        while done < data.len() {
            let addr = a + done as u64;
            let (p, off) = locate(addr);
            let n = (PAGE - off).min(data.len() - done);
            let pg = self.page_mut(p);
            pg[off..off + n].copy_from_slice(&data[done..done + n]);
            done += n;
        }
    }

    #[inline]
    pub fn read_u32(&self, a: u64) -> u32 {
        let mut b = [0u8; 4];
        self.read(a, &mut b);
        u32::from_le_bytes(b)
    }
    #[inline]
    pub fn write_u32(&mut self, a: u64, v: u32) {
        self.write(a, &v.to_le_bytes());
    }
    #[inline]
    pub fn read_u64(&self, a: u64) -> u64 {
        let mut b = [0u8; 8];
        self.read(a, &mut b);
        u64::from_le_bytes(b)
    }
    #[inline]
    pub fn write_u64(&mut self, a: u64, v: u64) {
        self.write(a, &v.to_le_bytes());
    }
    #[inline]
    pub fn read_f32(&self, a: u64) -> f32 {
        f32::from_bits(self.read_u32(a))
    }
    #[inline]
    pub fn write_f32(&mut self, a: u64, v: f32) {
        self.write_u32(a, v.to_bits());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sparse_pages_and_page_crossing() {
        let mut m = SparseMem::new(4 << 30);
        assert_eq!(m.resident_bytes(), 0);
        assert_eq!(m.read_u32(123_456_789), 0);
        m.write_u64((1 << 16) - 4, 0x0102_0304_0506_0708);
        assert_eq!(m.read_u64((1 << 16) - 4), 0x0102_0304_0506_0708);
        assert_eq!(m.resident_bytes(), 2 << 16, "two pages touched");
        m.write_f32(3 << 30, -2.5);
        assert_eq!(m.read_f32(3 << 30), -2.5);
    }

    #[test]
    fn a_snapshot_is_isolated_both_ways() {
        let mut m = SparseMem::new(1 << 30);
        m.write_u64(100, 7);
        let mut snap = m.clone();
        snap.write_u64(100, 8);
        snap.write_u32(5 << 20, 1);
        assert_eq!(
            m.read_u64(100),
            7,
            "the snapshot's write stays in the snapshot"
        );
        assert_eq!(m.read_u32(5 << 20), 0);
        assert_eq!(m.resident_bytes(), 1 << 16);
        assert_eq!(snap.resident_bytes(), 2 << 16);
        m.write_u64(108, 9);
        assert_eq!(
            snap.read_u64(108),
            0,
            "the original's write stays out of it"
        );
        assert_eq!((snap.read_u64(100), m.read_u64(100)), (8, 7));
        drop(snap);
        m.write_u64(100, 10);
        assert_eq!(m.read_u64(100), 10);
    }

    #[test]
    fn empty_access_at_the_end_is_fine() {
        // The capacity a whole number of pages: an empty access at its end is
        // within it, and on no page.
        let mut m = SparseMem::new(1 << 17);
        m.write(1 << 17, &[]);
        m.read(1 << 17, &mut []);
        m.write((1 << 17) - 4, &[1, 2, 3, 4]);
        assert_eq!(m.read_u32((1 << 17) - 4), 0x0403_0201);
    }

    #[test]
    #[should_panic(expected = "beyond the capacity")]
    fn out_of_range_is_caught() {
        SparseMem::new(1024).write_u32(1022, 1);
    }
}
