//! Triangles and the watertight, division-deferred ray-triangle test.
//!
//! Formulation: Plücker edge tests (Shevtsov et al. 2007, as in the paper)
//! evaluated in a ray-aligned 2-D frame (the projection of Woop, Benthin, Wald
//! 2013, "Watertight Ray/Triangle Intersection", but scaled instead of divided,
//! so no division happens before a hit).
//!
//! 1. Translate the vertices by the ray origin: `a = v0 - o`, `b = v1 - o`,
//!    `c = v2 - o`. Distances are now small numbers even far from the world
//!    origin, and every vertex is translated identically in every triangle.
//! 2. Pick `kz` = the axis of largest `|d|` and `kx, ky` = the next two axes
//!    cyclically. Project each vertex along `d`:
//!    `P(p) = (p[kx]*d[kz] - p[kz]*d[kx], p[ky]*d[kz] - p[kz]*d[ky])`.
//!    These are two components of the Plücker moment `p x d`; the ray itself
//!    projects to the 2-D origin exactly.
//! 3. Edge functions `E(p, q) = P(p).x*P(q).y - P(p).y*P(q).x`:
//!    `U = E(b, c)`, `V = E(c, a)`, `W = E(a, b)`. Each equals
//!    `d[kz] * (d . (p x q))`, i.e. the Plücker permuted inner product of the
//!    ray with the edge line, scaled by the same `d[kz]` for all edges.
//!
//! Why this is watertight: `P(p)` depends only on the ray and that one vertex,
//! so a vertex shared by several triangles projects to bit-identical 2-D points.
//! `E` is a 2-D orientation test of those points against the exact 2-D origin,
//! computed as `fl(fl(xy) - fl(zw))`. Rounding is monotonic, so if `xy > zw`
//! then `fl(xy) >= fl(zw)`, and the sign of a rounded difference is exact: the
//! computed sign is either the exact sign (for the rounded points) or zero —
//! never the opposite sign. Zero is accepted by both sides. Hence the computed
//! tests are those of one consistent exact 2-D configuration, plus extra hits
//! on ties: a ray through a shared edge or a shared fan vertex hits at least one
//! of the triangles. (`E(q, p) = -E(p, q)` bit-exactly as well.) In the plain
//! 3-D form `d . (p x q)` the three-term dot product can round to the wrong
//! sign, which leaks at fan vertices.
//!
//! Double-sided acceptance: all of U, V, W >= 0 or all <= 0, and
//! `det = U + V + W != 0` (zero means a degenerate projection: a zero-area
//! triangle or a ray in its plane). With same-sign U, V, W, `|det| >= |U|, |V|,
//! |W|`, so the barycentrics come out in [0, 1].
//!
//! Distance without division: `T = U*a[kz] + V*b[kz] + W*c[kz]` and
//! `D = det * d[kz]`, so `t = T / D`. The signs of T and D are normalised
//! (D > 0, a sign flip), the range is pre-checked as `t_min*D <= T <= t_max*D`
//! (with D widened by 2 ulps either way so the pre-check is conservative),
//! and only then `t = T/D`, `u = V/det` (weight of v1), `v = W/det` (weight of
//! v2) are divided out; finally `t_min <= t <= t_max` is checked on the rounded
//! `t` so the returned distance is exactly within the range.
//!
//! Range: intermediate values scale like |a|^3 |d|^2; vertex distances beyond
//! ~1e12 from the ray origin overflow and return None (never a false hit).

use glam::Vec3;

use super::aabb::Aabb;
use super::ops::Scalar;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub v0: Vec3,
    pub v1: Vec3,
    pub v2: Vec3,
}

impl Triangle {
    pub fn new(v0: Vec3, v1: Vec3, v2: Vec3) -> Triangle {
        Triangle { v0, v1, v2 }
    }

    /// Tight bounds of the three vertices.
    pub fn aabb(&self) -> Aabb {
        Aabb::from_points([self.v0, self.v1, self.v2])
    }

