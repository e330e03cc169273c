//! Bit-level view of payloads and register values.
//!
//! Every value that crosses a port or sits in a register has a fixed bit width, as it
//! would in hardware. The width is what the Verilog skeleton declares and what the VCD
//! trace shows; `pack` lays the value out LSB-first (the first field packed is in the
//! lowest bits), the way a SystemVerilog `{..}` concatenation reads right to left.

use glam::Vec3;

/// A growable little-endian bit vector used to pack values for tracing.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Bits {
    words: Vec<u64>,
    len: u32,
}

impl Bits {
    pub fn new() -> Self {
        Bits::default()
    }

    pub fn clear(&mut self) {
        self.words.clear();
        self.len = 0;
    }

    pub fn len(&self) -> u32 {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn words(&self) -> &[u64] {
        &self.words
    }

    /// Appends the low `width` bits of `value` (width <= 64).
    pub fn push(&mut self, value: u64, width: u32) {
        debug_assert!(width <= 64);
        if width == 0 {
            return;
        }
        let value = if width == 64 {
            value
        } else {
            value & ((1u64 << width) - 1)
        };
        let off = self.len % 64;
        if off == 0 {
            self.words.push(value);
        } else {
            *self.words.last_mut().expect("non-empty when off > 0") |= value << off;
            if off + width > 64 {
                self.words.push(value >> (64 - off));
            }
        }
        self.len += width;
    }

    /// Bit `i` (0 = LSB).
    pub fn bit(&self, i: u32) -> bool {
        (self.words[(i / 64) as usize] >> (i % 64)) & 1 == 1
    }

    /// Copies bits `at..at + width` into `out` (cleared first): one field of
    /// a packed payload.
    pub fn slice_into(&self, at: u32, width: u32, out: &mut Bits) {
        Bits::slice_words(&self.words, at, width, out);
    }

    /// As `slice_into`, from a value's words (LSB first).
    pub fn slice_words(words: &[u64], at: u32, width: u32, out: &mut Bits) {
        out.clear();
        let mut k = 0;
        while k < width {
            let w = (width - k).min(64);
            let (i, off) = (((at + k) / 64) as usize, (at + k) % 64);
            let lo = words.get(i).copied().unwrap_or(0) >> off;
            let hi = if off == 0 {
                0
            } else {
                words.get(i + 1).copied().unwrap_or(0) << (64 - off)
            };
            out.push(lo | hi, w);
            k += w;
        }
    }

    /// Reads `width` bits starting at bit `at` (for unpacking in tests).
    pub fn get(&self, at: u32, width: u32) -> u64 {
        let mut v = 0u64;
        for k in 0..width {
            if self.bit(at + k) {
                v |= 1 << k;
            }
        }
        v
    }
}

/// How a field's bits read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldKind {
    /// An unsigned integer, a flag or raw bits.
    Bits,
    /// An IEEE-754 single (shown as a number where the format allows).
    Float,
    /// An FSM state: index k is `names[k]`.
    Enum(&'static [&'static str]),
}

/// One leaf field of a packed payload: its path inside the payload
/// (`ray.origin.x`), where it sits and how it reads. The waveform shows each
/// as its own signal, as Verilator's `--trace-structs` does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    /// First bit (LSB-first, as packed).
    pub offset: u32,
    pub width: u32,
    pub kind: FieldKind,
}

/// `prefix.name`, or `name` at the top.
pub fn field_path(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_string()
    } else {
        format!("{prefix}.{name}")
    }
}

