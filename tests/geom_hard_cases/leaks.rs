//! Leak tests on closed meshes near and far from the origin: a ray from inside
//! always hits the surface.

use super::*;

/// Buckets sphere triangles by the polar/azimuth cell of their centroid so each
/// ray tests only triangles near where it leaves the ideal sphere. This can only
/// make a ray look like it escaped (then all triangles are tried), never hide an
/// escape, so the zero-escape assertion stays sound.
struct SphereIndex {
    c: glam::DVec3,
    r: f64,
    rows: usize,
    cols: usize,
    buckets: Vec<Vec<usize>>,
}

impl SphereIndex {
    fn new(tris: &[Triangle], c: Vec3, r: f32) -> SphereIndex {
        let (rows, cols) = (16, 32);
        let mut s = SphereIndex {
            c: c.as_dvec3(),
            r: r as f64,
            rows,
            cols,
            buckets: vec![Vec::new(); rows * cols],
        };
        for (i, t) in tris.iter().enumerate() {
            let g = (t.v0.as_dvec3() + t.v1.as_dvec3() + t.v2.as_dvec3()) / 3.0;
            let (a, b) = s.cell(g);
            s.buckets[a * cols + b].push(i);
        }
        s
    }

    fn cell(&self, p: glam::DVec3) -> (usize, usize) {
        let q = (p - self.c).normalize();
        let theta = q.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
        let phi = q.z.atan2(q.x) / std::f64::consts::TAU + 0.5;
        let a = ((theta * self.rows as f64) as usize).min(self.rows - 1);
        let b = ((phi * self.cols as f64) as usize).min(self.cols - 1);
        (a, b)
    }

    fn candidates(&self, o: Vec3, d: Vec3, out: &mut Vec<usize>) {
        out.clear();
        let (o, d) = (o.as_dvec3() - self.c, d.as_dvec3());
        let a = d.dot(d);
        let b = 2.0 * o.dot(d);
        let cc = o.dot(o) - self.r * self.r;
        let t = (-b + (b * b - 4.0 * a * cc).max(0.0).sqrt()) / (2.0 * a);
        let (row, col) = self.cell(o + d * t + self.c);
        for dr in -1i64..=1 {
            let r = row as i64 + dr;
            if r < 0 || r >= self.rows as i64 {
                continue;
            }
            let polar = r <= 1 || r >= self.rows as i64 - 2;
            for cidx in 0..self.cols {
                let dc = (cidx as i64 - col as i64).rem_euclid(self.cols as i64);
                if polar || dc <= 1 || dc >= self.cols as i64 - 1 {
                    out.extend_from_slice(&self.buckets[r as usize * self.cols + cidx]);
                }
            }
        }
    }
}

fn any_hit(tris: &[Triangle], ids: impl IntoIterator<Item = usize>, o: Vec3, d: Vec3) -> bool {
    ids.into_iter().any(|i| tri_hit(o, d, &tris[i]).is_some())
}

/// Shoots every ray and returns the ones that hit no triangle at all.
fn escapes(
    tris: &[Triangle],
    idx: Option<&SphereIndex>,
    rays: &[(Vec3, Vec3)],
) -> Vec<(Vec3, Vec3)> {
    let mut cand = Vec::new();
    let mut out = Vec::new();
    for &(o, d) in rays {
        let quick = match idx {
            Some(s) => {
                s.candidates(o, d, &mut cand);
                any_hit(tris, cand.iter().copied(), o, d)
            }
            None => false,
        };
        if !quick && !any_hit(tris, 0..tris.len(), o, d) {
            out.push((o, d));
        }
    }
    out
}

/// Unique vertices and edge midpoints (f32) of a mesh.
fn vertices_and_midpoints(tris: &[Triangle]) -> (Vec<Vec3>, Vec<Vec3>) {
    let key = |p: Vec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let mut vs = std::collections::BTreeMap::new();
    let mut ms = std::collections::BTreeMap::new();
    for t in tris {
        let p = [t.v0, t.v1, t.v2];
        for k in 0..3 {
            vs.insert(key(p[k]), p[k]);
            let m = mid(p[k], p[(k + 1) % 3]);
            ms.insert(key(m), m);
        }
    }
    (vs.into_values().collect(), ms.into_values().collect())
}

