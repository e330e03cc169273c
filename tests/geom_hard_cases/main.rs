//! Hard cases for the bit-exact geometry: conservative box test, watertight
//! triangle test, leak tests on closed meshes near and far from the origin,
//! secondary rays spawned inside closed spheres, determinism. Every assertion
//! here fails if the corresponding property breaks.

mod boxes;
mod determinism;
mod leaks;
mod spawn;
mod triangles;

use dualstream::accel::{Bvh, BvhCfg};
use dualstream::contract::{HitRec, PATH_BOUNCE_IN_FLIGHT, PathRec, TriRec};
use dualstream::geom::aabb::ray_box_generic;
use dualstream::geom::ops::Scalar;
use dualstream::geom::shapes::{box_mesh, icosphere, quad, uv_sphere};
use dualstream::geom::triangle::ray_triangle_generic;
use dualstream::geom::*;
use dualstream::util::rng::Rng;
use glam::Vec3;
use std::ops::{Add, Div, Mul, Sub};

const INF: f32 = f32::INFINITY;
const FAR: Vec3 = Vec3::new(148376.0, 1234.0, -223423.0);

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

fn bx(o: Vec3, d: Vec3, b: &Aabb) -> Option<f32> {
    ray_box(o, inverse_dir(d), 0.0, INF, b)
}

fn tri_hit(o: Vec3, d: Vec3, t: &Triangle) -> Option<TriHit> {
    ray_triangle(o, d, 0.0, INF, t)
}

fn set(p: Vec3, k: usize, x: f32) -> Vec3 {
    let mut a = p.to_array();
    a[k] = x;
    Vec3::from_array(a)
}

/// Random non-zero direction, uniform-ish over directions (not normalised).
fn rand_dir(rng: &mut Rng) -> Vec3 {
    loop {
        let d = v(
            rng.range_f32(-1.0, 1.0),
            rng.range_f32(-1.0, 1.0),
            rng.range_f32(-1.0, 1.0),
        );
        let l2 = d.x * d.x + d.y * d.y + d.z * d.z;
        if l2 > 0.01 && l2 <= 1.0 {
            return d;
        }
    }
}

fn rand_in_cube(rng: &mut Rng, c: Vec3, h: f32) -> Vec3 {
    v(
        c.x + rng.range_f32(-h, h),
        c.y + rng.range_f32(-h, h),
        c.z + rng.range_f32(-h, h),
    )
}

/// Componentwise `p - q` (explicit, f32).
fn sub(p: Vec3, q: Vec3) -> Vec3 {
    v(p.x - q.x, p.y - q.y, p.z - q.z)
}

/// Edge midpoint computed in f32 as `(p + q) * 0.5`.
fn mid(p: Vec3, q: Vec3) -> Vec3 {
    v((p.x + q.x) * 0.5, (p.y + q.y) * 0.5, (p.z + q.z) * 0.5)
}

fn dot(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}