/// A value with a fixed hardware bit width.
pub trait Payload: Clone + std::fmt::Debug + PartialEq + Send + 'static {
    /// Width in bits of the packed value (the Verilog vector width).
    const BITS: u32;
    /// Appends exactly `BITS` bits to `out`.
    fn pack(&self, out: &mut Bits);
    /// Names of the encodings of an enumerated (FSM state) value, listed in the VCD
    /// header so a waveform viewer user can read the integers.
    fn enum_names() -> Option<&'static [&'static str]> {
        None
    }
    /// Appends the leaf fields of a value packed at `offset`, named below
    /// `prefix`. A leaf (an integer, a flag, an FSM state) is one field named
    /// `prefix`; structs list their fields in packing order.
    fn fields(prefix: &str, offset: u32, out: &mut Vec<Field>) {
        out.push(Field {
            name: prefix.to_string(),
            offset,
            width: Self::BITS,
            kind: Self::enum_names().map_or(FieldKind::Bits, FieldKind::Enum),
        });
    }
    /// The SystemVerilog type (`hdl/ds_pkg.sv`): by default an FSM state's
    /// enum or a `logic` vector; structs list their members.
    fn sv_type() -> super::sv::SvType {
        match Self::enum_names() {
            Some(names) => super::sv::SvType::Enum {
                name: short_type_name::<Self>(),
                names,
            },
            None => super::sv::SvType::Logic(Self::BITS),
        }
    }
    /// The fields of the whole payload; empty for a leaf (its packed vector
    /// is all there is to show).
    fn field_list() -> Vec<Field> {
        let mut v = Vec::new();
        Self::fields("", 0, &mut v);
        if v.len() == 1 && v[0].name.is_empty() {
            v.clear();
        }
        v
    }
    /// Bit-exact equality (NaN payloads equal themselves, +0 and -0 differ), which is
    /// what "the value did not change" means for hardware. The packings compared;
    /// the kernel's own payloads override it with the same answer without packing
    /// (a link monitor asks it every time a refused offer is repeated).
    fn same_bits(&self, other: &Self) -> bool {
        // Link monitors call this every cycle a refused offer is repeated: pack into
        // two per-thread scratch vectors instead of allocating (`pack` never calls
        // `same_bits`, so the borrow cannot nest).
        SCRATCH.with(|s| {
            let (a, b) = &mut *s.borrow_mut();
            a.clear();
            b.clear();
            self.pack(a);
            other.pack(b);
            a == b
        })
    }
}

/// `dualstream::mem::StreamTag` -> `StreamTag`.
fn short_type_name<T: ?Sized>() -> &'static str {
    let n = std::any::type_name::<T>();
    n.rsplit("::").next().unwrap_or(n)
}

thread_local! {
    static SCRATCH: std::cell::RefCell<(Bits, Bits)> = const {
        std::cell::RefCell::new((
            Bits { words: Vec::new(), len: 0 },
            Bits { words: Vec::new(), len: 0 },
        ))
    };
}

macro_rules! uint_payload {
    ($($t:ty),*) => {$(
        impl Payload for $t {
            const BITS: u32 = <$t>::BITS;
            fn pack(&self, out: &mut Bits) {
                out.push(*self as u64, Self::BITS);
            }
            fn same_bits(&self, other: &Self) -> bool {
                self == other
            }
        }
    )*};
}
uint_payload!(u8, u16, u32, u64);

impl Payload for bool {
    const BITS: u32 = 1;
    fn pack(&self, out: &mut Bits) {
        out.push(*self as u64, 1);
    }
    fn same_bits(&self, other: &Self) -> bool {
        self == other
    }
}

impl Payload for f32 {
    const BITS: u32 = 32;
    fn sv_type() -> super::sv::SvType {
        super::sv::SvType::Float
    }
    fn fields(prefix: &str, offset: u32, out: &mut Vec<Field>) {
        out.push(Field {
            name: prefix.to_string(),
            offset,
            width: 32,
            kind: FieldKind::Float,
        });
    }
    fn pack(&self, out: &mut Bits) {
        out.push(self.to_bits() as u64, 32);
    }
    fn same_bits(&self, other: &Self) -> bool {
        self.to_bits() == other.to_bits()
    }
}

impl Payload for Vec3 {
    const BITS: u32 = 96;
    fn sv_type() -> super::sv::SvType {
        use super::sv::SvType;
        SvType::Struct {
            name: "Vec3".into(),
            members: vec![
                ("x", SvType::Float),
                ("y", SvType::Float),
                ("z", SvType::Float),
            ],
        }
    }
    fn fields(prefix: &str, offset: u32, out: &mut Vec<Field>) {
        for (k, n) in ["x", "y", "z"].into_iter().enumerate() {
            f32::fields(&field_path(prefix, n), offset + 32 * k as u32, out);
        }
    }
    fn pack(&self, out: &mut Bits) {
        self.x.pack(out);
        self.y.pack(out);
        self.z.pack(out);
    }
    fn same_bits(&self, o: &Self) -> bool {
        self.x.same_bits(&o.x) && self.y.same_bits(&o.y) && self.z.same_bits(&o.z)
    }
}

