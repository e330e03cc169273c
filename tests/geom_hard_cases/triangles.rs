//! The watertight ray-triangle test: shared edges and vertices never leak,
//! degenerates and bad inputs are no hit, the t range is exact, ties go to the smaller id.

use super::*;

#[test]
fn triangle_shared_diagonal_of_quad_never_leaks() {
    let mut rng = Rng::new(21);
    for center in [Vec3::ZERO, FAR] {
        let (a, b, c, d) = (
            v(center.x - 1.0, center.y - 1.0, center.z),
            v(center.x + 1.5, center.y - 1.0, center.z + 0.25),
            v(center.x + 1.0, center.y + 1.25, center.z),
            v(center.x - 1.25, center.y + 1.0, center.z - 0.5),
        );
        let q = quad(a, b, c, d);
        for i in 0..2000 {
            // Away from the corners, where a target rounded off the diagonal
            // could fall outside the quad.
            let s = rng.range_f32(0.02, 0.98);
            let target = match i % 3 {
                0 => v(
                    a.x + s * (c.x - a.x),
                    a.y + s * (c.y - a.y),
                    a.z + s * (c.z - a.z),
                ),
                1 => mid(a, c),
                _ => v(
                    c.x + s * (a.x - c.x),
                    c.y + s * (a.y - c.y),
                    c.z + s * (a.z - c.z),
                ),
            };
            // From above or below, at least ~30 degrees off the plane.
            let side = if i % 2 == 0 { 1.0 } else { -1.0 };
            let o = v(
                target.x + rng.range_f32(-3.0, 3.0),
                target.y + rng.range_f32(-3.0, 3.0),
                target.z + side * rng.range_f32(2.5, 6.0),
            );
            let dir = sub(target, o);
            let n = q.iter().filter(|t| tri_hit(o, dir, t).is_some()).count();
            assert!(
                n >= 1,
                "ray through shared diagonal leaked: o {o:?} d {dir:?}"
            );
        }
    }
}

#[test]
fn triangle_random_shared_edge_pairs_never_leak() {
    let mut rng = Rng::new(22);
    let mut checked = 0;
    for pair in 0..400 {
        let center = if pair % 2 == 0 { Vec3::ZERO } else { FAR };
        let p = rand_in_cube(&mut rng, center, 2.0);
        let q = rand_in_cube(&mut rng, center, 2.0);
        let e = sub(q, p);
        // Build a frame around the edge and place r1, r2 on opposite sides.
        let mut side = rand_dir(&mut rng);
        let k = dot(side, e) / dot(e, e);
        side = v(side.x - k * e.x, side.y - k * e.y, side.z - k * e.z);
        // Unit side vector: the two triangles are tilted at most ~11 degrees from
        // a common plane, and the rays come within ~27 degrees of its normal, so
        // the pair never folds over in the ray's view (a fold would be a
        // legitimate silhouette miss, not a leak).
        side /= side.length();
        let normal = e.cross(side);
        let m = mid(p, q);
        let bend = rng.range_f32(-0.3, 0.3);
        let r1 = m + side * 1.5 + normal * (bend / normal.length());
        let r2 = m - side * 1.2 + normal * (bend / normal.length());
        let t1 = Triangle::new(p, q, r1);
        let t2 = Triangle::new(q, p, r2);
        let nunit = normal / normal.length();
        for i in 0..25 {
            // Stay away from the edge ends: far from the origin the f32 target can
            // be ~0.01 off the edge, which near an end is outside both triangles.
            let s = rng.range_f32(0.05, 0.95);
            let target = if i == 0 {
                m
            } else {
                v(p.x + s * e.x, p.y + s * e.y, p.z + s * e.z)
            };
            // Origin on the normal side, within ~60 degrees of the normal.
            let up = if i % 2 == 0 { 1.0 } else { -1.0 };
            let jitter = rand_dir(&mut rng) * 0.5;
            let dir_to = nunit * up + jitter;
            let o = target + dir_to * rng.range_f32(1.0, 8.0);
            let d = sub(target, o);
            let n = [t1, t2]
                .iter()
                .filter(|t| tri_hit(o, d, t).is_some())
                .count();
            assert!(n >= 1, "shared edge leak: {t1:?} {t2:?} o {o:?} d {d:?}");
            checked += 1;
        }
    }
    assert_eq!(checked, 400 * 25);
}

