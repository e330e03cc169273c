//! The data contract: every byte the chip reads and writes in simulated DRAM.
//! `docs/data-contract.md` is the prose version of this file; the two must agree
//! (the byte offsets below are the single source of truth, little-endian).

pub mod memmap;
pub mod sparse;

pub use memmap::{MapError, MemoryMap, MemoryMapCfg};
pub use sparse::SparseMem;

use glam::Vec3;

/// One cache line / DRAM burst.
pub const LINE_BYTES: u64 = 64;

// ---- scene stream: segments (treelets) ----

/// Segment header: magic, id, node count, triangle count, byte size; rest zero.
pub const SEGMENT_HEADER_BYTES: u32 = 64;
/// "SEG1" little-endian.
pub const SEGMENT_MAGIC: u32 = u32::from_le_bytes(*b"SEG1");
/// BVH2 inner node: both children's boxes, references and segments (one line).
pub const NODE_BYTES: u32 = 64;
/// Triangle: three vertices, scene triangle id, material id, reserved.
pub const TRI_BYTES: u32 = 48;

/// Reference to a node or leaf inside a segment (see `docs/data-contract.md`).
pub const REF_NONE: u32 = u32::MAX;
/// In a node's segment word: the child is in this same segment.
pub const SEG_SAME: u32 = u32::MAX;
const LEAF_BIT: u32 = 1 << 31;
pub const MAX_LEAF_TRIS: u32 = 128;
pub const MAX_REF_INDEX: u32 = (1 << 24) - 1;

/// A decoded reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ref {
    /// Inner node: index in the segment's node array.
    Node(u32),
    /// Leaf: first index in the segment's triangle array and count (1..=128).
    Leaf {
        first: u32,
        count: u32,
    },
    None,
}

impl Ref {
    pub fn encode(self) -> u32 {
        match self {
            Ref::Node(i) => {
                assert!(i <= MAX_REF_INDEX, "node index fits 24 bits");
                i
            }
            Ref::Leaf { first, count } => {
                assert!(
                    first <= MAX_REF_INDEX && (1..=MAX_LEAF_TRIS).contains(&count),
                    "leaf fits its encoding"
                );
                LEAF_BIT | ((count - 1) << 24) | first
            }
            Ref::None => REF_NONE,
        }
    }
    pub fn decode(w: u32) -> Ref {
        if w == REF_NONE {
            Ref::None
        } else if w & LEAF_BIT != 0 {
            Ref::Leaf {
                first: w & MAX_REF_INDEX,
                count: ((w >> 24) & 0x7F) + 1,
            }
        } else {
            Ref::Node(w & MAX_REF_INDEX)
        }
    }
}

/// Node record (64 B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeRec {
    pub bmin: [Vec3; 2],
    pub bmax: [Vec3; 2],
    pub child: [u32; 2],
    /// `SEG_SAME`, or the segment that holds the child (an exit).
    pub seg: [u32; 2],
}

/// Triangle record (48 B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriRec {
    pub v: [Vec3; 3],
    pub tri_id: u32,
    pub material: u32,
}

// ---- ray stream ----

pub const RAY_BYTES: u32 = 32;
pub const BUCKET_HEADER_BYTES: u32 = 32;
/// Bit of the ray id that marks a shadow (any-hit) ray.
pub const SHADOW_BIT: u32 = 1 << 31;

/// Ray record (32 B): origin, direction, ray id, entry reference.
/// Shadow rays have no t_max: their direction is unnormalised and t = 1 is the light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayRec {
    pub origin: Vec3,
    pub dir: Vec3,
    /// bit 31: shadow; bits 0..30: pixel index (y * width + x).
    pub ray_id: u32,
    /// Where the ray enters the segment whose queue holds it (an encoded `Ref`).
    pub entry: u32,
}

impl RayRec {
    pub fn is_shadow(&self) -> bool {
        self.ray_id & SHADOW_BIT != 0
    }
    pub fn pixel(&self) -> u32 {
        self.ray_id & !SHADOW_BIT
    }
    /// Index of the ray's hit record: two per pixel, bounce then shadow.
    pub fn hit_index(&self) -> u64 {
        self.pixel() as u64 * 2 + self.is_shadow() as u64
    }
    pub fn t_max(&self) -> f32 {
        if self.is_shadow() { 1.0 } else { f32::INFINITY }
    }
}

