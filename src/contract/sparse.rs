//! The simulated DRAM image: sparse, as a page table. Nothing is sized to the
//! capacity; a 64 KB page is allocated when first written. Unwritten bytes read 0.

const PAGE_BITS: u32 = 16;
const PAGE: usize = 1 << PAGE_BITS;

/// One page of the image (`None`: never written, reads 0).
type Page = Option<Box<[u8]>>;

pub struct SparseMem {
    capacity: u64,
    pages: Vec<Option<Box<[u8]>>>,
    allocated: usize,
    /// Undo journal (see [`SparseMem::journal`]): each page's content before its
    /// first write since the journal started. Simulation bookkeeping: a window of
    /// the chip runs on the image and is then undone, not a copy of the image.
    undo: Option<Vec<(usize, Page)>>,
    saved: Vec<bool>,
}

impl SparseMem {
    /// A memory of `capacity` bytes (addresses beyond it are a modelling error).
    pub fn new(capacity: u64) -> Self {
        let n = capacity.div_ceil(PAGE as u64) as usize;
        SparseMem {
            capacity,
            pages: (0..n).map(|_| None).collect(),
            allocated: 0,
            undo: None,
            saved: Vec::new(),
        }
    }

    /// Starts recording every page's content before its first write, so that
    /// [`SparseMem::rollback`] can put the image back as it is now.
    pub fn journal(&mut self) {
        assert!(self.undo.is_none(), "one journal at a time");
        self.undo = Some(Vec::new());
        self.saved = vec![false; self.pages.len()];
    }

    /// Undoes every write since [`SparseMem::journal`] and stops journaling.
    pub fn rollback(&mut self) {
        let undo = self.undo.take().expect("rollback without a journal");
        for (p, old) in undo.into_iter().rev() {
            if old.is_none() && self.pages[p].is_some() {
                self.allocated -= 1;
            }
            self.pages[p] = old;
        }
        self.saved = Vec::new();
    }

    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Bytes of host memory the image occupies.
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

    pub fn read(&self, a: u64, out: &mut [u8]) {
        self.check(a, out.len());
        let mut done = 0;
        while done < out.len() {
            let addr = a + done as u64;
            let (p, off) = ((addr >> PAGE_BITS) as usize, (addr as usize) & (PAGE - 1));
            let n = (PAGE - off).min(out.len() - done);
            match &self.pages[p] {
                Some(pg) => out[done..done + n].copy_from_slice(&pg[off..off + n]),
                None => out[done..done + n].fill(0),
            }
            done += n;
        }
    }

    pub fn write(&mut self, a: u64, data: &[u8]) {
        self.check(a, data.len());
        let mut done = 0;
        while done < data.len() {
            let addr = a + done as u64;
            let (p, off) = ((addr >> PAGE_BITS) as usize, (addr as usize) & (PAGE - 1));
            let n = (PAGE - off).min(data.len() - done);
            if let Some(u) = &mut self.undo
                && !self.saved[p]
            {
                self.saved[p] = true;
                u.push((p, self.pages[p].clone()));
            }
            let pg = self.pages[p].get_or_insert_with(|| {
                self.allocated += 1;
                vec![0u8; PAGE].into_boxed_slice()
            });
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
    fn rollback_restores_the_image() {
        let mut m = SparseMem::new(1 << 30);
        m.write_u64(100, 7);
        m.journal();
        m.write_u64(100, 8);
        m.write_u64(100, 9);
        m.write_u32(5 << 20, 1);
        assert_eq!(m.read_u64(100), 9);
        assert_eq!(m.resident_bytes(), 2 << 16);
        m.rollback();
        assert_eq!(m.read_u64(100), 7, "the first write's old page came back");
        assert_eq!(m.read_u32(5 << 20), 0);
        assert_eq!(
            m.resident_bytes(),
            1 << 16,
            "the page the journal saw allocated is gone"
        );
        m.write_u64(100, 10);
        assert_eq!(m.read_u64(100), 10, "no journal: writes stay");
    }

    #[test]
    #[should_panic(expected = "beyond the capacity")]
    fn out_of_range_is_caught() {
        SparseMem::new(1024).write_u32(1022, 1);
    }
}
