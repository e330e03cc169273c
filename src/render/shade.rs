//! Shading: what happens to a path at each hit, and the numerics it needs
//! (per-pixel random numbers, robust ray offsets, cosine sampling), all
//! deterministic and free of platform maths libraries.

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

/// Next uniform number in [0, 1) from a path's state (SplitMix64 stream).
#[inline]
pub fn next_f32(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    (mix64(*state) >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Moves a surface point off the surface along `n` so that a ray leaving it does not
/// hit the surface again (Wächter & Binder, Ray Tracing Gems ch. 6): an integer ulp
/// offset far from the origin, a small float offset near it.
pub fn offset_ray(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let comp = |p: f32, n: f32| {
        let of = (INT_SCALE * n) as i32;
        let pi = f32::from_bits(
            (p.to_bits() as i32).wrapping_add(if p < 0.0 { -of } else { of }) as u32,
        );
        if p.abs() < ORIGIN {
            p + FLOAT_SCALE * n
        } else {
            pi
        }
    };
    Vec3::new(comp(p.x, n.x), comp(p.y, n.y), comp(p.z, n.z))
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

/// Geometric normal of a triangle, facing against the incoming direction.
pub fn facing_normal(v: &[Vec3; 3], dir: Vec3) -> Vec3 {
    let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
    if n.dot(dir) > 0.0 { -n } else { n }
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
            let n = facing_normal(&tri.v, path.dir);
            // The hit point from the barycentrics, on the triangle's plane (Wächter &
            // Binder's offset assumes a point computed this way).
            let hitp = tri.v[0] + (tri.v[1] - tri.v[0]) * h.u + (tri.v[2] - tri.v[0]) * h.v;
            let o = offset_ray(hitp, n);
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
    fn offset_leaves_the_surface_far_from_the_origin() {
        let tri = crate::geom::Triangle::new(
            Vec3::new(148376.0, 1234.0, -223423.0),
            Vec3::new(148377.0, 1234.0, -223423.0),
            Vec3::new(148376.0, 1235.0, -223423.0),
        );
        let n = Vec3::Z;
        let p = tri.point_at(0.25, 0.25);
        let o = offset_ray(p, n);
        // A ray leaving the offset point along the hemisphere must not re-hit.
        for d in [
            Vec3::Z,
            Vec3::new(1.0, 0.0, 0.01).normalize(),
            Vec3::new(-0.7, 0.7, 0.05).normalize(),
        ] {
            assert!(
                crate::geom::ray_triangle(o, d, 0.0, f32::INFINITY, &tri).is_none(),
                "{d:?}"
            );
        }
    }
}
