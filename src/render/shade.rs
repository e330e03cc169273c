//! Shading: what happens to a path at each hit, and the numerics it needs
//! (per-pixel random numbers, robust ray offsets, cosine sampling), all
//! deterministic and free of platform maths libraries.

use glam::Vec3;

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
