//! Operation counts of the intersection tests, and the scalar trait that lets the
//! arithmetic be written once and run either on plain `f32` (production, zero
//! cost) or on a counting wrapper (tests), so the published counts cannot drift
//! from the code.
//!
//! Counting rules (what a hardware datapath would need an FP unit for):
//! - `add`: every `+` and `-` (subtract is an adder).
//! - `mul`, `div`: every `*` and `/`.
//! - `cmp`: every `<`, `<=`, `>`, `>=`, `==` between two scalars.
//! - `minmax`: every compare-and-select (`Scalar::max_acc` / `Scalar::min_acc`).
//! - Free (wiring / bit logic, not counted): constants, sign flips, `abs`,
//!   sign-bit tests, NaN/finite classification, axis permutation muxes.

use std::ops::{Add, Div, Mul, Sub};

/// Number of floating-point operations of each kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct OpCount {
    /// Adds and subtracts.
    pub add: u32,
    pub mul: u32,
    /// Scalar comparisons.
    pub cmp: u32,
    /// Compare-and-select (min/max) operations.
    pub minmax: u32,
    pub div: u32,
}

impl OpCount {
    pub const ZERO: OpCount = OpCount {
        add: 0,
        mul: 0,
        cmp: 0,
        minmax: 0,
        div: 0,
    };

    /// All operations regardless of kind.
    pub fn total(&self) -> u32 {
        self.add + self.mul + self.cmp + self.minmax + self.div
    }
}

impl Add for OpCount {
    type Output = OpCount;
    fn add(self, o: OpCount) -> OpCount {
        OpCount {
            add: self.add + o.add,
            mul: self.mul + o.mul,
            cmp: self.cmp + o.cmp,
            minmax: self.minmax + o.minmax,
            div: self.div + o.div,
        }
    }
}

/// `ray_box` (single path; inputs rejected by the NaN/inf screen cost nothing):
/// 6 subtracts + 6 multiplies for the slabs, 6 min/max to reduce them together
/// with `t_min`/`t_max`, 1 multiply for the robust far scale, 1 final compare.
pub const RAY_BOX_OPS: OpCount = OpCount {
    add: 6,
    mul: 7,
    cmp: 1,
    minmax: 6,
    div: 0,
};

/// `ray_triangle` when the ray misses the edge test (the common early-out):
/// 9 subtracts (translate), 2 compares (dominant axis), 12 mul + 6 sub
/// (project 3 vertices), 6 mul + 3 sub (3 edge functions), 6 compares (signs).
pub const RAY_TRI_MISS_OPS: OpCount = OpCount {
    add: 18,
    mul: 18,
    cmp: 8,
    minmax: 0,
    div: 0,
};

/// `ray_triangle` when the edge test passes but det == 0 or the distance
/// pre-check fails (no division): the miss path plus 2 adds (det), 1 compare
/// (det == 0), 3 mul and 2 add (T), 1 mul (D), 2 mul (widened D), and 2 mul
/// with 2 compares (range pre-check).
pub const RAY_TRI_REJECT_OPS: OpCount = OpCount {
    add: 22,
    mul: 26,
    cmp: 11,
    minmax: 0,
    div: 0,
};

/// `ray_triangle` on the full hit path: reject path + 3 divides (t, u, v) +
/// 2 compares (exact range check of the divided t).
pub const RAY_TRI_OPS: OpCount = OpCount {
    add: 22,
    mul: 26,
    cmp: 13,
    minmax: 0,
    div: 3,
};

/// Inverse ray direction: one exact IEEE divide per component.
pub const DIV_OPS: OpCount = OpCount {
    add: 0,
    mul: 0,
    cmp: 0,
    minmax: 0,
    div: 3,
};

/// The scalar type the intersection arithmetic is written against. Implemented
/// for `f32` (what production code runs) and, in tests, for counting wrappers.
/// Arithmetic operators and comparisons are counted; the methods documented as
/// free are bit-level logic and must not be counted.
pub trait Scalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + PartialOrd
{
    /// Free: an input or constant enters the datapath.
    fn from_f32(x: f32) -> Self;
    /// Free: read the value back out.
    fn to_f32(self) -> f32;
    /// One minmax op: `if x > acc { x } else { acc }`. A NaN `x` never replaces
    /// `acc`, so a NaN candidate is ignored (used to neutralise 0*inf slabs).
    fn max_acc(acc: Self, x: Self) -> Self;
    /// One minmax op: `if x < acc { x } else { acc }` (NaN `x` ignored).
    fn min_acc(acc: Self, x: Self) -> Self;