/// Ray bucket header (32 B at the start of each bucket).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BucketHeader {
    /// Address of the next bucket of the same queue, 0 if none (address 0 is the
    /// segment table, never a bucket).
    pub next: u64,
    pub count: u32,
    pub segment: u32,
}

// ---- hit records and path state ----

pub const HIT_BYTES: u32 = 16;
/// t = +inf and id = !0: no hit.
pub const HIT_NONE_ID: u32 = u32::MAX;

/// Hit record (16 B): distance, triangle id, and the barycentrics of the hit (the
/// weights of v1 and v2), from which shading rebuilds the hit point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitRec {
    pub t: f32,
    pub tri_id: u32,
    pub u: f32,
    pub v: f32,
}

impl HitRec {
    pub const NONE: HitRec = HitRec {
        t: f32::INFINITY,
        tri_id: HIT_NONE_ID,
        u: 0.0,
        v: 0.0,
    };
    pub fn is_hit(&self) -> bool {
        self.tri_id != HIT_NONE_ID
    }
    /// Closest-hit order: the pair (t, triangle id).
    pub fn closer_than(&self, o: &HitRec) -> bool {
        self.t < o.t || (self.t == o.t && self.tri_id < o.tri_id)
    }
}

pub const PATH_BYTES: u32 = 64;
pub const PATH_BOUNCE_IN_FLIGHT: u16 = 1;
pub const PATH_SHADOW_IN_FLIGHT: u16 = 2;

/// Per-pixel path state (64 B, one line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathRec {
    pub throughput: Vec3,
    /// Radiance the in-flight shadow ray adds if it reaches the light.
    pub pending: Vec3,
    pub radiance: Vec3,
    /// Direction of the bounce ray in flight (shading faces the normal against it).
    pub dir: Vec3,
    pub rng: u64,
    /// Hit points so far.
    pub depth: u16,
    pub flags: u16,
}

// ---- segment table ----

pub const SEG_ENTRY_BYTES: u32 = 32;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SegEntry {
    pub base: u64,
    pub bytes: u32,
    pub nodes: u32,
    pub tris: u32,
    /// `SEG_SAME` (all ones) for the root segment.
    pub parent: u32,
    pub first_child: u32,
    pub child_count: u32,
}

// ---- queue records ----

/// A closed ray queue waiting for its segment's admission: the stream scheduler
/// writes it when the queue leaves the destination table (whose entries hold only
/// the working set's write destinations, paper §4.1) and reads it back at admission.
pub const QUEUE_REC_BYTES: u32 = 16;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueueRec {
    /// Address of the queue's first bucket.
    pub head: u64,
    pub buckets: u32,
    pub rays: u32,
}

impl QueueRec {
    pub fn encode(&self) -> [u8; QUEUE_REC_BYTES as usize] {
        let mut b = [0u8; QUEUE_REC_BYTES as usize];
        b[0..8].copy_from_slice(&self.head.to_le_bytes());
        put_u32(&mut b, 8, self.buckets);
        put_u32(&mut b, 12, self.rays);
        b
    }
    pub fn decode(b: &[u8]) -> QueueRec {
        QueueRec {
            head: u64::from_le_bytes(b[0..8].try_into().expect("8 bytes")),
            buckets: u32_at(b, 8),
            rays: u32_at(b, 12),
        }
    }
}

// ---- codecs over the sparse DRAM image ----