impl<T: Payload> Payload for Option<T> {
    // A valid bit in the LSB, then the payload (zeros when absent).
    const BITS: u32 = 1 + T::BITS;
    /// `valid`, then the value's members (a leaf is `value`), as `fields`.
    fn sv_type() -> super::sv::SvType {
        use super::sv::SvType;
        let inner = T::sv_type();
        let name = inner.option_name();
        let mut members = vec![("valid", SvType::Logic(1))];
        match inner {
            SvType::Struct { members: m, .. } => members.extend(m),
            leaf => members.push(("value", leaf)),
        }
        SvType::Struct { name, members }
    }
    /// `valid`, then the value's fields (a leaf value is named `value`).
    fn fields(prefix: &str, offset: u32, out: &mut Vec<Field>) {
        bool::fields(&field_path(prefix, "valid"), offset, out);
        let mut inner = Vec::new();
        T::fields(prefix, offset + 1, &mut inner);
        if inner.len() == 1 && inner[0].name == prefix {
            inner[0].name = field_path(prefix, "value");
        }
        out.extend(inner);
    }
    fn pack(&self, out: &mut Bits) {
        match self {
            Some(v) => {
                out.push(1, 1);
                v.pack(out);
            }
            None => {
                out.push(0, 1);
                let mut left = T::BITS;
                while left > 0 {
                    let w = left.min(64);
                    out.push(0, w);
                    left -= w;
                }
            }
        }
    }
    fn same_bits(&self, other: &Self) -> bool {
        match (self, other) {
            (Some(a), Some(b)) => a.same_bits(b),
            (None, None) => true,
            _ => false,
        }
    }
}