#[test]
fn triangle_fan_shared_vertex_never_leaks() {
    let mut rng = Rng::new(23);
    for center in [Vec3::ZERO, FAR, v(1e-3, 7.0, -3.0)] {
        for fan in 0..20 {
            let hub = v(
                center.x + rng.range_f32(-1.0, 1.0),
                center.y + rng.range_f32(-1.0, 1.0),
                center.z + rng.range_f32(-0.2, 0.2),
            );
            // Six rim vertices around the hub, non-planar.
            let rim: Vec<Vec3> = (0..6)
                .map(|i| {
                    let a = std::f32::consts::PI / 3.0 * i as f32 + rng.range_f32(-0.3, 0.3);
                    let r = rng.range_f32(0.5, 2.0);
                    v(
                        hub.x + r * a.cos(),
                        hub.y + r * a.sin(),
                        hub.z + rng.range_f32(-0.4, 0.4),
                    )
                })
                .collect();
            let tris: Vec<Triangle> = (0..6)
                .map(|i| Triangle::new(hub, rim[i], rim[(i + 1) % 6]))
                .collect();
            for i in 0..150 {
                let target = match i % 3 {
                    0 => hub,
                    // A neighbour of the hub in f32 (one ulp step on random axes).
                    1 => {
                        let mut a = hub.to_array();
                        for x in a.iter_mut() {
                            let step = rng.below(3) as i64 - 1;
                            *x = f32::from_bits((x.to_bits() as i64 + step) as u32);
                        }
                        Vec3::from_array(a)
                    }
                    _ => mid(hub, rim[rng.below(6) as usize]),
                };
                let up = if fan % 2 == 0 { 1.0 } else { -1.0 };
                let o = v(
                    target.x + rng.range_f32(-2.0, 2.0),
                    target.y + rng.range_f32(-2.0, 2.0),
                    target.z + up * rng.range_f32(2.0, 5.0),
                );
                let d = sub(target, o);
                let n = tris.iter().filter(|t| tri_hit(o, d, t).is_some()).count();
                assert!(n >= 1, "fan leak at {target:?}: o {o:?} d {d:?}");
            }
        }
    }
}

#[test]
fn triangle_grazing_in_plane_is_none() {
    // Exactly representable in-plane rays: every product is exact, so det == 0.
    let t = Triangle::new(v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, 0.0, 1.0));
    assert!(tri_hit(v(2.0, -1.0, 0.0), v(-1.0, 1.0, 0.0), &t).is_none());
    assert!(tri_hit(v(-1.0, 1.0, 1.0), v(1.0, -1.0, 0.0), &t).is_none());
    assert!(tri_hit(v(3.0, -1.0, -1.0), v(-1.0, 0.5, 0.5), &t).is_none());
    let flat = Triangle::new(v(0.0, 0.0, 5.0), v(4.0, 0.0, 5.0), v(0.0, 4.0, 5.0));
    for d in [v(1.0, 0.0, 0.0), v(1.0, 0.3, 0.0), v(-0.7, 1.0, -0.0)] {
        assert!(tri_hit(v(1.0, 1.0, 5.0), d, &flat).is_none());
        assert!(tri_hit(v(-3.0, 1.0, 5.0), d, &flat).is_none());
    }
    // Random (inexact) near-in-plane rays: never panic, any hit honours the contract.
    let mut rng = Rng::new(24);
    for _ in 0..2000 {
        let tri = Triangle::new(
            rand_in_cube(&mut rng, FAR, 3.0),
            rand_in_cube(&mut rng, FAR, 3.0),
            rand_in_cube(&mut rng, FAR, 3.0),
        );
        let o = tri.point_at(rng.range_f32(-1.0, 2.0), rng.range_f32(-1.0, 2.0));
        let d = sub(tri.point_at(rng.unit_f32(), rng.unit_f32() * 0.5), o);
        if let Some(h) = tri_hit(o, d, &tri) {
            assert!(h.t >= 0.0 && h.t.is_finite());
            assert!((0.0..=1.0).contains(&h.u) && (0.0..=1.0).contains(&h.v));
        }
    }
}

