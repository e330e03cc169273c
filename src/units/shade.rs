//! Shading: what happens to a path at each hit, and the numerics it needs
//! (per-pixel random numbers, robust ray offsets, cosine sampling), all
//! deterministic and free of platform maths libraries. One step, two callers:
//! the TPs run it between wavefronts (`tp_shade`), the host runs the same
//! function in functional mode and with `chip.shading = "host"`.

use glam::Vec3;

use crate::contract::{
    HitRec, PATH_BOUNCE_IN_FLIGHT, PATH_SHADOW_IN_FLIGHT, PathRec, RayRec, SHADOW_BIT, TriRec,
};
use crate::geom::shapes::sin_cos;

/// SplitMix64 finaliser: a good 64-bit mix.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The random state a pixel's path starts with.
pub fn pixel_seed(seed: u64, pixel: u32) -> u64 {
    mix64(seed ^ mix64(pixel as u64 + 0x9E37_79B9_7F4A_7C15))
}

/// The seed of a pixel's path `sample` (of its `spp`): the frame's own for
/// the first, so one path per pixel is the frame without samples.
pub fn sample_seed(seed: u64, sample: u32) -> u64 {
    if sample == 0 {
        seed
    } else {
        mix64(seed ^ mix64(0xD1B5_4A32_D192_ED03 ^ sample as u64))
    }
}

