//! Geometry: rays, boxes, triangles and the bit-exact intersection tests.
//!
//! Everything here is pure f32 arithmetic written as explicit scalar steps in a
//! fixed order, with no fused multiply-add, so hardware-unit models and software
//! references get bit-identical results on every machine. The intersection
//! tests are written once over [`ops::Scalar`]: production code runs them on
//! `f32`, tests run them on a counting type so [`OpCount`] constants cannot drift.
//! NaN/inf inputs never hit and never panic.
pub mod aabb;
pub mod ops;
pub mod ray;
pub mod shapes;
pub mod triangle;

pub use aabb::{Aabb, ray_box};
pub use ops::OpCount;
pub use ops::{DIV_OPS, RAY_BOX_OPS, RAY_TRI_MISS_OPS, RAY_TRI_OPS, RAY_TRI_REJECT_OPS};
pub use ray::{Hit, Ray, closest, inverse_dir};
pub use triangle::{TriHit, Triangle, ray_triangle};

/// Largest |coordinate| of a mesh vertex (world space) the f32 datapath takes.
///
/// The ray-triangle test multiplies coordinate differences up to five deep, and
/// shadow rays are not normalised (direction = light - hit point, t in [0, 1]).
/// With vertices and hit points within M and the light within V (see
/// [`MAX_VIEW_COORD`]), per component: `a = v - o` <= 2M, `d` <= M + V, the
/// projection `P` <= 2 * 2M * (M + V), the edge functions `E` <= 2 P^2, the
/// distance numerator `T` <= 3 E * 2M and the denominator `D` <= 3 E (M + V).
/// M = 1e6 and V = 1e7 give P <= 4.4e13, E <= 3.9e27, T <= 2.3e34 and
/// D <= 1.3e35: finite, 2,600 times below f32::MAX (3.4e38); ten times farther
/// out, D could reach 1.3e40 and overflow. (Unit camera and bounce rays from within V reach
/// T <= 3.2e22; the slab test, normals and SAH areas are squares at most.)
pub const MAX_COORD: f32 = 1e6;

/// Largest |coordinate| of the camera's eye and look-at point and of the light
/// (the V of [`MAX_COORD`]). The automatic framing of a mesh within
/// [`MAX_COORD`] at an aspect ratio of 1 or wider stays within it: the light's
/// coordinates reach at most 4.5 M, the eye's 5.6 M.
pub const MAX_VIEW_COORD: f32 = 1e7;

/// Boxes and segment exits are culled only beyond this distance from the best hit
/// so far. The box test may place a box's entry a few ulps after a hit on a triangle
/// inside it (independent roundings), and a tie on a shared edge must still reach
/// the triangle with the smaller id, so culling keeps a margin of 2^-16 relative
/// (triangle tests themselves use the exact best t, inclusively).
#[inline]
pub fn cull(t: f32) -> f32 {
    t * (1.0 + 1.0 / 65536.0)
}

/// Whether a coordinate of `v` exceeds `limit` in magnitude (NaN does).
pub fn beyond(v: glam::Vec3, limit: f32) -> bool {
    !(v.x.abs() <= limit && v.y.abs() <= limit && v.z.abs() <= limit)
}