// Each record is encoded to / decoded from its bytes in one piece, so a record
// costs one access to the sparse image, not one per field.
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"))
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().expect("4 bytes"))
}
fn vec3_at(b: &[u8], o: usize) -> Vec3 {
    Vec3::new(f32_at(b, o), f32_at(b, o + 4), f32_at(b, o + 8))
}
fn put_u32(b: &mut [u8], o: usize, v: u32) {
    b[o..o + 4].copy_from_slice(&v.to_le_bytes());
}
fn put_f32(b: &mut [u8], o: usize, v: f32) {
    put_u32(b, o, v.to_bits());
}
fn put_vec3(b: &mut [u8], o: usize, v: Vec3) {
    put_f32(b, o, v.x);
    put_f32(b, o + 4, v.y);
    put_f32(b, o + 8, v.z);
}
impl NodeRec {
    pub fn encode(&self) -> [u8; NODE_BYTES as usize] {
        let mut b = [0u8; NODE_BYTES as usize];
        for s in 0..2 {
            put_vec3(&mut b, 24 * s, self.bmin[s]);
            put_vec3(&mut b, 24 * s + 12, self.bmax[s]);
            put_u32(&mut b, 48 + 4 * s, self.child[s]);
            put_u32(&mut b, 56 + 4 * s, self.seg[s]);
        }
        b
    }
    pub fn decode(b: &[u8]) -> NodeRec {
        NodeRec {
            bmin: [vec3_at(b, 0), vec3_at(b, 24)],
            bmax: [vec3_at(b, 12), vec3_at(b, 36)],
            child: [u32_at(b, 48), u32_at(b, 52)],
            seg: [u32_at(b, 56), u32_at(b, 60)],
        }
    }
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> NodeRec {
        let mut b = [0u8; NODE_BYTES as usize];
        m.read(a, &mut b);
        NodeRec::decode(&b)
    }
}

impl TriRec {
    pub fn encode(&self) -> [u8; TRI_BYTES as usize] {
        let mut b = [0u8; TRI_BYTES as usize];
        for k in 0..3 {
            put_vec3(&mut b, 12 * k, self.v[k]);
        }
        put_u32(&mut b, 36, self.tri_id);
        put_u32(&mut b, 40, self.material);
        b
    }
    pub fn decode(b: &[u8]) -> TriRec {
        TriRec {
            v: [vec3_at(b, 0), vec3_at(b, 12), vec3_at(b, 24)],
            tri_id: u32_at(b, 36),
            material: u32_at(b, 40),
        }
    }
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> TriRec {
        let mut b = [0u8; TRI_BYTES as usize];
        m.read(a, &mut b);
        TriRec::decode(&b)
    }
}

impl RayRec {
    pub fn encode(&self) -> [u8; RAY_BYTES as usize] {
        let mut b = [0u8; RAY_BYTES as usize];
        put_vec3(&mut b, 0, self.origin);
        put_vec3(&mut b, 12, self.dir);
        put_u32(&mut b, 24, self.ray_id);
        put_u32(&mut b, 28, self.entry);
        b
    }
    pub fn decode(b: &[u8]) -> RayRec {
        RayRec {
            origin: vec3_at(b, 0),
            dir: vec3_at(b, 12),
            ray_id: u32_at(b, 24),
            entry: u32_at(b, 28),
        }
    }
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> RayRec {
        let mut b = [0u8; RAY_BYTES as usize];
        m.read(a, &mut b);
        RayRec::decode(&b)
    }
}

impl BucketHeader {
    pub fn encode(&self) -> [u8; BUCKET_HEADER_BYTES as usize] {
        let mut b = [0u8; BUCKET_HEADER_BYTES as usize];
        b[0..8].copy_from_slice(&self.next.to_le_bytes());
        put_u32(&mut b, 8, self.count);
        put_u32(&mut b, 12, self.segment);
        b
    }
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> BucketHeader {
        BucketHeader {
            next: m.read_u64(a),
            count: m.read_u32(a + 8),
            segment: m.read_u32(a + 12),
        }
    }
}

impl HitRec {
    pub fn encode(&self) -> [u8; HIT_BYTES as usize] {
        let mut b = [0u8; HIT_BYTES as usize];
        put_f32(&mut b, 0, self.t);
        put_u32(&mut b, 4, self.tri_id);
        put_f32(&mut b, 8, self.u);
        put_f32(&mut b, 12, self.v);
        b
    }
    pub fn decode(b: &[u8]) -> HitRec {
        HitRec {
            t: f32_at(b, 0),
            tri_id: u32_at(b, 4),
            u: f32_at(b, 8),
            v: f32_at(b, 12),
        }
    }
    /// One access of the record's bytes, not one per field (the functional
    /// model reads and writes a hit record per ray and segment).
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> HitRec {
        let mut b = [0u8; HIT_BYTES as usize];
        m.read(a, &mut b);
        HitRec::decode(&b)
    }
}

