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