    /// Free: sign-bit flip.
    #[inline(always)]
    fn neg(self) -> Self {
        Self::from_f32(-self.to_f32())
    }
    /// Free: clear the sign bit.
    #[inline(always)]
    fn abs(self) -> Self {
        Self::from_f32(self.to_f32().abs())
    }
    /// Free: the sign bit (true for -0.0 and -inf).
    #[inline(always)]
    fn sign_negative(self) -> bool {
        self.to_f32().is_sign_negative()
    }
    /// Free: exponent/mantissa classification.
    #[inline(always)]
    fn is_nan(self) -> bool {
        self.to_f32().is_nan()
    }
    /// Free: exponent classification.
    #[inline(always)]
    fn is_finite(self) -> bool {
        self.to_f32().is_finite()
    }
}

impl Scalar for f32 {
    #[inline(always)]
    fn from_f32(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline(always)]
    fn max_acc(acc: f32, x: f32) -> f32 {
        if x > acc { x } else { acc }
    }
    #[inline(always)]
    fn min_acc(acc: f32, x: f32) -> f32 {
        if x < acc { x } else { acc }
    }
}

#[cfg(test)]
pub(crate) mod counted {
    //! A counting f32 wrapper: every counted operation bumps a thread-local tally.
    use super::{OpCount, Scalar};
    use std::cell::Cell;
    use std::cmp::Ordering;
    use std::ops::{Add, Div, Mul, Sub};

    thread_local! {
        static TALLY: Cell<OpCount> = const { Cell::new(OpCount::ZERO) };
    }

    #[derive(Clone, Copy)]
    enum Kind {
        Add,
        Mul,
        Div,
        Cmp,
        MinMax,
    }

    fn bump(k: Kind) {
        TALLY.with(|t| {
            let mut c = t.get();
            match k {
                Kind::Add => c.add += 1,
                Kind::Mul => c.mul += 1,
                Kind::Div => c.div += 1,
                Kind::Cmp => c.cmp += 1,
                Kind::MinMax => c.minmax += 1,
            }
            t.set(c);
        });
    }

    /// Reset the tally, run `f`, return its result and the ops it performed.
    pub fn count<R>(f: impl FnOnce() -> R) -> (R, OpCount) {
        TALLY.with(|t| t.set(OpCount::ZERO));
        let r = f();
        (r, TALLY.with(|t| t.get()))
    }

    #[derive(Clone, Copy, Debug)]
    pub struct Counted(pub f32);

