//! Pinhole camera and the automatic framing used when a scene gives no camera.

use glam::Vec3;

use crate::geom::shapes::sin_cos;
use crate::geom::{Aabb, MAX_VIEW_COORD, beyond};

/// A pinhole camera. `vfov_deg` is the full vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub vfov_deg: f32,
}

fn finite(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// `tan(deg/2)` without the platform libm (which differs between machines), so
/// primary rays are bit-identical everywhere.
pub(crate) fn tan_half_deg(deg: f32) -> f32 {
    let (s, c) = sin_cos(deg as f64 * (std::f64::consts::PI / 360.0));
    (s / c) as f32
}

/// `v / |v|`; zero or non-finite input gives a non-finite result (never panics).
fn unit(v: Vec3) -> Vec3 {
    let len = (v.x * v.x + v.y * v.y + v.z * v.z).sqrt();
    Vec3::new(v.x / len, v.y / len, v.z / len)
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

impl Camera {
    /// Checks that the camera defines a view. The messages say what to change.
    pub fn validate(&self) -> Result<(), super::SceneError> {
        for (name, v) in [
            ("eye", self.eye),
            ("look_at", self.look_at),
            ("up", self.up),
        ] {
            if !finite(v) {
                return Err(super::SceneError::Invalid(format!(
                    "camera {name} {v:?} is not finite; give three finite numbers"
                )));
            }
        }
        for (name, v) in [("eye", self.eye), ("look_at", self.look_at)] {
            if beyond(v, MAX_VIEW_COORD) {
                return Err(super::SceneError::Invalid(format!(
                    "camera {name} [{:?}, {:?}, {:?}] is beyond ±{MAX_VIEW_COORD:e}, the f32 datapath's limit \
                     for the camera and light (ray arithmetic would overflow); move it closer, \
                     or scale and recentre the scene",
                    v.x, v.y, v.z
                )));
            }
        }
        if !(self.vfov_deg > 0.0 && self.vfov_deg < 180.0) {
            return Err(super::SceneError::Invalid(format!(
                "camera vfov {} degrees is outside (0, 180); use e.g. 45",
                self.vfov_deg
            )));
        }
        let w = unit(self.look_at - self.eye);
        if self.eye == self.look_at || !finite(w) {
            return Err(super::SceneError::Invalid(format!(
                "camera eye and look_at are the same point {:?}; move one of them",
                self.eye
            )));
        }
        if self.up == Vec3::ZERO {
            return Err(super::SceneError::Invalid(
                "camera up is the zero vector; use e.g. [0, 1, 0]".to_string(),
            ));
        }
        let up = unit(self.up);
        if !finite(up) {
            return Err(super::SceneError::Invalid(format!(
                "camera up {:?} cannot be normalised in f32 (its squared length over- or \
                 underflows); give a vector of ordinary length, e.g. [0, 1, 0]",
                self.up
            )));
        }
        // sin of the angle between up and the view direction.
        if cross(w, up).length() < 1e-6 {
            return Err(super::SceneError::Invalid(format!(
                "camera up {:?} is parallel to the view direction {:?}; pick an up \
                 vector across the view, e.g. [0, 1, 0] or [0, 0, 1]",
                self.up, w
            )));
        }
        Ok(())
    }

    /// Orthonormal basis (right, true up, forward).
    fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let w = unit(self.look_at - self.eye);
        let u = unit(cross(w, self.up));
        let v = cross(u, w);
        (u, v, w)
    }

    /// Primary ray through pixel (px, py) of a width x height image, (0,0)
    /// top-left, jitter in [0,1)^2 within the pixel (0.5,0.5 = centre).
    /// Returns (origin, unit direction). Square pixels: the horizontal field of
    /// view follows from the aspect ratio. An invalid camera (see
    /// [`Camera::validate`]) or a zero size gives a non-finite direction.
    pub fn ray(
        &self,
        px: u32,
        py: u32,
        width: u32,
        height: u32,
        jitter: (f32, f32),
    ) -> (Vec3, Vec3) {
        let (u, v, w) = self.basis();
        let t = tan_half_deg(self.vfov_deg);
        let (wf, hf) = (width as f32, height as f32);
        let sx = (2.0 * (px as f32 + jitter.0) / wf - 1.0) * t * (wf / hf);
        let sy = (1.0 - 2.0 * (py as f32 + jitter.1) / hf) * t;
        let d = Vec3::new(
            w.x + sx * u.x + sy * v.x,
            w.y + sx * u.y + sy * v.y,
            w.z + sx * u.z + sy * v.z,
        );
        (self.eye, unit(d))
    }

    /// A camera looking along -z at the centre of `b` from in front (+z), far
    /// enough that the bounding sphere fits both fields of view.
    pub fn frame(b: &Aabb, vfov_deg: f32, aspect: f32) -> Camera {
        let c = b.centroid();
        let r = (b.extent().length() * 0.5).max(1e-6);
        let th = tan_half_deg(vfov_deg);
        let half = th.min(th * aspect);
        // Sphere of radius r fits a cone of half-angle a at distance r / sin a.
        let dist = r * (1.0 + half * half).sqrt() / half;
        Camera {
            eye: Vec3::new(c.x, c.y, c.z + dist),
            look_at: c,
            up: Vec3::Y,
            vfov_deg,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera {
            eye: Vec3::new(1.0, 2.0, 3.0),
            look_at: Vec3::new(1.0, 2.0, -7.0),
            up: Vec3::Y,
            vfov_deg: 60.0,
        }
    }

    #[test]
    fn tan_matches_libm() {
        for d in [1.0f32, 30.0, 45.0, 60.0, 89.2, 120.0, 179.0] {
            let want = (d as f64 / 2.0).to_radians().tan();
            assert!(
                ((tan_half_deg(d) as f64) - want).abs() < 1e-6 * want.max(1.0),
                "{d}"
            );
        }
    }

    #[test]
    fn centre_pixel_points_at_look_at() {
        let c = Camera {
            eye: Vec3::new(0.3, -1.0, 2.0),
            look_at: Vec3::new(4.0, 5.0, -6.0),
            up: Vec3::Z,
            vfov_deg: 40.0,
        };
        let (o, d) = c.ray(50, 20, 101, 41, (0.5, 0.5));
        assert_eq!(o, c.eye);
        let want = (c.look_at - c.eye).normalize();
        assert!((d - want).length() < 1e-6, "{d} vs {want}");
        assert!((d.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn corners_span_the_vfov_and_up_is_respected() {
        let c = cam();
        let (w, h) = (200, 100);
        // Top and bottom edge midpoints are vfov apart; top is towards +up.
        let (_, top) = c.ray(100, 0, w, h, (0.0, 0.0));
        let (_, bot) = c.ray(100, h - 1, w, h, (0.0, 1.0));
        let ang = top.dot(bot).clamp(-1.0, 1.0).acos().to_degrees();
        assert!((ang - 60.0).abs() < 1e-3, "{ang}");
        assert!(top.y > 0.0 && bot.y < 0.0);
        // Left/right edges span the horizontal fov from the aspect ratio.
        let (_, l) = c.ray(0, 50, w, h, (0.0, 0.0));
        let (_, r) = c.ray(w - 1, 50, w, h, (1.0, 0.0));
        let hfov = 2.0 * (2.0 * tan_half_deg(60.0)).atan().to_degrees();
        let ang = l.dot(r).clamp(-1.0, 1.0).acos().to_degrees();
        assert!((ang - hfov).abs() < 1e-3, "{ang} vs {hfov}");
        assert!(l.x < 0.0 && r.x > 0.0, "looking along -z, right is +x");
        // Flipping up flips the image vertically.
        let f = Camera { up: -Vec3::Y, ..c };
        let (_, ftop) = f.ray(100, 0, w, h, (0.0, 0.0));
        assert!(ftop.y < 0.0);
        // Deterministic bit patterns.
        assert_eq!(
            c.ray(3, 4, w, h, (0.25, 0.75)),
            c.ray(3, 4, w, h, (0.25, 0.75))
        );
    }

    #[test]
    fn validate_rejects_bad_cameras() {
        assert!(cam().validate().is_ok());
        let bad = [
            Camera {
                look_at: cam().eye,
                ..cam()
            },
            Camera {
                up: Vec3::Z,
                ..cam()
            },
            Camera {
                up: Vec3::ZERO,
                ..cam()
            },
            Camera {
                eye: Vec3::new(f32::NAN, 0.0, 0.0),
                ..cam()
            },
            Camera {
                vfov_deg: 0.0,
                ..cam()
            },
            Camera {
                vfov_deg: 180.0,
                ..cam()
            },
            Camera {
                vfov_deg: f32::NAN,
                ..cam()
            },
        ];
        let want = [
            "same point",
            "parallel",
            "zero vector",
            "not finite",
            "vfov",
            "vfov",
            "vfov",
        ];
        for (c, w) in bad.iter().zip(want) {
            let e = c.validate().unwrap_err().to_string();
            assert!(e.contains(w), "{e}");
            // Never panics, even on invalid cameras.
            let _ = c.ray(0, 0, 0, 0, (0.5, 0.5));
        }
    }

    #[test]
    fn frame_fits_the_bounds() {
        let b = Aabb::new(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 1.0, 0.0));
        let c = Camera::frame(&b, 45.0, 0.5);
        assert!(c.validate().is_ok());
        assert!(c.eye.z > b.max.z && c.look_at == b.centroid());
        // Every corner is inside the view frustum of a 50x100 image.
        let (u, v, w) = c.basis();
        let t = tan_half_deg(45.0);
        for i in 0..8 {
            let p = Vec3::new(
                if i & 1 != 0 { b.max.x } else { b.min.x },
                if i & 2 != 0 { b.max.y } else { b.min.y },
                if i & 4 != 0 { b.max.z } else { b.min.z },
            ) - c.eye;
            let z = p.dot(w);
            assert!(p.dot(u).abs() <= z * t * 0.5 && p.dot(v).abs() <= z * t);
        }
    }
}