    /// Any non-finite coordinate, or `(v1 - v0) x (v2 - v0)` rounds to exactly
    /// zero (repeated vertices, exactly collinear edges, underflowed area) or
    /// overflows. Builders should drop these: the intersection test rejects
    /// them only when their projection is exactly degenerate.
    pub fn is_degenerate(&self) -> bool {
        let vs = [self.v0, self.v1, self.v2];
        if vs
            .iter()
            .any(|v| !(v.x.is_finite() && v.y.is_finite() && v.z.is_finite()))
        {
            return true;
        }
        let n = self.normal();
        let finite = n.x.is_finite() && n.y.is_finite() && n.z.is_finite();
        !finite || (n.x == 0.0 && n.y == 0.0 && n.z == 0.0)
    }

    /// Unnormalised normal `(v1 - v0) x (v2 - v0)` (counter-clockwise winding
    /// faces towards it), written out scalar by scalar.
    pub fn normal(&self) -> Vec3 {
        let e1 = Vec3::new(
            self.v1.x - self.v0.x,
            self.v1.y - self.v0.y,
            self.v1.z - self.v0.z,
        );
        let e2 = Vec3::new(
            self.v2.x - self.v0.x,
            self.v2.y - self.v0.y,
            self.v2.z - self.v0.z,
        );
        Vec3::new(
            e1.y * e2.z - e1.z * e2.y,
            e1.z * e2.x - e1.x * e2.z,
            e1.x * e2.y - e1.y * e2.x,
        )
    }

    /// `v0 + u*(v1 - v0) + v*(v2 - v0)`, in that fixed order.
    pub fn point_at(&self, u: f32, v: f32) -> Vec3 {
        let (a, b, c) = (self.v0, self.v1, self.v2);
        Vec3::new(
            a.x + u * (b.x - a.x) + v * (c.x - a.x),
            a.y + u * (b.y - a.y) + v * (c.y - a.y),
            a.z + u * (b.z - a.z) + v * (c.z - a.z),
        )
    }
}

/// Result of [`ray_triangle`]: distance and the barycentrics of v1 (u), v2 (v).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// Watertight, double-sided ray/triangle test (see the module docs). Returns a
/// hit with `t_min <= t <= t_max` (the rounded `t`; -0.0 for a hit exactly at
/// the origin), `u, v` in [0, 1]; None on a miss, on a degenerate projection,
/// or if any input is NaN/inf (`t_max` may be +inf).
pub fn ray_triangle(
    origin: Vec3,
    dir: Vec3,
    t_min: f32,
    t_max: f32,
    tri: &Triangle,
) -> Option<TriHit> {
    let v = |p: Vec3| [p.x, p.y, p.z];
    ray_triangle_generic(
        v(origin),
        v(dir),
        t_min,
        t_max,
        [v(tri.v0), v(tri.v1), v(tri.v2)],
    )
    .map(|[t, u, v]| TriHit { t, u, v })
}

/// `1 - 2^-22`: widens the pre-division range check downwards. See [`WIDEN_UP`].
pub const WIDEN_DOWN: f32 = 1.0 - 4.0 * (f32::EPSILON * 0.5);

/// `1 + 2^-22`: widens the pre-division range check upwards, so that it never
/// rejects a hit whose divided, rounded `t` lies in `[t_min, t_max]`. With
/// unit roundoff u: `fl(T/D) <= t_max` implies `T <= t_max*D*(1+u)`, while the
/// computed bound `fl(t_max * fl(D*(1+4u)))` is at least `t_max*D*(1+2u)`
/// (symmetrically for `t_min`). Without this, a triangle re-tested with
/// `t_max` equal to its own hit distance could be rejected, breaking the
/// equal-`t` smaller-id tie rule. Assumes `t_min >= 0` and normal (not
/// subnormal) magnitudes.
pub const WIDEN_UP: f32 = 1.0 + 4.0 * (f32::EPSILON * 0.5);

/// `p.x*q.y - p.y*q.x`: 2 mul, 1 sub. The one expression shape used for all edges.
#[inline(always)]
fn edge<S: Scalar>(p: [S; 2], q: [S; 2]) -> S {
    p[0] * q[1] - p[1] * q[0]
}