impl PathRec {
    pub fn encode(&self) -> [u8; PATH_BYTES as usize] {
        let mut b = [0u8; PATH_BYTES as usize];
        put_vec3(&mut b, 0, self.throughput);
        put_vec3(&mut b, 12, self.pending);
        put_vec3(&mut b, 24, self.radiance);
        put_vec3(&mut b, 36, self.dir);
        b[48..56].copy_from_slice(&self.rng.to_le_bytes());
        put_u32(&mut b, 56, self.depth as u32 | (self.flags as u32) << 16);
        b
    }
    pub fn decode(b: &[u8]) -> PathRec {
        let w = u32_at(b, 56);
        PathRec {
            throughput: vec3_at(b, 0),
            pending: vec3_at(b, 12),
            radiance: vec3_at(b, 24),
            dir: vec3_at(b, 36),
            rng: u64::from_le_bytes(b[48..56].try_into().expect("8 bytes")),
            depth: w as u16,
            flags: (w >> 16) as u16,
        }
    }
    /// One access of the record's bytes, as `HitRec`'s (the last word is
    /// written zero, as `encode` leaves it).
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> PathRec {
        let mut b = [0u8; PATH_BYTES as usize];
        m.read(a, &mut b);
        PathRec::decode(&b)
    }
}

impl SegEntry {
    pub fn encode(&self) -> [u8; SEG_ENTRY_BYTES as usize] {
        let mut b = [0u8; SEG_ENTRY_BYTES as usize];
        b[0..8].copy_from_slice(&self.base.to_le_bytes());
        put_u32(&mut b, 8, self.bytes);
        put_u32(&mut b, 12, self.nodes);
        put_u32(&mut b, 16, self.tris);
        put_u32(&mut b, 20, self.parent);
        put_u32(&mut b, 24, self.first_child);
        put_u32(&mut b, 28, self.child_count);
        b
    }
    /// The entry in its first `SEG_ENTRY_BYTES` bytes `b`: the one decoder, for
    /// the DRAM image (`read`) and for the line the stream scheduler fetched.
    pub fn decode(b: &[u8]) -> SegEntry {
        SegEntry {
            base: u64::from_le_bytes(b[0..8].try_into().expect("8 bytes")),
            bytes: u32_at(b, 8),
            nodes: u32_at(b, 12),
            tris: u32_at(b, 16),
            parent: u32_at(b, 20),
            first_child: u32_at(b, 24),
            child_count: u32_at(b, 28),
        }
    }
    pub fn write(&self, m: &mut SparseMem, a: u64) {
        m.write(a, &self.encode());
    }
    pub fn read(m: &SparseMem, a: u64) -> SegEntry {
        let mut b = [0u8; SEG_ENTRY_BYTES as usize];
        m.read(a, &mut b);
        SegEntry::decode(&b)
    }
}

/// Number of 64 B lines touched by the byte range `[addr, addr + len)`.
pub fn lines_touched(addr: u64, len: u64) -> u64 {
    if len == 0 {
        return 0;
    }
    (addr + len - 1) / LINE_BYTES - addr / LINE_BYTES + 1
}

/// The ray stream between two segments of a wavefront, in the order the functional
/// model takes them: every queue holding rays (all closed: their parents are done)
/// as the record the stream scheduler reads, and the bucket pool. What a chip needs
/// to take the wavefront over at that point (`machine::Chip::trace_window`).
#[derive(Clone, Debug, Default)]
pub struct Boundary {
    pub queues: Vec<(u32, QueueRec)>,
    pub free_chunks: Vec<u64>,
    pub chunk_live: Vec<u8>,
    pub live_buckets: u64,
    /// Bytes written into the window's snapshot of the image before the chip
    /// starts: a compacted root queue and its hit records
    /// (`render::queues::RayQueues::boundary_compact`).
    pub writes: Vec<(u64, Vec<u8>)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refs_round_trip() {
        for r in [
            Ref::Node(0),
            Ref::Node(MAX_REF_INDEX),
            Ref::Leaf { first: 7, count: 1 },
            Ref::Leaf {
                first: 99,
                count: 128,
            },
            Ref::None,
        ] {
            assert_eq!(Ref::decode(r.encode()), r);
        }
        assert_eq!(Ref::Leaf { first: 3, count: 2 }.encode(), 0x8100_0003);
    }

