//! Axis-aligned boxes and the conservative slab test.

use glam::Vec3;

use super::ops::Scalar;

/// Unit roundoff of f32 (half an ulp of 1.0).
const EPS: f32 = f32::EPSILON * 0.5;

/// gamma(n) = n*eps / (1 - n*eps): the relative error bound of n rounded f32
/// operations (Pharr/Jakob/Humphreys; Ize 2013).
const fn gamma(n: f32) -> f32 {
    (n * EPS) / (1.0 - n * EPS)
}

/// `1 + 2*gamma(3)` rounded to f32 (= 1 + 3*2^-23). Each slab distance carries at
/// most three roundings (the divide that made `inv_dir`, the subtract, the
/// multiply), so a computed near may be too large by gamma(3) and a computed far
/// too small by gamma(3); growing far by 2*gamma(3) closes the gap (Ize 2013,
/// "Robust BVH Ray Traversal").
pub const ROBUST_SCALE: f32 = 1.0 + 2.0 * gamma(3.0);

/// A box given by its min and max corners. `min > max` on any axis is empty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

#[inline(always)]
fn lower(a: f32, b: f32) -> f32 {
    if b < a { b } else { a }
}

#[inline(always)]
fn upper(a: f32, b: f32) -> f32 {
    if b > a { b } else { a }
}

impl Aabb {
    /// The identity for `union`/`grow`: min = +inf, max = -inf.
    pub fn empty() -> Aabb {
        Aabb {
            min: Vec3::splat(f32::INFINITY),
            max: Vec3::splat(f32::NEG_INFINITY),
        }
    }

    pub fn new(min: Vec3, max: Vec3) -> Aabb {
        Aabb { min, max }
    }

    /// Smallest box holding all points (empty for no points). NaN coordinates
    /// are ignored (they never compare smaller/larger).
    pub fn from_points<I: IntoIterator<Item = Vec3>>(points: I) -> Aabb {
        let mut b = Aabb::empty();
        for p in points {
            b.grow(p);
        }
        b
    }

    /// Extend to include `p` (exact: only compares and selects).
    pub fn grow(&mut self, p: Vec3) {
        self.min = Vec3::new(
            lower(self.min.x, p.x),
            lower(self.min.y, p.y),
            lower(self.min.z, p.z),
        );
        self.max = Vec3::new(
            upper(self.max.x, p.x),
            upper(self.max.y, p.y),
            upper(self.max.z, p.z),
        );
    }

    /// Smallest box holding both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: Vec3::new(
                lower(self.min.x, o.min.x),
                lower(self.min.y, o.min.y),
                lower(self.min.z, o.min.z),
            ),
            max: Vec3::new(
                upper(self.max.x, o.max.x),
                upper(self.max.y, o.max.y),
                upper(self.max.z, o.max.z),
            ),
        }
    }

    /// Finite corners with `min <= max` on every axis (zero thickness allowed).
    pub fn is_valid(&self) -> bool {
        let (a, b) = (self.min, self.max);
        a.x.is_finite()
            && a.y.is_finite()
            && a.z.is_finite()
            && b.x.is_finite()
            && b.y.is_finite()
            && b.z.is_finite()
            && a.x <= b.x
            && a.y <= b.y
            && a.z <= b.z
    }

    /// True if `p` lies in the closed box.
    pub fn contains(&self, p: Vec3) -> bool {
        self.min.x <= p.x
            && p.x <= self.max.x
            && self.min.y <= p.y
            && p.y <= self.max.y
            && self.min.z <= p.z
            && p.z <= self.max.z
    }

    /// `max - min` per axis.
    pub fn extent(&self) -> Vec3 {
        Vec3::new(
            self.max.x - self.min.x,
            self.max.y - self.min.y,
            self.max.z - self.min.z,
        )
    }

    /// `(min + max) * 0.5` per axis.
    pub fn centroid(&self) -> Vec3 {
        Vec3::new(
            (self.min.x + self.max.x) * 0.5,
            (self.min.y + self.max.y) * 0.5,
            (self.min.z + self.max.z) * 0.5,
        )
    }

    /// `2 * (x*y + y*z + z*x)` of the extent, for SAH builders (0 if invalid).
    pub fn surface_area(&self) -> f32 {
        if !self.is_valid() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * ((e.x * e.y + e.y * e.z) + e.z * e.x)
    }
}