/// [`ray_triangle`] over any [`Scalar`]; returns `[t, u, v]`. Operation order
/// (counts in `RAY_TRI_MISS_OPS`, `RAY_TRI_REJECT_OPS`, `RAY_TRI_OPS`):
/// ```text
/// screen inputs (bit logic)
/// a, b, c = v - o per component                      9 sub
/// kz = |dx| > |dy| ? (|dx| > |dz| ? x : z)
///                  : (|dy| > |dz| ? y : z)           2 cmp (ties -> later axis)
/// P(p) for a, b, c                                   12 mul, 6 sub
/// U = E(Pb,Pc), V = E(Pc,Pa), W = E(Pa,Pb)           6 mul, 3 sub
/// pos = U>=0 & V>=0 & W>=0; neg = U<=0 & V<=0 & W<=0 6 cmp (all evaluated)
/// -- miss if !(pos | neg) --
/// det = (U + V) + W                                  2 add
/// T = (U*a[kz] + V*b[kz]) + W*c[kz]                  3 mul, 2 add
/// D = det * d[kz]                                    1 mul
/// if sign(D): T = -T, D = -D                         (sign flip)
/// D_lo = D * WIDEN_DOWN ; D_hi = D * WIDEN_UP         2 mul
/// ok = det != 0 & T >= t_min*D_lo & T <= t_max*D_hi  2 mul, 3 cmp (all evaluated)
/// -- reject if !ok --
/// t = T / D ; u = V / det ; v = W / det              3 div
/// hit iff t >= t_min & t <= t_max & all finite       2 cmp
/// ```
#[inline(always)]
pub fn ray_triangle_generic<S: Scalar>(
    o: [S; 3],
    d: [S; 3],
    t_min: S,
    t_max: S,
    tri: [[S; 3]; 3],
) -> Option<[S; 3]> {
    let all_finite = |p: &[S; 3]| p[0].is_finite() && p[1].is_finite() && p[2].is_finite();
    if !all_finite(&o)
        || !all_finite(&d)
        || !tri.iter().all(all_finite)
        || !t_min.is_finite()
        || t_max.is_nan()
    {
        return None;
    }
    let [v0, v1, v2] = tri;
    let a = [v0[0] - o[0], v0[1] - o[1], v0[2] - o[2]];
    let b = [v1[0] - o[0], v1[1] - o[1], v1[2] - o[2]];
    let c = [v2[0] - o[0], v2[1] - o[1], v2[2] - o[2]];

    let (ax, ay, az) = (d[0].abs(), d[1].abs(), d[2].abs());
    let kz = if ax > ay {
        if ax > az { 0 } else { 2 }
    } else if ay > az {
        1
    } else {
        2
    };
    let kx = (kz + 1) % 3;
    let ky = (kz + 2) % 3;
    let (dx, dy, dz) = (d[kx], d[ky], d[kz]);
    let project = |p: [S; 3]| [p[kx] * dz - p[kz] * dx, p[ky] * dz - p[kz] * dy];
    let pa = project(a);
    let pb = project(b);
    let pc = project(c);

    let u_e = edge(pb, pc);
    let v_e = edge(pc, pa);
    let w_e = edge(pa, pb);

    let zero = S::from_f32(0.0);
    let pos = (u_e >= zero) & (v_e >= zero) & (w_e >= zero);
    let neg = (u_e <= zero) & (v_e <= zero) & (w_e <= zero);
    if !(pos | neg) {
        return None;
    }

    let det = (u_e + v_e) + w_e;
    let mut t_num = (u_e * a[kz] + v_e * b[kz]) + w_e * c[kz];
    let mut d_den = det * dz;
    if d_den.sign_negative() {
        t_num = t_num.neg();
        d_den = d_den.neg();
    }
    let d_lo = d_den * S::from_f32(WIDEN_DOWN);
    let d_hi = d_den * S::from_f32(WIDEN_UP);
    let ok = (det != zero) & (t_num >= t_min * d_lo) & (t_num <= t_max * d_hi);
    if !ok {
        return None;
    }

    let t = t_num / d_den;
    let u = v_e / det;
    let v = w_e / det;
    let in_range = (t >= t_min) & (t <= t_max);
    if in_range && t.is_finite() && u.is_finite() && v.is_finite() {
        Some([t, u, v])
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> Triangle {
        Triangle::new(
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 4.0, 0.0),
        )
    }

    #[test]
    fn simple_hit_exact_values() {
        let h = ray_triangle(
            Vec3::new(1.0, 2.0, 5.0),
            Vec3::new(0.0, 0.0, -1.0),
            0.0,
            f32::INFINITY,
            &tri(),
        )
        .unwrap();
        assert_eq!(
            h,
            TriHit {
                t: 5.0,
                u: 0.25,
                v: 0.5
            }
        );
        // Back side, unnormalised direction: double-sided, t in units of |dir|.
        let h = ray_triangle(
            Vec3::new(1.0, 2.0, -5.0),
            Vec3::new(0.0, 0.0, 2.0),
            0.0,
            f32::INFINITY,
            &tri(),
        )
        .unwrap();
        assert_eq!(
            h,
            TriHit {
                t: 2.5,
                u: 0.25,
                v: 0.5
            }
        );
    }

    #[test]
    fn simple_misses() {
        let t = tri();
        let down = Vec3::new(0.0, 0.0, -1.0);
        assert!(ray_triangle(Vec3::new(3.0, 3.0, 5.0), down, 0.0, f32::INFINITY, &t).is_none());
        assert!(ray_triangle(Vec3::new(1.0, 1.0, 5.0), -down, 0.0, f32::INFINITY, &t).is_none());
        assert!(ray_triangle(Vec3::new(1.0, 1.0, 5.0), down, 0.0, 4.5, &t).is_none());
        assert!(ray_triangle(Vec3::new(1.0, 1.0, 5.0), down, 5.5, 9.0, &t).is_none());
        // Range boundaries are inclusive.
        assert!(ray_triangle(Vec3::new(1.0, 1.0, 5.0), down, 5.0, 5.0, &t).is_some());
    }

    #[test]
    fn widen_constants_are_two_ulps() {
        assert_eq!(WIDEN_UP.to_bits(), 0x3F80_0002);
        assert_eq!(WIDEN_DOWN.to_bits(), 0x3F7F_FFFC);
    }

    #[test]
    fn retest_at_own_distance_still_hits() {
        // The pre-division check is widened, so t_min = t_max = the hit's own
        // rounded t is accepted (needed for equal-t tie resolution).
        let t = Triangle::new(
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(3.7, -0.4, 1.1),
            Vec3::new(-0.6, 2.9, -1.3),
        );
        let o = Vec3::new(0.3, 0.7, 9.1);
        for i in 0..200 {
            let s = i as f32 / 200.0;
            let d = Vec3::new(0.5 * s - 0.2, 0.3 - 0.4 * s, -1.0 - s);
            if let Some(h) = ray_triangle(o, d, 0.0, f32::INFINITY, &t) {
                assert_eq!(ray_triangle(o, d, h.t, h.t, &t), Some(h));
            }
        }
    }

    #[test]
    fn degenerate_and_aabb() {
        let t = tri();
        assert!(!t.is_degenerate());
        assert_eq!(t.normal(), Vec3::new(0.0, 0.0, 16.0));
        assert_eq!(t.aabb().min, Vec3::ZERO);
        assert_eq!(t.aabb().max, Vec3::new(4.0, 4.0, 0.0));
        assert_eq!(t.point_at(0.25, 0.5), Vec3::new(1.0, 2.0, 0.0));
        let line = Triangle::new(Vec3::ZERO, Vec3::ONE, Vec3::splat(2.0));
        assert!(line.is_degenerate());
        let rep = Triangle::new(Vec3::ONE, Vec3::ONE, Vec3::X);
        assert!(rep.is_degenerate());
        let nan = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::NAN, 0.0));
        assert!(nan.is_degenerate());
        let huge = Triangle::new(Vec3::ZERO, Vec3::X * 3e38, Vec3::Y * 3e38);
        assert!(huge.is_degenerate());
    }

    /// An f32 that records the largest magnitude any operation produces.
    mod peak {
        use crate::geom::ops::Scalar;
        use std::cell::Cell;
        use std::ops::{Add, Div, Mul, Sub};

        thread_local! {
            static PEAK: Cell<f32> = const { Cell::new(0.0) };
        }

        #[derive(Clone, Copy, PartialEq, PartialOrd)]
        pub struct Peak(pub f32);

        fn seen(x: f32) -> Peak {
            // NaN and inf are recorded as inf.
            PEAK.with(|p| {
                p.set(if x.is_finite() {
                    p.get().max(x.abs())
                } else {
                    f32::INFINITY
                })
            });
            Peak(x)
        }

        /// The largest magnitude produced while running `f`.
        pub fn peak(f: impl FnOnce()) -> f32 {
            PEAK.with(|p| p.set(0.0));
            f();
            PEAK.with(|p| p.get())
        }

        impl Add for Peak {
            type Output = Peak;
            fn add(self, o: Peak) -> Peak {
                seen(self.0 + o.0)
            }
        }
        impl Sub for Peak {
            type Output = Peak;
            fn sub(self, o: Peak) -> Peak {
                seen(self.0 - o.0)
            }
        }
        impl Mul for Peak {
            type Output = Peak;
            fn mul(self, o: Peak) -> Peak {
                seen(self.0 * o.0)
            }
        }
        impl Div for Peak {
            type Output = Peak;
            fn div(self, o: Peak) -> Peak {
                seen(self.0 / o.0)
            }
        }
        impl Scalar for Peak {
            fn from_f32(x: f32) -> Peak {
                Peak(x)
            }
            fn to_f32(self) -> f32 {
                self.0
            }
            fn max_acc(acc: Peak, x: Peak) -> Peak {
                Peak(f32::max_acc(acc.0, x.0))
            }
            fn min_acc(acc: Peak, x: Peak) -> Peak {
                Peak(f32::min_acc(acc.0, x.0))
            }
        }
    }

    /// The datapath's coordinate limits keep every intermediate of the triangle
    /// test finite in the worst case: a shadow ray from one corner of the
    /// vertex range to a light at the far corner of the view range, against
    /// triangles spanning the vertex range; ten times farther out, it overflows.
    #[test]
    fn coordinate_limits_keep_the_triangle_test_finite() {
        use super::super::{MAX_COORD, MAX_VIEW_COORD};
        use peak::{Peak, peak};
        let worst = |m: f32, v: f32| {
            let mut most = 0.0f32;
            for s in [1.0f32, -1.0] {
                let o = [-m * s, -m * s, -m * s];
                let light = [v * s, v * s, v * s * 0.999];
                let d = [light[0] - o[0], light[1] - o[1], light[2] - o[2]];
                let tris = [
                    [[m, -m, m], [-m, m, -m], [m, m, -m]],
                    [[m * s, m * s, -m * s], [-m, m, m], [m, -m, -m]],
                    [[0.5 * m, m, m], [m, 0.5 * m, -m], [-m, -m, m]],
                ];
                for tri in tris {
                    let p = |a: [f32; 3]| a.map(Peak);
                    most = most.max(peak(|| {
                        let _ = ray_triangle_generic(p(o), p(d), Peak(0.0), Peak(1.0), tri.map(p));
                    }));
                }
            }
            most
        };
        let at_limit = worst(MAX_COORD, MAX_VIEW_COORD);
        assert!(at_limit < f32::MAX / 1000.0, "{at_limit:e}");
        assert!(at_limit > 1e33, "the worst case is exercised: {at_limit:e}");
        assert!(worst(10.0 * MAX_COORD, 10.0 * MAX_VIEW_COORD).is_infinite());
    }
}