/// Declares a struct payload whose width is the sum of its fields' widths and whose
/// packing is the fields in declaration order (first field in the lowest bits).
#[macro_export]
macro_rules! payload_struct {
    ($(#[$m:meta])* $vis:vis struct $name:ident { $($(#[$fm:meta])* $fvis:vis $f:ident : $t:ty),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Debug, PartialEq)]
        $vis struct $name { $($(#[$fm])* $fvis $f: $t),* }
        impl $crate::rtl::bits::Payload for $name {
            const BITS: u32 = 0 $(+ <$t as $crate::rtl::bits::Payload>::BITS)*;
            #[allow(unused_variables, unused_mut, unused_assignments)]
            fn fields(prefix: &str, offset: u32, out: &mut Vec<$crate::rtl::bits::Field>) {
                let mut at = offset;
                $(
                    <$t as $crate::rtl::bits::Payload>::fields(
                        &$crate::rtl::bits::field_path(prefix, stringify!($f)), at, out);
                    at += <$t as $crate::rtl::bits::Payload>::BITS;
                )*
            }
            fn sv_type() -> $crate::rtl::sv::SvType {
                $crate::rtl::sv::SvType::Struct {
                    name: stringify!($name).to_string(),
                    members: vec![$((stringify!($f), <$t as $crate::rtl::bits::Payload>::sv_type())),*],
                }
            }
            fn pack(&self, out: &mut $crate::rtl::bits::Bits) {
                $($crate::rtl::bits::Payload::pack(&self.$f, out);)*
            }
            // Field by field: each packs to its fixed width, so the packings are
            // equal exactly when every field's are.
            #[allow(unused_variables)]
            fn same_bits(&self, other: &Self) -> bool {
                true $(&& $crate::rtl::bits::Payload::same_bits(&self.$f, &other.$f))*
            }
        }
    };
}

/// Declares an FSM state enum: encoded as its index, width = enough bits for all
/// states, names listed for waveform viewers.
#[macro_export]
macro_rules! fsm_states {
    ($(#[$m:meta])* $vis:vis enum $name:ident { $first:ident $(, $rest:ident)* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
        #[repr(u8)]
        $vis enum $name { #[default] $first $(, $rest)* }
        impl $crate::rtl::bits::Payload for $name {
            const BITS: u32 = $crate::rtl::bits::clog2_u32([stringify!($first) $(, stringify!($rest))*].len() as u32);
            fn pack(&self, out: &mut $crate::rtl::bits::Bits) {
                out.push(*self as u64, Self::BITS);
            }
            fn same_bits(&self, other: &Self) -> bool {
                self == other
            }
            fn enum_names() -> Option<&'static [&'static str]> {
                Some(&[stringify!($first) $(, stringify!($rest))*])
            }
            fn sv_type() -> $crate::rtl::sv::SvType {
                $crate::rtl::sv::SvType::Enum {
                    name: stringify!($name),
                    names: &[stringify!($first) $(, stringify!($rest))*],
                }
            }
        }
    };
}

/// Bits needed to encode `n` distinct values (at least 1).
pub const fn clog2_u32(n: u32) -> u32 {
    if n <= 2 {
        1
    } else {
        32 - (n - 1).leading_zeros()
    }
}

/// Packs a value into a fresh bit vector.
pub fn packed<T: Payload>(v: &T) -> Bits {
    let mut b = Bits::new();
    v.pack(&mut b);
    debug_assert_eq!(
        b.len(),
        T::BITS,
        "pack() of {} wrote the wrong width",
        std::any::type_name::<T>()
    );
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    crate::payload_struct! {
        struct Pair { a: u8, b: f32, c: bool }
    }

    crate::fsm_states! {
        enum Five { A, B, C, D, E }
    }

    #[test]
    fn struct_width_is_sum_and_fields_pack_lsb_first() {
        assert_eq!(Pair::BITS, 41);
        let p = Pair {
            a: 0xA5,
            b: 1.0,
            c: true,
        };
        let bits = packed(&p);
        assert_eq!(bits.len(), 41);
        assert_eq!(bits.get(0, 8), 0xA5);
        assert_eq!(bits.get(8, 32), 1.0f32.to_bits() as u64);
        assert!(bits.bit(40));
    }

    crate::payload_struct! {
        struct Outer { p: Pair, o: Option<Pair>, f: Option<f32>, s: Five, v: Vec3 }
    }

    /// Fields tile the packed vector in order, nested names are paths, and
    /// each field's slice of a packed value is that field's own packing.
    #[test]
    fn fields_tile_the_packing() {
        let f = Outer::field_list();
        let names: Vec<&str> = f.iter().map(|x| x.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "p.a", "p.b", "p.c", "o.valid", "o.a", "o.b", "o.c", "f.valid", "f.value", "s",
                "v.x", "v.y", "v.z"
            ]
        );
        let mut at = 0;
        for x in &f {
            assert_eq!(x.offset, at, "{} starts where the last ended", x.name);
            at += x.width;
        }
        assert_eq!(at, Outer::BITS);
        assert_eq!(f[1].kind, FieldKind::Float);
        assert_eq!(f[9].kind, FieldKind::Enum(Five::enum_names().unwrap()));
        assert!(u32::field_list().is_empty() && Five::field_list().is_empty());
        // The SystemVerilog struct's leaves are these fields (an `Option`'s
        // members inline after its `valid`, a leaf one as `value`).
        let mut leaves = Vec::new();
        Outer::sv_type().leaves("", 0, &mut leaves);
        let want: Vec<(String, u32, u32)> = f
            .iter()
            .map(|x| (x.name.clone(), x.offset, x.width))
            .collect();
        assert_eq!(leaves, want);
        assert_eq!(Outer::sv_type().width(), Outer::BITS);
        assert_eq!(<Option<Pair>>::sv_type().sv_name(), "opt_pair_t");
        assert_eq!(<Option<f32>>::sv_type().sv_name(), "opt_f32_t");
        let v = Outer {
            p: Pair {
                a: 7,
                b: -2.5,
                c: true,
            },
            o: Some(Pair {
                a: 0xFE,
                b: 3.0,
                c: false,
            }),
            f: None,
            s: Five::D,
            v: Vec3::new(1.0, 2.0, 3.0),
        };
        let bits = packed(&v);
        let mut s = Bits::new();
        let mut field = |k: usize| {
            bits.slice_into(f[k].offset, f[k].width, &mut s);
            assert_eq!(s.len(), f[k].width);
            s.get(0, f[k].width.min(64))
        };
        assert_eq!(field(0), 7);
        assert_eq!(field(1), (-2.5f32).to_bits() as u64);
        assert_eq!(field(4), 0xFE);
        assert_eq!(field(5), 3.0f32.to_bits() as u64);
        assert_eq!(field(7), 0);
        assert_eq!(field(9), 3);
        assert_eq!(field(12), 3.0f32.to_bits() as u64);
        // A slice wider than a word, across word boundaries.
        let mut w = Bits::new();
        w.push(0xAAAA_AAAA_AAAA_AAAA, 64);
        w.push(0x5555_5555_5555_5555, 64);
        w.push(0xF, 4);
        w.slice_into(3, 128, &mut s);
        assert_eq!(s.get(0, 61), 0xAAAA_AAAA_AAAA_AAAA >> 3);
        assert_eq!(s.get(61, 64), 0x5555_5555_5555_5555);
        assert_eq!(s.get(125, 3), 0b111);
    }

    #[test]
    fn push_across_word_boundaries() {
        let mut b = Bits::new();
        b.push(0x1, 60);
        b.push(0xFF, 8);
        b.push(u64::MAX, 64);
        assert_eq!(b.len(), 132);
        assert_eq!(b.get(60, 8), 0xFF);
        assert_eq!(b.get(68, 64), u64::MAX);
        assert_eq!(b.get(0, 60), 1);
    }

    /// Every `same_bits` override answers what comparing the packings would.
    #[test]
    fn same_bits_is_equality_of_the_packings() {
        fn check<T: Payload>(pairs: &[(T, T)]) {
            for (a, b) in pairs {
                let packed_equal = packed(a).words == packed(b).words;
                assert_eq!(a.same_bits(b), packed_equal, "{a:?} vs {b:?}");
                assert!(a.same_bits(a), "{a:?} vs itself");
            }
        }
        let nan = f32::from_bits(0x7fc0_0001);
        check(&[(0.0f32, -0.0), (nan, nan), (nan, f32::NAN), (1.5, 1.5)]);
        check(&[(Some(0.0f32), None), (None, None), (Some(-0.0), Some(0.0))]);
        check(&[(Some(0u32), None), (Some(7u32), Some(7))]);
        check(&[
            (Vec3::new(0.0, 1.0, 2.0), Vec3::new(-0.0, 1.0, 2.0)),
            (Vec3::new(nan, 1.0, 2.0), Vec3::new(nan, 1.0, 2.0)),
        ]);
        let pair = |a: u8, b: f32| Pair { a, b, c: true };
        check(&[
            (pair(1, 0.0), pair(1, -0.0)),
            (pair(1, nan), pair(1, nan)),
            (pair(1, 0.0), pair(2, 0.0)),
        ]);
        check(&[(true, false), (false, false)]);
        check(&[(0u8, 1), (0xA5, 0xA5)]);
        check(&[(0u16, 1 << 15)]);
        check(&[(u64::MAX, u64::MAX - 1), (1 << 63, 1 << 63)]);
        check(&[(Five::A, Five::E), (Five::D, Five::D)]);
        // The units' payloads (records, cache lines) are checked in
        // tests/payloads.rs: the kernel knows nothing of them.
    }

    #[test]
    fn fsm_width_and_names() {
        assert_eq!(Five::BITS, 3);
        assert_eq!(Five::enum_names().unwrap()[4], "E");
        assert_eq!(packed(&Five::E).get(0, 3), 4);
        let all = [Five::A, Five::B, Five::C, Five::D, Five::E];
        assert_eq!(all.len(), 5);
        assert_eq!(clog2_u32(1), 1);
        assert_eq!(clog2_u32(2), 1);
        assert_eq!(clog2_u32(3), 2);
        assert_eq!(clog2_u32(16), 4);
        assert_eq!(clog2_u32(17), 5);
        assert_eq!(<Option<u16>>::BITS, 17);
    }
}