/// Rays from the exact centre and random interior points: random directions,
/// plus rays aimed exactly at every vertex and edge midpoint (from the centre and
/// from one interior point). Returns the number of rays shot.
fn sphere_leak_test(
    center: Vec3,
    radius: f32,
    stacks: u32,
    slices: u32,
    random_rays: usize,
    seed: u64,
) -> usize {
    let tris = uv_sphere(center, radius, stacks, slices);
    let idx = SphereIndex::new(&tris, center, radius);
    let mut rng = Rng::new(seed);
    let mut origins = vec![center];
    while origins.len() < 8 {
        let p = rand_dir(&mut rng) * (0.7 * radius);
        origins.push(v(center.x + p.x, center.y + p.y, center.z + p.z));
    }
    let mut rays = Vec::new();
    for i in 0..random_rays {
        let o = origins[i % origins.len()];
        rays.push((o, rand_dir(&mut rng)));
    }
    let (verts, mids) = vertices_and_midpoints(&tris);
    for &o in &origins[..2] {
        for &p in verts.iter().chain(mids.iter()) {
            let d = sub(p, o);
            if d != Vec3::ZERO {
                rays.push((o, d));
            }
        }
    }
    let esc = escapes(&tris, Some(&idx), &rays);
    assert!(
        esc.is_empty(),
        "{} of {} rays escaped sphere c {center:?} r {radius}: first {:?}",
        esc.len(),
        rays.len(),
        esc[0]
    );
    rays.len()
}

#[test]
fn leak_sphere_far_from_origin() {
    let n1 = sphere_leak_test(FAR, 1.0, 32, 64, 8000, 31);
    let n2 = sphere_leak_test(FAR, 50.0, 32, 64, 8000, 32);
    assert!(n1 + n2 >= 20_000, "{}", n1 + n2);
}

#[test]
fn leak_sphere_near_origin() {
    let n1 = sphere_leak_test(Vec3::ZERO, 1.0, 32, 64, 6000, 33);
    let n2 = sphere_leak_test(v(0.25, -0.5, 0.125), 50.0, 40, 80, 6000, 34);
    assert!(n1 + n2 >= 20_000, "{}", n1 + n2);
}

#[test]
fn leak_box_mesh_near_and_far() {
    let mut rng = Rng::new(35);
    for (lo, hi) in [
        (v(-1.0, -2.0, -0.5), v(1.0, 3.0, 0.75)),
        (FAR - v(1.0, 2.0, 0.5), FAR + v(1.0, 3.0, 0.75)),
        (FAR - v(40.0, 0.25, 7.0), FAR + v(60.0, 0.5, 3.0)),
    ] {
        let tris = box_mesh(lo, hi);
        let c = mid(lo, hi);
        let (verts, mids) = vertices_and_midpoints(&tris);
        let mut rays = Vec::new();
        for i in 0..3000 {
            let o = if i % 4 == 0 {
                c
            } else {
                // Strictly inside (an origin on a face starts at t ~ 0, where
                // the sign of t is rounding noise: not a leak).
                let ext = sub(hi, lo) * 0.45;
                v(
                    c.x + rng.range_f32(-ext.x, ext.x),
                    c.y + rng.range_f32(-ext.y, ext.y),
                    c.z + rng.range_f32(-ext.z, ext.z),
                )
            };
            rays.push((o, rand_dir(&mut rng)));
            for &p in verts.iter().chain(mids.iter()) {
                if i % 100 == 0 {
                    rays.push((o, sub(p, o)));
                }
            }
        }
        let esc = escapes(&tris, None, &rays);
        assert!(
            esc.is_empty(),
            "box {lo:?}..{hi:?}: {} escaped, first {:?}",
            esc.len(),
            esc[0]
        );
    }
}