#[test]
fn triangle_degenerates_are_none() {
    let mut rng = Rng::new(25);
    let int = |rng: &mut Rng| rng.below(17) as f32 - 8.0;
    for i in 0..3000 {
        // Small-integer geometry: every intermediate is exact, so collinear
        // triangles give exactly det == 0 (or a failed edge test).
        let p = v(int(&mut rng), int(&mut rng), int(&mut rng));
        let e = v(int(&mut rng), int(&mut rng), int(&mut rng));
        let (s1, s2) = (int(&mut rng), int(&mut rng));
        let line = Triangle::new(p, p + e * s1, p + e * s2);
        let o = v(int(&mut rng), int(&mut rng), int(&mut rng));
        let target = p + e * int(&mut rng);
        let d = if i % 2 == 0 {
            sub(target, o)
        } else {
            v(int(&mut rng), int(&mut rng), int(&mut rng))
        };
        assert!(line.is_degenerate());
        assert!(
            tri_hit(o, d, &line).is_none(),
            "collinear hit {line:?} o {o:?} d {d:?}"
        );
    }
    // Repeated vertices with arbitrary floats: W == 0 and U == -V exactly, det == 0.
    for _ in 0..3000 {
        let p = rand_in_cube(&mut rng, FAR, 2.0);
        let q = rand_in_cube(&mut rng, FAR, 2.0);
        let o = rand_in_cube(&mut rng, FAR, 6.0);
        for t in [
            Triangle::new(p, p, q),
            Triangle::new(p, q, p),
            Triangle::new(q, p, p),
            Triangle::new(p, p, p),
        ] {
            for target in [p, q, mid(p, q)] {
                assert!(tri_hit(o, sub(target, o), &t).is_none(), "{t:?}");
            }
        }
    }
}

#[test]
fn triangle_nan_and_inf_inputs_are_none() {
    let t = Triangle::new(v(0.0, 0.0, 0.0), v(4.0, 0.0, 0.0), v(0.0, 4.0, 0.0));
    let o = v(1.0, 1.0, 5.0);
    let d = v(0.0, 0.0, -1.0);
    assert!(tri_hit(o, d, &t).is_some());
    for bad in [f32::NAN, INF, -INF] {
        for k in 0..3 {
            assert!(tri_hit(set(o, k, bad), d, &t).is_none());
            assert!(tri_hit(o, set(d, k, bad), &t).is_none());
            for which in 0..3 {
                let mut u = t;
                match which {
                    0 => u.v0 = set(u.v0, k, bad),
                    1 => u.v1 = set(u.v1, k, bad),
                    _ => u.v2 = set(u.v2, k, bad),
                }
                assert!(tri_hit(o, d, &u).is_none());
            }
        }
        assert!(ray_triangle(o, d, bad, INF, &t).is_none());
    }
    assert!(ray_triangle(o, d, 0.0, f32::NAN, &t).is_none());
    assert!(tri_hit(o, Vec3::ZERO, &t).is_none());
    // Overflowing intermediates: None, never a bogus hit.
    let huge = Triangle::new(v(-3e37, -3e37, 0.0), v(3e37, -3e37, 0.0), v(0.0, 3e37, 0.0));
    let r = tri_hit(v(0.0, 0.0, 1e30), d, &huge);
    assert!(r.is_none() || r.unwrap().t == 1e30);
}