/// Next uniform number in [0, 1) from a path's state (SplitMix64 stream).
#[inline]
pub fn next_f32(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    (mix64(*state) >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Unit roundoff ε of f32 (2^-24): a correctly rounded operation's relative error.
const UNIT: f32 = f32::EPSILON * 0.5;

/// Scale of the hit point's rounding-error bound (2ε; see [`hit_point`]).
const HIT_POINT_ERR: f32 = 2.0 * UNIT;

/// Scale of the triangle test's own error term in the offset (2^-18 = 64ε; see [`spawn`]).
const TRI_TEST_ERR: f32 = 64.0 * UNIT;

/// Cap on the sliver factor `L^2 / |N|` of the triangle-test term: it keeps the
/// offset of a near-degenerate triangle below ~0.4% of its size instead of
/// throwing the ray across the scene (an apex angle below ~0.1 degree).
const SLIVER_CAP: f32 = 1024.0;

/// Moves `p` off its surface by at least `h` along the unit normal `n`: each
/// coordinate moves by `n_i * h` and is then rounded one float further away from
/// `p` (pbrt-v4's `OffsetRayOrigin`), so the rounding of the sum never gives back
/// part of the offset. A coordinate with `n_i = 0` stays.
pub fn offset_ray(p: Vec3, n: Vec3, h: f32) -> Vec3 {
    let comp = |p: f32, n: f32| {
        if n > 0.0 {
            (p + n * h).next_up()
        } else if n < 0.0 {
            (p + n * h).next_down()
        } else {
            p
        }
    };
    Vec3::new(comp(p.x, n.x), comp(p.y, n.y), comp(p.z, n.z))
}

/// The hit point at barycentrics `(u, w)` (of `v[1]`, `v[2]`) and a bound on its
/// rounding error per coordinate. Per coordinate `p = v0 + (u*e1 + w*e2)`
/// (`e1 = v1 - v0`, `e2 = v2 - v0`; the small terms are summed first, so `v0`
/// costs one rounding) is within `ε|p| + 3ε(|u*e1| + |w*e2|)` of the exact point
/// for the same barycentrics, to first order (ε = 2^-24). That point lies on the
/// triangle's plane whatever error the barycentrics carry. The bound returned is
/// `2ε (|p| + 2(|u*e1| + |w*e2|))`, from the computed terms.
pub fn hit_point(v: &[Vec3; 3], u: f32, w: f32) -> (Vec3, Vec3) {
    let (m, k) = ((v[1] - v[0]) * u, (v[2] - v[0]) * w);
    let p = v[0] + (m + k);
    (p, (p.abs() + (m.abs() + k.abs()) * 2.0) * HIT_POINT_ERR)
}

/// Where the rays leaving a bounce hit start: the geometric normal facing against
/// the incoming direction `dir`, and the hit point ([`hit_point`]) moved off the
/// triangle's plane along it by the sum of
/// - `h_p`, the hit point's error bound along the normal, `|n| . err`;
/// - a bound on the triangle test's own error for a ray starting that close to
///   the plane (`geom::triangle`, t_min = 0): its computed `t` has the exact sign
///   when the origin is farther than `(13 + 48 L^2/|N|) ε L` from the plane, to
///   first order (`L`: the largest distance of a vertex from the ray origin, in
///   the max norm; `|N| = |e1 x e2|`). Used: `64ε L (1 + min(L^2/|N|, 1024))` with
///   `L = max|e1_i| + max|e2_i| + h_p`.
///
/// docs/data-contract.md ("Ray spawn offset") has the derivation. Shading
/// (functional and the TPs' kernel) calls this once per bounce hit; the shadow and
/// the bounce ray both leave from the returned origin.
pub fn spawn(v: &[Vec3; 3], u: f32, w: f32, dir: Vec3) -> (Vec3, Vec3) {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let cross = e1.cross(e2);
    let inv_len = cross.length_recip();
    let n = cross * inv_len;
    let n = if n.dot(dir) > 0.0 { -n } else { n };
    let (p, err) = hit_point(v, u, w);
    let h_p = n.abs().dot(err);
    let l = e1.abs().max_element() + e2.abs().max_element() + h_p;
    let sliver = (l * l * inv_len).min(SLIVER_CAP);
    (n, offset_ray(p, n, h_p + TRI_TEST_ERR * l * (1.0 + sliver)))
}

/// Pixel `real`'s camera ray (jittered by its first two random numbers) and the
/// path state it starts with, for a `w` x `h` frame rendered with `seed`.
pub fn primary_path(
    camera: &crate::scene::Camera,
    seed: u64,
    real: u32,
    w: u32,
    h: u32,
) -> (Vec3, Vec3, PathRec) {
    let mut rng = pixel_seed(seed, real);
    let jitter = (next_f32(&mut rng), next_f32(&mut rng));
    let (o, d) = camera.ray(real % w, real / w, w, h, jitter);
    let path = PathRec {
        throughput: Vec3::ONE,
        pending: Vec3::ZERO,
        radiance: Vec3::ZERO,
        dir: d,
        rng,
        depth: 0,
        flags: PATH_BOUNCE_IN_FLIGHT,
    };
    (o, d, path)
}

/// Orthonormal basis around a unit normal (Duff et al. 2017, branchless).
pub fn basis(n: Vec3) -> (Vec3, Vec3) {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3::new(b, s + n.y * n.y * a, -n.y),
    )
}

/// Cosine-weighted direction around `n` from two uniforms: for a Lambertian surface
/// the weight f·cos/pdf is exactly the albedo.
pub fn cosine_sample(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let (s, c) = sin_cos(2.0 * std::f64::consts::PI * u2 as f64);
    let (x, y, z) = (r * c as f32, r * s as f32, (1.0 - u1).max(0.0).sqrt());
    let (t, b) = basis(n);
    (t * x + b * y + n * z).normalize()
}

/// The scene constants a shading step needs: the shading pass's control
/// registers (loaded by the host before the pass, like a GPU's uniforms).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeConsts {
    pub light_pos: Vec3,
    pub light_intensity: Vec3,
    pub sky: Vec3,
    /// Hit points per path (the scene's `bounces`).
    pub bounces: u32,
    /// The root segment's entry reference every new ray starts from.
    pub root_entry: u32,
}

/// The result of shading one pixel's finished rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeOut {
    pub path: PathRec,
    /// The next wavefront's rays, shadow first (the order the host emits them).
    pub shadow: Option<RayRec>,
    pub bounce: Option<RayRec>,
    /// The shadow ray of the previous hit was blocked.
    pub occluded: bool,
    /// The bounce ray hit a surface.
    pub hit: bool,
}

/// Which hit records a shading step reads, from the path's flags: (shadow, bounce).
pub fn shade_reads(path: &PathRec) -> (bool, bool) {
    (
        path.flags & PATH_SHADOW_IN_FLIGHT != 0,
        path.flags & PATH_BOUNCE_IN_FLIGHT != 0,
    )
}