#[test]
fn dense_grid_is_watertight() {
    const N: usize = 64;
    let mut rng = Rng::new(36);
    for origin in [Vec3::ZERO, FAR] {
        let h = 0.25f32;
        // Vertex table: computed once, so shared vertices are bit-identical.
        let mut grid = vec![Vec3::ZERO; (N + 1) * (N + 1)];
        for j in 0..=N {
            for i in 0..=N {
                let z = origin.z + rng.range_f32(-0.2, 0.2);
                grid[j * (N + 1) + i] = v(origin.x + i as f32 * h, origin.y + j as f32 * h, z);
            }
        }
        let g = |i: usize, j: usize| grid[j * (N + 1) + i];
        let mut tris = Vec::new();
        for j in 0..N {
            for i in 0..N {
                // Alternate diagonals so vertices have both 4- and 8-triangle fans.
                let q = if (i + j) % 2 == 0 {
                    quad(g(i, j), g(i + 1, j), g(i + 1, j + 1), g(i, j + 1))
                } else {
                    quad(g(i + 1, j), g(i + 1, j + 1), g(i, j + 1), g(i, j))
                };
                tris.extend(q);
            }
        }
        let cell_tris = |x: f32, y: f32| {
            let ci = (((x - origin.x) / h) as i64).clamp(0, N as i64 - 1);
            let cj = (((y - origin.y) / h) as i64).clamp(0, N as i64 - 1);
            let mut out = Vec::new();
            for dj in -1..=1 {
                for di in -1..=1 {
                    let (i, j) = (ci + di, cj + dj);
                    if (0..N as i64).contains(&i) && (0..N as i64).contains(&j) {
                        let base = 2 * (j as usize * N + i as usize);
                        out.extend([base, base + 1]);
                    }
                }
            }
            out
        };
        let mut targets = Vec::new();
        for j in 0..=N {
            for i in 0..=N {
                targets.push(g(i, j));
                if i < N {
                    targets.push(mid(g(i, j), g(i + 1, j)));
                }
                if j < N {
                    targets.push(mid(g(i, j), g(i, j + 1)));
                }
                if i < N && j < N {
                    targets.push(mid(g(i, j), g(i + 1, j + 1)));
                    targets.push(mid(g(i + 1, j), g(i, j + 1)));
                }
            }
        }
        for _ in 0..4000 {
            let t = tris[rng.below(tris.len() as u64) as usize];
            let (a, b) = (rng.unit_f32(), rng.unit_f32());
            let (a, b) = if a + b > 1.0 {
                (1.0 - a, 1.0 - b)
            } else {
                (a, b)
            };
            targets.push(t.point_at(a, b));
        }
        let mut misses = 0;
        for (k, p) in targets.iter().enumerate() {
            // Straight down onto the target, and a slanted ray aimed at it.
            let down = (v(p.x, p.y, origin.z + 10.0), v(0.0, 0.0, -1.0));
            let so = v(
                p.x + rng.range_f32(-3.0, 3.0),
                p.y + rng.range_f32(-3.0, 3.0),
                origin.z + 6.0,
            );
            let slant = (so, sub(*p, so));
            for (i, (o, d)) in [down, slant].into_iter().enumerate() {
                // Slanted rays aimed near the rim may leave through the open side.
                let m = 0.5;
                let inside = |q: Vec3| {
                    q.x > origin.x + m
                        && q.x < origin.x + N as f32 * h - m
                        && q.y > origin.y + m
                        && q.y < origin.y + N as f32 * h - m
                };
                if i == 1 && !inside(*p) {
                    continue;
                }
                let ids = cell_tris(p.x, p.y);
                if !any_hit(&tris, ids, o, d) && !any_hit(&tris, 0..tris.len(), o, d) {
                    misses += 1;
                    eprintln!("grid miss #{k}: o {o:?} d {d:?}");
                }
            }
        }
        assert_eq!(misses, 0, "grid at {origin:?} leaked");
    }
}