    #[test]
    fn records_round_trip_at_their_offsets() {
        let mut m = SparseMem::new(1 << 20);
        let n = NodeRec {
            bmin: [Vec3::new(1.0, 2.0, 3.0), Vec3::splat(-1.0)],
            bmax: [Vec3::new(4.0, 5.0, 6.0), Vec3::splat(1.0)],
            child: [
                Ref::Node(5).encode(),
                Ref::Leaf { first: 2, count: 1 }.encode(),
            ],
            seg: [SEG_SAME, 17],
        };
        n.write(&mut m, 128);
        assert_eq!(NodeRec::read(&m, 128), n);
        assert_eq!(m.read_u32(128 + 60), 17, "seg of child 1 at byte 60");
        let r = RayRec {
            origin: Vec3::X,
            dir: -Vec3::Y,
            ray_id: 5 | SHADOW_BIT,
            entry: 3,
        };
        r.write(&mut m, 4096);
        assert_eq!(RayRec::read(&m, 4096), r);
        assert!(r.is_shadow() && r.pixel() == 5 && r.hit_index() == 11);
        let p = PathRec {
            throughput: Vec3::ONE,
            pending: Vec3::ZERO,
            radiance: Vec3::splat(0.5),
            dir: Vec3::Y,
            depth: 3,
            rng: 0xDEAD_BEEF_0123_4567,
            flags: 3,
        };
        m.write(8192 + 60, &[0xFF; 4]);
        p.write(&mut m, 8192);
        assert_eq!(PathRec::read(&m, 8192), p);
        // The fields at the contract's offsets, not just a round trip.
        assert_eq!(m.read_f32(8192 + 24), 0.5, "radiance.x at byte 24");
        assert_eq!(m.read_f32(8192 + 40), 1.0, "dir.y at byte 40");
        assert_eq!(
            m.read_u64(8192 + 48),
            0xDEAD_BEEF_0123_4567,
            "rng at byte 48"
        );
        assert_eq!(
            m.read_u32(8192 + 56),
            3 | 3 << 16,
            "depth | flags << 16 at byte 56"
        );
        assert_eq!(m.read_u32(8192 + 60), 0, "the last word written zero");
        let h = HitRec {
            t: 2.5,
            tri_id: 77,
            u: 0.25,
            v: 0.5,
        };
        // A record across a 64 KB page boundary (the slow path) reads back too.
        for a in [12288, (1 << 16) - 8] {
            h.write(&mut m, a);
            assert_eq!(HitRec::read(&m, a), h);
            assert_eq!(m.read_u32(a + 4), 77, "tri_id at byte 4");
            assert_eq!(m.read_f32(a + 12), 0.5, "v at byte 12");
        }
        let e = SegEntry {
            base: 0x1_2345_6780,
            bytes: 4096,
            nodes: 31,
            tris: 40,
            parent: SEG_SAME,
            first_child: 9,
            child_count: 3,
        };
        e.write(&mut m, 16384 + 32);
        assert_eq!(SegEntry::read(&m, 16384 + 32), e);
        assert_eq!(m.read_u64(16384 + 32), 0x1_2345_6780, "base at byte 0");
        assert_eq!(m.read_u32(16384 + 32 + 24), 9, "first_child at byte 24");
        assert_eq!(m.read_u32(16384 + 32 + 28), 3, "child_count at byte 28");
        // From the 64 B line that holds it, as the stream scheduler reads it.
        let mut line = [0u8; LINE_BYTES as usize];
        m.read(16384, &mut line);
        let e1 = &line[32..32 + SEG_ENTRY_BYTES as usize];
        assert_eq!(SegEntry::decode(e1), e);
    }

    #[test]
    fn lines() {
        assert_eq!(lines_touched(0, 64), 1);
        assert_eq!(lines_touched(48, 48), 2);
        assert_eq!(lines_touched(64, 1), 1);
        assert_eq!(lines_touched(0, 0), 0);
    }
}