/// One shading step of pixel `pix`, as a pure function of what it read: the path
/// record, the hit records of its shadow and bounce rays (`None` when not in
/// flight), and for a bounce hit the triangle and its material's albedo. The host
/// (functional mode) and the TPs (cycle mode) both call it, so images agree bit
/// for bit.
pub fn shade_step(
    c: &ShadeConsts,
    pix: u32,
    mut path: PathRec,
    shadow_hit: Option<HitRec>,
    bounce_hit: Option<HitRec>,
    surface: Option<(&TriRec, Vec3)>,
) -> ShadeOut {
    let mut out = ShadeOut {
        path,
        shadow: None,
        bounce: None,
        occluded: false,
        hit: false,
    };
    // The shadow ray from the previous hit: its contribution, if the light is visible.
    if let Some(h) = shadow_hit {
        if h.is_hit() {
            out.occluded = true;
        } else {
            path.radiance += path.pending;
        }
        path.pending = Vec3::ZERO;
        path.flags &= !PATH_SHADOW_IN_FLIGHT;
    }
    if let Some(h) = bounce_hit {
        path.flags &= !PATH_BOUNCE_IN_FLIGHT;
        if !h.is_hit() {
            path.radiance += path.throughput * c.sky;
        } else {
            out.hit = true;
            let (tri, albedo) = surface.expect("a bounce hit is shaded with its triangle");
            let (n, o) = spawn(&tri.v, h.u, h.v, path.dir);
            let to_light = c.light_pos - o;
            let d2 = to_light.length_squared();
            let cos = n.dot(to_light) / d2.sqrt();
            if cos > 0.0 && d2 > 0.0 {
                path.pending = path.throughput
                    * albedo
                    * (std::f32::consts::FRAC_1_PI * cos / d2)
                    * c.light_intensity;
                path.flags |= PATH_SHADOW_IN_FLIGHT;
                out.shadow = Some(RayRec {
                    origin: o,
                    dir: to_light,
                    ray_id: pix | SHADOW_BIT,
                    entry: c.root_entry,
                });
            }
            path.depth += 1;
            if (path.depth as u32) < c.bounces {
                let (u1, u2) = (next_f32(&mut path.rng), next_f32(&mut path.rng));
                let d = cosine_sample(n, u1, u2);
                path.throughput *= albedo;
                path.flags |= PATH_BOUNCE_IN_FLIGHT;
                out.bounce = Some(RayRec {
                    origin: o,
                    dir: d,
                    ray_id: pix,
                    entry: c.root_entry,
                });
                path.dir = d;
            }
        }
    }
    out.path = path;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_numbers_are_uniform_enough_and_deterministic() {
        let mut s = pixel_seed(1, 7);
        let mut t = pixel_seed(1, 7);
        let xs: Vec<f32> = (0..10_000).map(|_| next_f32(&mut s)).collect();
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        let mean = xs.iter().sum::<f32>() / xs.len() as f32;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
        assert_eq!(next_f32(&mut t), xs[0]);
        assert_ne!(pixel_seed(1, 7), pixel_seed(1, 8));
    }

    #[test]
    fn cosine_samples_stay_in_the_hemisphere() {
        let mut s = 5;
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
        ] {
            let mut mean_cos = 0.0;
            for _ in 0..2000 {
                let d = cosine_sample(n, next_f32(&mut s), next_f32(&mut s));
                assert!((d.length() - 1.0).abs() < 1e-5);
                assert!(d.dot(n) >= -1e-6);
                mean_cos += d.dot(n);
            }
            // E[cos] under a cosine-weighted distribution is 2/3.
            assert!(
                (mean_cos / 2000.0 - 2.0 / 3.0).abs() < 0.02,
                "{}",
                mean_cos / 2000.0
            );
        }
    }

    #[test]
    fn offset_moves_each_coordinate_at_least_its_share_away() {
        let n = Vec3::new(0.6, -0.8, 0.0);
        // Far from the origin a tiny offset rounds back to p; one float further
        // still moves it, and along n only.
        let p = Vec3::new(148376.0, 1234.0, -223423.0);
        let o = offset_ray(p, n, 1e-9);
        assert_eq!(o.x, p.x.next_up());
        assert_eq!(o.y, p.y.next_down());
        assert_eq!(o.z, p.z);
        // A larger one: at least n_i * h in each coordinate.
        let q = Vec3::new(0.3, -2.0, 7.0);
        let o = offset_ray(q, n, 0.125);
        assert!(o.x - q.x >= 0.6 * 0.125 && q.y - o.y >= 0.8 * 0.125);
        assert_eq!(o.z, q.z);
        // Signed zeros and exact zeros of p move too (next float from zero).
        let o = offset_ray(Vec3::new(-0.0, 0.0, 0.0), Vec3::Y, 0.0);
        assert_eq!(o.to_array().map(f32::to_bits), [0x8000_0000, 1, 0]);
    }

    /// Rays in the whole hemisphere around the spawn normal, grazing ones included.
    fn hemisphere(n: Vec3) -> impl Iterator<Item = Vec3> {
        let mut s = 9;
        (0..400).map(move |i| {
            // Every fourth at the largest u1 a path can draw: the most grazing.
            let u1 = if i % 4 == 0 {
                1.0 - UNIT * 2.0
            } else {
                next_f32(&mut s)
            };
            cosine_sample(n, u1, next_f32(&mut s))
        })
    }

    /// The height of `o` above the triangle's plane on the side of `n`, in f64 (exact
    /// to far below the offsets checked).
    fn height(t: &crate::geom::Triangle, n: Vec3, o: Vec3) -> f64 {
        let (a, b, c) = (t.v0.as_dvec3(), t.v1.as_dvec3(), t.v2.as_dvec3());
        let m = (b - a).cross(c - a).normalize();
        let m = if m.dot(n.as_dvec3()) < 0.0 { -m } else { m };
        m.dot(o.as_dvec3() - a)
    }

    #[test]
    fn spawned_rays_leave_the_triangle_near_and_far_from_the_origin() {
        use crate::geom::{Triangle, ray_triangle};
        let far = Vec3::new(148376.0, 1234.0, -223423.0);
        let tris = [
            // Tilted, far: the hit point's rounding dominates the offset.
            Triangle::new(
                far,
                far + Vec3::new(1.0, 0.25, 0.0),
                far + Vec3::new(0.0, 1.0, 1.0),
            ),
            // In the plane y = 0: the hit point is exact, the triangle test's own
            // error alone needs the offset.
            Triangle::new(
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 0.0, -1.0),
                Vec3::new(1.0, 0.0, 3.0),
            ),
            // A sliver (apex ~0.6 degrees) through the origin.
            Triangle::new(
                Vec3::new(-0.5, -0.25, 0.1),
                Vec3::new(1.5, 0.75, -0.1),
                Vec3::new(1.5, 0.77, -0.08),
            ),
        ];
        for (k, t) in tris.iter().enumerate() {
            let v = [t.v0, t.v1, t.v2];
            for (u, w) in [
                (0.25, 0.25),
                (0.0, 0.0),
                (1.0, 0.0),
                (0.5, 0.5),
                (0.01, 0.98),
            ] {
                for dir in [Vec3::new(0.1, -1.0, 0.2), Vec3::new(-0.1, 1.0, -0.3)] {
                    let (n, o) = spawn(&v, u, w, dir);
                    assert!(n.dot(dir) < 0.0);
                    assert!(height(t, n, o) > 0.0, "triangle {k}: {o:?} below");
                    for d in hemisphere(n) {
                        assert!(
                            ray_triangle(o, d, 0.0, f32::INFINITY, t).is_none(),
                            "triangle {k} ({u}, {w}): re-hit along {d:?}"
                        );
                    }
                }
            }
        }
    }

    /// The triangle-test term is needed: with the hit point's error bound alone
    /// (pbrt-v4's offset, whose triangle test rejects t below its own error bound,
    /// which ours does not), rays leaving a triangle in the plane y = 0 re-hit it.
    #[test]
    fn the_hit_point_bound_alone_re_hits_an_exact_plane() {
        use crate::geom::{Triangle, ray_triangle};
        let t = Triangle::new(
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 3.0),
        );
        let (n, o) = spawn(&[t.v0, t.v1, t.v2], 0.3, 0.4, -Vec3::Y);
        assert_eq!(n, Vec3::Y);
        let (p, err) = hit_point(&[t.v0, t.v1, t.v2], 0.3, 0.4);
        let pbrt = offset_ray(p, n, n.abs().dot(err));
        assert_eq!(
            pbrt.y,
            0.0f32.next_up(),
            "exact in y: only the rounding moves it"
        );
        let rehits = |o: Vec3| {
            hemisphere(n)
                .filter(|&d| ray_triangle(o, d, 0.0, f32::INFINITY, &t).is_some())
                .count()
        };
        assert!(rehits(pbrt) > 0);
        assert_eq!(rehits(o), 0);
        assert!(o.y > 1e-6 && o.y < 1e-3, "{o:?}");
    }
}