    impl Add for Counted {
        type Output = Counted;
        fn add(self, o: Counted) -> Counted {
            bump(Kind::Add);
            Counted(self.0 + o.0)
        }
    }
    impl Sub for Counted {
        type Output = Counted;
        fn sub(self, o: Counted) -> Counted {
            bump(Kind::Add);
            Counted(self.0 - o.0)
        }
    }
    impl Mul for Counted {
        type Output = Counted;
        fn mul(self, o: Counted) -> Counted {
            bump(Kind::Mul);
            Counted(self.0 * o.0)
        }
    }
    impl Div for Counted {
        type Output = Counted;
        fn div(self, o: Counted) -> Counted {
            bump(Kind::Div);
            Counted(self.0 / o.0)
        }
    }
    impl PartialEq for Counted {
        fn eq(&self, o: &Counted) -> bool {
            bump(Kind::Cmp);
            self.0 == o.0
        }
    }
    impl PartialOrd for Counted {
        // `<`, `<=`, `>`, `>=` all route through here: one compare each.
        fn partial_cmp(&self, o: &Counted) -> Option<Ordering> {
            bump(Kind::Cmp);
            self.0.partial_cmp(&o.0)
        }
    }
    impl Scalar for Counted {
        fn from_f32(x: f32) -> Counted {
            Counted(x)
        }
        fn to_f32(self) -> f32 {
            self.0
        }
        fn max_acc(acc: Counted, x: Counted) -> Counted {
            bump(Kind::MinMax);
            Counted(f32::max_acc(acc.0, x.0))
        }
        fn min_acc(acc: Counted, x: Counted) -> Counted {
            bump(Kind::MinMax);
            Counted(f32::min_acc(acc.0, x.0))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::counted::{Counted, count};
    use super::*;
    use crate::geom::aabb::ray_box_generic;
    use crate::geom::ray::inverse_dir_generic;
    use crate::geom::triangle::ray_triangle_generic;

    fn c3(v: [f32; 3]) -> [Counted; 3] {
        v.map(Counted)
    }

    fn boxc(o: [f32; 3], inv: [f32; 3], t0: f32, t1: f32) -> (Option<f32>, OpCount) {
        let (r, n) = count(|| {
            ray_box_generic(
                c3(o),
                c3(inv),
                Counted(t0),
                Counted(t1),
                c3([-1.0, -1.0, -1.0]),
                c3([1.0, 1.0, 1.0]),
            )
        });
        (r.map(|x| x.0), n)
    }

    #[test]
    fn ray_box_ops_match_code_on_hit_and_miss() {
        let (hit, n) = boxc(
            [-5.0, 0.0, 0.0],
            [1.0, f32::INFINITY, -f32::INFINITY],
            0.0,
            100.0,
        );
        assert_eq!(hit, Some(4.0));
        assert_eq!(n, RAY_BOX_OPS);
        let (miss, n) = boxc([-5.0, 3.0, 0.0], [1.0, 1.0, 1.0], 0.0, 100.0);
        assert_eq!(miss, None);
        assert_eq!(n, RAY_BOX_OPS);
        // Screened input: rejected before any arithmetic.
        let (nan, n) = boxc([f32::NAN, 0.0, 0.0], [1.0, 1.0, 1.0], 0.0, 1.0);
        assert_eq!(nan, None);
        assert_eq!(n, OpCount::ZERO);
    }

    fn tric(o: [f32; 3], d: [f32; 3], t0: f32, t1: f32) -> (Option<[f32; 3]>, OpCount) {
        let (r, n) = count(|| {
            ray_triangle_generic(
                c3(o),
                c3(d),
                Counted(t0),
                Counted(t1),
                [
                    c3([0.0, 0.0, 0.0]),
                    c3([4.0, 0.0, 0.0]),
                    c3([0.0, 4.0, 0.0]),
                ],
            )
        });
        (r.map(|h| h.map(|x| x.0)), n)
    }

    #[test]
    fn ray_tri_ops_match_code_on_each_path() {
        // Hit: t = 5, u = 0.25 (weight of v1), v = 0.5 (weight of v2).
        let (hit, n) = tric([1.0, 2.0, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
        assert_eq!(hit, Some([5.0, 0.25, 0.5]));
        assert_eq!(n, RAY_TRI_OPS);
        // Outside the edges: early out.
        let (miss, n) = tric([3.0, 3.0, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY);
        assert_eq!(miss, None);
        assert_eq!(n, RAY_TRI_MISS_OPS);
        // Inside the edges but beyond t_max: rejected before dividing.
        let (far, n) = tric([1.0, 2.0, 5.0], [0.0, 0.0, -1.0], 0.0, 4.0);
        assert_eq!(far, None);
        assert_eq!(n, RAY_TRI_REJECT_OPS);
        // Ray in the triangle's plane: det == 0, same cost as a reject.
        let (flat, n) = tric([-1.0, 1.0, 0.0], [1.0, 0.0, 0.0], 0.0, f32::INFINITY);
        assert_eq!(flat, None);
        assert_eq!(n, RAY_TRI_REJECT_OPS);
    }

    #[test]
    fn inverse_dir_ops_match_code() {
        let (inv, n) = count(|| inverse_dir_generic(c3([2.0, -0.0, 0.5])));
        assert_eq!(inv.map(|x| x.0), [0.5, f32::NEG_INFINITY, 2.0]);
        assert_eq!(n, DIV_OPS);
    }

    #[test]
    fn op_count_add_and_total() {
        let s = RAY_TRI_OPS + RAY_BOX_OPS;
        assert_eq!(s.add, 28);
        assert_eq!(s.total(), RAY_TRI_OPS.total() + RAY_BOX_OPS.total());
        assert_eq!(RAY_BOX_OPS.total(), 20);
        assert_eq!(RAY_TRI_OPS.total(), 64);
        assert_eq!(RAY_TRI_MISS_OPS.total(), 44);
        assert_eq!(DIV_OPS.total(), 3);
    }
}
