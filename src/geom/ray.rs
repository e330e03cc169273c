//! Rays, hit records and the closest-hit order.

use glam::Vec3;

use super::ops::Scalar;

/// A ray segment `origin + t * dir` for `t` in `[t_min, t_max]`. `dir` need not be
/// normalised: the hardware never normalises, so distances are in units of |dir|.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    /// Ray over `[0, +inf]`.
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray {
            origin,
            dir,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }

    /// Same ray with a different `[t_min, t_max]`.
    pub fn with_range(self, t_min: f32, t_max: f32) -> Ray {
        Ray {
            t_min,
            t_max,
            ..self
        }
    }

    /// Finite origin/dir, non-zero dir, `0 <= t_min <= t_max` (`t_max` may be
    /// +inf). The intersection tests tolerate invalid rays (they return None);
    /// this is for producers that want to reject them up front.
    pub fn is_valid(&self) -> bool {
        let o = self.origin;
        let d = self.dir;
        let finite = o.x.is_finite()
            && o.y.is_finite()
            && o.z.is_finite()
            && d.x.is_finite()
            && d.y.is_finite()
            && d.z.is_finite();
        let nonzero = d.x != 0.0 || d.y != 0.0 || d.z != 0.0;
        finite
            && nonzero
            && self.t_min.is_finite()
            && self.t_min >= 0.0
            && !self.t_max.is_nan()
            && self.t_min <= self.t_max
    }

    /// The inverse direction the box test needs (see [`inverse_dir`]).
    pub fn inv_dir(&self) -> Vec3 {
        inverse_dir(self.dir)
    }

    /// `origin + t * dir`, componentwise as `o + t*d` (one rounding per step, no FMA).
    pub fn at(&self, t: f32) -> Vec3 {
        let o = self.origin;
        let d = self.dir;
        Vec3::new(o.x + t * d.x, o.y + t * d.y, o.z + t * d.z)
    }
}

/// Per component `1.0 / x`, exactly as the shared hardware divider computes it:
/// +0 -> +inf and -0 -> -inf, which the box test relies on to keep the slab
/// orientation of axis-parallel rays.
pub fn inverse_dir(dir: Vec3) -> Vec3 {
    let [x, y, z] = inverse_dir_generic([dir.x, dir.y, dir.z]);
    Vec3::new(x, y, z)
}

/// [`inverse_dir`] over any [`Scalar`] (3 divides, see `DIV_OPS`).
#[inline(always)]
pub fn inverse_dir_generic<S: Scalar>(d: [S; 3]) -> [S; 3] {
    let one = S::from_f32(1.0);
    [one / d[0], one / d[1], one / d[2]]
}

/// A closest-hit record: distance, triangle id and barycentrics of v1 (u), v2 (v).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub tri_id: u32,
    pub u: f32,
    pub v: f32,
}

impl Hit {
    /// The single closest-hit order used everywhere: by `t`, then the smaller
    /// `tri_id` wins on equal `t`. A total order on valid hits, so the result does
    /// not depend on the order in which triangles were tested (which differs
    /// between the baseline and the dual-streaming traversal). A NaN `t` is never
    /// closer.
    pub fn closer_than(&self, other: &Hit) -> bool {
        self.t < other.t || (self.t == other.t && self.tri_id < other.tri_id)
    }
}

/// The closer of two optional hits under [`Hit::closer_than`]. Hits with a NaN
/// distance are dropped so the result is symmetric in its arguments.
pub fn closest(a: Option<Hit>, b: Option<Hit>) -> Option<Hit> {
    let a = a.filter(|h| !h.t.is_nan());
    let b = b.filter(|h| !h.t.is_nan());
    match (a, b) {
        (Some(x), Some(y)) => Some(if y.closer_than(&x) { y } else { x }),
        (x, None) => x,
        (None, y) => y,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(t: f32, id: u32) -> Hit {
        Hit {
            t,
            tri_id: id,
            u: 0.0,
            v: 0.0,
        }
    }

    #[test]
    fn ray_new_and_validity() {
        let r = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(r.t_min, 0.0);
        assert_eq!(r.t_max, f32::INFINITY);
        assert!(r.is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::ZERO).is_valid());
        assert!(!Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X).is_valid());
        assert!(!Ray::new(Vec3::ZERO, Vec3::new(f32::INFINITY, 0.0, 0.0)).is_valid());
        assert!(!r.with_range(-1.0, 1.0).is_valid());
        assert!(!r.with_range(2.0, 1.0).is_valid());
        assert!(!r.with_range(0.0, f32::NAN).is_valid());
        assert!(!r.with_range(f32::INFINITY, f32::INFINITY).is_valid());
        assert!(r.with_range(1.0, 1.0).is_valid());
        assert_eq!(r.at(2.5), Vec3::new(2.5, 0.0, 0.0));
    }

    #[test]
    fn inverse_dir_keeps_signed_zero() {
        let i = inverse_dir(Vec3::new(0.0, -0.0, 4.0));
        assert_eq!(i.x, f32::INFINITY);
        assert_eq!(i.y, f32::NEG_INFINITY);
        assert_eq!(i.z, 0.25);
        let j = inverse_dir(Vec3::new(f32::INFINITY, f32::NAN, -2.0));
        assert_eq!(j.x.to_bits(), 0.0f32.to_bits());
        assert!(j.y.is_nan());
        assert_eq!(j.z, -0.5);
    }

    #[test]
    fn closer_than_is_lexicographic() {
        assert!(h(1.0, 9).closer_than(&h(2.0, 0)));
        assert!(!h(2.0, 0).closer_than(&h(1.0, 9)));
        assert!(h(1.0, 3).closer_than(&h(1.0, 4)));
        assert!(!h(1.0, 4).closer_than(&h(1.0, 3)));
        assert!(!h(1.0, 4).closer_than(&h(1.0, 4)));
        // -0 and +0 are the same distance: id decides.
        assert!(h(-0.0, 1).closer_than(&h(0.0, 2)));
        assert!(!h(f32::NAN, 0).closer_than(&h(1.0, 1)));
        assert!(!h(1.0, 1).closer_than(&h(f32::NAN, 0)));
    }

    #[test]
    fn closest_is_symmetric() {
        let cases = [
            (Some(h(1.0, 2)), Some(h(1.0, 1)), Some(h(1.0, 1))),
            (Some(h(0.5, 7)), Some(h(1.0, 1)), Some(h(0.5, 7))),
            (None, Some(h(3.0, 0)), Some(h(3.0, 0))),
            (Some(h(f32::NAN, 0)), Some(h(3.0, 5)), Some(h(3.0, 5))),
            (Some(h(f32::NAN, 0)), None, None),
            (None, None, None),
        ];
        for (a, b, want) in cases {
            assert_eq!(closest(a, b), want);
            assert_eq!(closest(b, a), want);
        }
    }
}