/// Slab test (Williams et al. 2005, as in the paper) with a precomputed inverse
/// direction. Returns the entry distance `max(t_min, t_near)` on a hit.
///
/// Conservative — never a false miss against the exact box and ray segment:
/// - direction components ±0 give `inv = ±inf`; the near/far planes are chosen by
///   the sign bit of `inv` (so -0 behaves as a negative direction);
/// - an origin exactly on a slab plane with a zero direction component gives
///   `0 * inf = NaN`, which the NaN-ignoring min/max reduction treats as
///   unconstraining, so rays on (or grazing along) a face still hit;
/// - rounding: the final far distance is multiplied by [`ROBUST_SCALE`].
///   Because that scale also applies to `t_max`, a box starting up to 3 ulps
///   beyond `t_max` may be reported (harmless over-inclusion).
///
/// Inputs: origin and box must be finite, `t_min` finite, `inv_dir` and `t_max`
/// not NaN; otherwise None. The guarantee assumes `t_min >= 0` (as for a valid
/// [`Ray`](super::Ray)). The entry distance itself is not rounded down: it is
/// within gamma(3) (relative) of the exact entry.
#[inline]
pub fn ray_box(origin: Vec3, inv_dir: Vec3, t_min: f32, t_max: f32, b: &Aabb) -> Option<f32> {
    ray_box_generic(
        [origin.x, origin.y, origin.z],
        [inv_dir.x, inv_dir.y, inv_dir.z],
        t_min,
        t_max,
        [b.min.x, b.min.y, b.min.z],
        [b.max.x, b.max.y, b.max.z],
    )
}

/// [`ray_box`] for a ray and box screened already: finite origin and box, no NaN
/// in `inv`, `t_min` finite (what [`ray_box`] checks first, on every call). The
/// same operations in the same order, so the same result; a NaN `t_max` needs no
/// screen (`far` stays NaN and `near <= far` fails, as the screen's `None`). The
/// functional traversal screens a ray once per segment and the boxes once per
/// segment load, not on every test (docs/results/2026-11-27-speed-error-the-functional-traversal-s-box-screen-and-the-dragon-box-aga.md).
#[inline(always)]
pub fn ray_box_screened(
    o: Vec3,
    inv: Vec3,
    t_min: f32,
    t_max: f32,
    bmin: Vec3,
    bmax: Vec3,
) -> Option<f32> {
    slabs(
        o.to_array(),
        inv.to_array(),
        t_min,
        t_max,
        bmin.to_array(),
        bmax.to_array(),
    )
}

/// [`ray_box`] over any [`Scalar`]. Exact operation sequence (`RAY_BOX_OPS`):
/// ```text
/// screen inputs (bit logic)                  -> None on NaN/inf as documented
/// near = t_min ; far = t_max
/// for k in x, y, z:
///     (pn, pf) = sign(inv[k]) ? (max[k], min[k]) : (min[k], max[k])   // mux
///     tn = (pn - o[k]) * inv[k]              // 1 sub, 1 mul
///     tf = (pf - o[k]) * inv[k]              // 1 sub, 1 mul
///     near = tn > near ? tn : near           // 1 minmax, NaN ignored
///     far  = tf < far  ? tf : far            // 1 minmax, NaN ignored
/// far = far * ROBUST_SCALE                   // 1 mul
/// hit iff near <= far                        // 1 cmp ; return near
/// ```
#[inline(always)]
pub fn ray_box_generic<S: Scalar>(
    o: [S; 3],
    inv: [S; 3],
    t_min: S,
    t_max: S,
    bmin: [S; 3],
    bmax: [S; 3],
) -> Option<S> {
    for k in 0..3 {
        if !o[k].is_finite() || inv[k].is_nan() || !bmin[k].is_finite() || !bmax[k].is_finite() {
            return None;
        }
    }
    if !t_min.is_finite() || t_max.is_nan() {
        return None;
    }
    slabs(o, inv, t_min, t_max, bmin, bmax)
}