#[test]
fn triangle_t_range_is_exact_and_inclusive() {
    let mut rng = Rng::new(26);
    let mut n = 0;
    for _ in 0..2000 {
        let c = if rng.below(2) == 0 { Vec3::ZERO } else { FAR };
        let t = Triangle::new(
            rand_in_cube(&mut rng, c, 3.0),
            rand_in_cube(&mut rng, c, 3.0),
            rand_in_cube(&mut rng, c, 3.0),
        );
        let o = rand_in_cube(&mut rng, c, 10.0);
        let d = sub(t.point_at(rng.unit_f32() * 0.5, rng.unit_f32() * 0.5), o);
        let Some(h) = tri_hit(o, d, &t) else { continue };
        n += 1;
        let below = f32::from_bits(h.t.to_bits() - 1);
        let above = f32::from_bits(h.t.to_bits() + 1);
        assert_eq!(ray_triangle(o, d, h.t, h.t, &t), Some(h));
        assert_eq!(ray_triangle(o, d, below, above, &t), Some(h));
        assert_eq!(ray_triangle(o, d, 0.0, below, &t), None);
        assert_eq!(ray_triangle(o, d, above, INF, &t), None);
        assert_eq!(ray_triangle(o, d, 0.0, h.t * 0.5, &t), None);
        assert_eq!(ray_triangle(o, d, h.t * 2.0 + 1.0, INF, &t), None);
        // Behind the origin: reverse the ray.
        assert_eq!(tri_hit(o, -d, &t), None);
    }
    assert!(n > 1500, "{n}");
}

#[test]
fn triangle_barycentrics_and_hit_point() {
    let mut rng = Rng::new(27);
    let mut n = 0;
    for i in 0..3000 {
        let c = if i % 2 == 0 { Vec3::ZERO } else { FAR };
        let t = Triangle::new(
            rand_in_cube(&mut rng, c, 3.0),
            rand_in_cube(&mut rng, c, 3.0),
            rand_in_cube(&mut rng, c, 3.0),
        );
        let (su, sv) = (rng.unit_f32(), rng.unit_f32());
        let (su, sv) = if su + sv > 1.0 {
            (1.0 - su, 1.0 - sv)
        } else {
            (su, sv)
        };
        let o = rand_in_cube(&mut rng, c, 10.0);
        let d = sub(t.point_at(su, sv), o);
        let Some(h) = tri_hit(o, d, &t) else { continue };
        n += 1;
        assert!(
            (0.0..=1.0).contains(&h.u) && (0.0..=1.0).contains(&h.v),
            "{h:?}"
        );
        assert!(h.u + h.v <= 1.0 + 1e-6, "{h:?}");
        // Work relative to v0 in f64 so the check itself is accurate far away.
        let rel = |p: Vec3| p.as_dvec3() - t.v0.as_dvec3();
        let hit_p = rel(o) + d.as_dvec3() * h.t as f64;
        let bary_p = rel(t.v1) * h.u as f64 + rel(t.v2) * h.v as f64;
        let n_ = rel(t.v1).cross(rel(t.v2)).normalize();
        let scale = 1.0 + rel(o).length();
        assert!(hit_p.dot(n_).abs() < 1e-5 * scale, "off plane {h:?}");
        assert!(
            (hit_p - bary_p).length() < 1e-4 * scale,
            "bary mismatch {h:?}"
        );
    }
    assert!(n > 2500, "{n}");
}

#[test]
fn closest_hit_tie_on_shared_edge_goes_to_smaller_id() {
    // Square [0,2]^2 at z = 0 split on the diagonal; a ray straight down through
    // (1,1) hits both halves at exactly t = 5.
    let q = quad(
        v(0.0, 0.0, 0.0),
        v(2.0, 0.0, 0.0),
        v(2.0, 2.0, 0.0),
        v(0.0, 2.0, 0.0),
    );
    let o = v(1.0, 1.0, 5.0);
    let d = v(0.0, 0.0, -1.0);
    let h0 = tri_hit(o, d, &q[0]).unwrap();
    let h1 = tri_hit(o, d, &q[1]).unwrap();
    assert_eq!(h0.t, 5.0);
    assert_eq!(h1.t, 5.0);
    for (id0, id1) in [(7u32, 3u32), (3, 7)] {
        let a = Hit {
            t: h0.t,
            tri_id: id0,
            u: h0.u,
            v: h0.v,
        };
        let b = Hit {
            t: h1.t,
            tri_id: id1,
            u: h1.u,
            v: h1.v,
        };
        let want = if id0 < id1 { a } else { b };
        assert_eq!(closest(Some(a), Some(b)), Some(want));
        assert_eq!(closest(Some(b), Some(a)), Some(want));
        assert_eq!(want.tri_id, 3);
        // Any traversal order over both gives the same result.
        let mut acc = None;
        for h in [b, a] {
            acc = closest(acc, Some(h));
        }
        assert_eq!(acc, Some(want));
    }
}