/// The box test after its input screen: the slabs, the robust scale, the compare
/// (shared by [`ray_box_generic`] and [`ray_box_screened`]).
#[inline(always)]
fn slabs<S: Scalar>(
    o: [S; 3],
    inv: [S; 3],
    t_min: S,
    t_max: S,
    bmin: [S; 3],
    bmax: [S; 3],
) -> Option<S> {
    let mut near = t_min;
    let mut far = t_max;
    for k in 0..3 {
        let (pn, pf) = if inv[k].sign_negative() {
            (bmax[k], bmin[k])
        } else {
            (bmin[k], bmax[k])
        };
        let tn = (pn - o[k]) * inv[k];
        let tf = (pf - o[k]) * inv[k];
        near = S::max_acc(near, tn);
        far = S::min_acc(far, tf);
    }
    let far = far * S::from_f32(ROBUST_SCALE);
    if near <= far { Some(near) } else { None }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::ray::inverse_dir;

    fn unit() -> Aabb {
        Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    fn hit(o: Vec3, d: Vec3, b: &Aabb) -> Option<f32> {
        ray_box(o, inverse_dir(d), 0.0, f32::INFINITY, b)
    }

    /// The screened test gives `ray_box`'s bits wherever its screen passes: hard
    /// cases (axis-parallel rays with infinite inverses, origins on a slab's plane
    /// so 0 * inf is NaN, degenerate boxes, signed zeros, NaN and infinite limits)
    /// and random ones.
    #[test]
    fn screened_box_test_is_the_box_test_on_screened_inputs() {
        let vals = [0.0f32, -0.0, 1.0, -1.0, 0.5, 3.0, -2.0, 1e-30, 1e30];
        let dirs = [0.0f32, -0.0, 1.0, -1.0, 1e-40, -3.0];
        let limits = [f32::INFINITY, 0.0, 2.0, 1e-3, f32::NAN];
        let same = |o: Vec3, d: Vec3, tmax: f32, b: &Aabb| {
            let inv = inverse_dir(d);
            if !inv.is_nan() {
                let a = ray_box(o, inv, 0.0, tmax, b);
                let s = ray_box_screened(o, inv, 0.0, tmax, b.min, b.max);
                assert_eq!(
                    a.map(f32::to_bits),
                    s.map(f32::to_bits),
                    "o {o} d {d} t_max {tmax} box {b:?}"
                );
            }
        };
        let b = unit();
        for &x in &vals {
            for &dx in &dirs {
                for &dy in &dirs {
                    for &t in &limits {
                        same(Vec3::new(x, 1.0, -x), Vec3::new(dx, dy, 1.0), t, &b);
                        same(Vec3::new(-1.0, x, 0.0), Vec3::new(dx, dy, -dx), t, &b);
                        let flat = Aabb::new(Vec3::new(x, -1.0, 0.0), Vec3::new(x, 1.0, 0.0));
                        same(Vec3::new(x, 0.0, -5.0), Vec3::new(dx, 0.0, dy), t, &flat);
                    }
                }
            }
        }
        let mut r = crate::util::rng::Rng::new(7);
        let mut f = |s: f32| (r.unit_f32() - 0.5) * s;
        for _ in 0..20_000 {
            let p = Vec3::new(f(4.0), f(4.0), f(4.0));
            let b = Aabb::from_points([p, p + Vec3::new(f(2.0), f(2.0), f(2.0))]);
            let o = Vec3::new(f(10.0), f(10.0), f(10.0));
            let d = Vec3::new(f(2.0), f(2.0), f(2.0));
            let t = f(20.0).abs();
            same(o, d, t, &b);
            // Grazing: aimed at a corner, where near and far meet within rounding
            // and the robust scale decides.
            let corner = Vec3::new(b.min.x, b.max.y, b.min.z);
            same(o, corner - o, t, &b);
            same(o, corner - o, f32::INFINITY, &b);
        }
    }

    #[test]
    fn robust_scale_is_three_ulps_above_one() {
        assert_eq!(ROBUST_SCALE.to_bits(), 0x3F80_0003);
    }

    #[test]
    fn basic_hits_and_misses() {
        let b = unit();
        assert_eq!(hit(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, &b), Some(4.0));
        assert_eq!(hit(Vec3::new(5.0, 0.0, 0.0), -Vec3::X, &b), Some(4.0));
        assert_eq!(hit(Vec3::ZERO, Vec3::Y, &b), Some(0.0));
        assert_eq!(hit(Vec3::new(-5.0, 0.0, 0.0), -Vec3::X, &b), None);
        assert_eq!(hit(Vec3::new(-5.0, 2.0, 0.0), Vec3::X, &b), None);
        // Diagonal through a corner region.
        assert!(hit(Vec3::splat(-3.0), Vec3::ONE, &b).is_some());
    }

    #[test]
    fn aabb_helpers() {
        let mut b = Aabb::empty();
        assert!(!b.is_valid());
        assert_eq!(b.surface_area(), 0.0);
        b.grow(Vec3::new(1.0, 2.0, 3.0));
        assert!(b.is_valid());
        assert_eq!(b.min, b.max);
        b.grow(Vec3::new(-1.0, 5.0, f32::NAN));
        assert_eq!(b.min, Vec3::new(-1.0, 2.0, 3.0));
        assert_eq!(b.max, Vec3::new(1.0, 5.0, 3.0));
        let c = Aabb::from_points([Vec3::ZERO, Vec3::new(4.0, -1.0, 2.0)]);
        let u = b.union(&c);
        assert_eq!(u.min, Vec3::new(-1.0, -1.0, 0.0));
        assert_eq!(u.max, Vec3::new(4.0, 5.0, 3.0));
        assert_eq!(u.union(&Aabb::empty()), u);
        assert_eq!(u.extent(), Vec3::new(5.0, 6.0, 3.0));
        assert_eq!(u.centroid(), Vec3::new(1.5, 2.0, 1.5));
        assert_eq!(u.surface_area(), 2.0 * (30.0 + 18.0 + 15.0));
        assert!(u.contains(Vec3::new(4.0, 5.0, 3.0)));
        assert!(!u.contains(Vec3::new(4.0, 5.0, 3.5)));
        assert!(!Aabb::new(Vec3::ZERO, Vec3::new(1.0, f32::INFINITY, 1.0)).is_valid());
    }
}
