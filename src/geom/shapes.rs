//! Closed, watertight meshes for built-in scenes and leak tests.
//!
//! Every vertex is computed once into a table and triangles copy from the table,
//! so vertices shared by neighbouring triangles are bit-identical (what the
//! watertight triangle test needs to close the mesh). Trigonometry uses a
//! fixed-order f64 polynomial instead of the platform libm, so the meshes are
//! the same on every machine. Winding is counter-clockwise seen from outside.

use glam::Vec3;

use super::triangle::Triangle;

/// (sin x, cos x) for |x| <= ~8 using only IEEE f64 add/mul in a fixed order:
/// reduce by the nearest multiple of pi/2, then Taylor series to degree 21/22
/// (|r| <= pi/4, truncation < 1e-20). Deterministic, unlike libm.
pub fn sin_cos(x: f64) -> (f64, f64) {
    let half_pi = std::f64::consts::FRAC_PI_2;
    let q = (x / half_pi).round();
    let r = x - q * half_pi;
    let r2 = r * r;
    // Horner from the highest term: sin r = r(1 - r2/(2*3)(1 - r2/(4*5)(...)))
    let mut s = 1.0f64;
    let mut c = 1.0f64;
    let mut k = 11.0f64;
    while k >= 1.0 {
        s = 1.0 - r2 / ((2.0 * k) * (2.0 * k + 1.0)) * s;
        c = 1.0 - r2 / ((2.0 * k - 1.0) * (2.0 * k)) * c;
        k -= 1.0;
    }
    let s = r * s;
    match (q as i64).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// `center + radius * unit`, computed in f64 and rounded once to f32.
fn place(center: Vec3, radius: f32, unit: [f64; 3]) -> Vec3 {
    let r = radius as f64;
    Vec3::new(
        (center.x as f64 + r * unit[0]) as f32,
        (center.y as f64 + r * unit[1]) as f32,
        (center.z as f64 + r * unit[2]) as f32,
    )
}

/// `n` UV spheres (12 x 24) of radius 0.2-1.5 at random centres in a 20-unit
/// cube, from `seed`: a scene of many separate objects for BVH tests.
pub fn random_spheres(n: usize, seed: u64) -> Vec<Triangle> {
    let mut rng = crate::util::rng::Rng::new(seed);
    let mut t = Vec::new();
    for _ in 0..n {
        let c = Vec3::new(
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
            rng.range_f32(-10.0, 10.0),
        );
        t.extend(uv_sphere(c, rng.range_f32(0.2, 1.5), 12, 24));
    }
    t
}

/// A closed UV sphere: `stacks` bands from the +y pole to the -y pole and
/// `slices` columns around y (clamped to at least 2 and 3). Poles are single
/// vertices; the seam column reuses column 0. Produces
/// `2 * slices * (stacks - 1)` triangles. Far from the origin or for tiny radii
/// some triangles may round to zero area; the mesh stays closed regardless.
pub fn uv_sphere(center: Vec3, radius: f32, stacks: u32, slices: u32) -> Vec<Triangle> {
    let stacks = stacks.max(2) as usize;
    let slices = slices.max(3) as usize;
    let pi = std::f64::consts::PI;
    let top = place(center, radius, [0.0, 1.0, 0.0]);
    let bottom = place(center, radius, [0.0, -1.0, 0.0]);
    // rings[i - 1][j] is the vertex at polar angle pi*i/stacks, azimuth 2pi*j/slices.
    let rings: Vec<Vec<Vec3>> = (1..stacks)
        .map(|i| {
            let (st, ct) = sin_cos(pi * i as f64 / stacks as f64);
            (0..slices)
                .map(|j| {
                    let (sp, cp) = sin_cos(2.0 * pi * j as f64 / slices as f64);
                    place(center, radius, [st * cp, ct, st * sp])
                })
                .collect()
        })
        .collect();
    let mut tris = Vec::with_capacity(2 * slices * (stacks - 1));
    for j in 0..slices {
        let jn = (j + 1) % slices;
        let first = &rings[0];
        tris.push(Triangle::new(top, first[jn], first[j]));
        for i in 0..stacks - 2 {
            let (up, dn) = (&rings[i], &rings[i + 1]);
            tris.extend(quad(up[j], up[jn], dn[jn], dn[j]));
        }
        let last = &rings[stacks - 2];
        tris.push(Triangle::new(bottom, last[j], last[jn]));
    }
    tris
}

/// A closed icosphere: the icosahedron with every face split into four
/// `subdivisions` times (clamped to at most 6), new vertices on the unit sphere
/// (edge midpoints normalised in f64; `sqrt` is exact-rounded IEEE, so the mesh is
/// the same everywhere). Produces `20 * 4^subdivisions` triangles of nearly equal
/// size and shape, unlike the UV sphere's thin polar ones.
pub fn icosphere(center: Vec3, radius: f32, subdivisions: u32) -> Vec<Triangle> {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let unit = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    let mut dirs: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .into_iter()
    .map(unit)
    .collect();
    // Counter-clockwise seen from outside.
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions.min(6) {
        // One new vertex per edge, shared by the two faces on it.
        let mut mids = std::collections::HashMap::new();
        let mut mid = |a: usize, b: usize, dirs: &mut Vec<[f64; 3]>| {
            *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (dirs[a], dirs[b]);
                dirs.push(unit([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                dirs.len() - 1
            })
        };
        faces = faces
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    mid(a, b, &mut dirs),
                    mid(b, c, &mut dirs),
                    mid(c, a, &mut dirs),
                );
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let verts: Vec<Vec3> = dirs.iter().map(|&d| place(center, radius, d)).collect();
    faces
        .iter()
        .map(|&[a, b, c]| Triangle::new(verts[a], verts[b], verts[c]))
        .collect()
}

/// A closed tube (a generalised cylinder) along the polyline `points` (f64, at
/// least 2 distinct consecutive points): a ring of `sides` vertices (at least 3)
/// around every point, each ring perpendicular to the polyline's mean tangent
/// there and turned from the last by parallel transport (no twist), quads
/// between neighbouring rings and a fan capping each end. Vertices are computed
/// once in f64 and rounded once, so neighbours share them bit for bit. Produces
/// `2 * sides * (points - 1) + 2 * sides` triangles, outward.
pub fn tube(points: &[[f64; 3]], radius: f32, sides: u32) -> Vec<Triangle> {
    type V = [f64; 3];
    let sub = |a: V, b: V| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: V, b: V| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: V, b: V| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: V| {
        let l = dot(a, a).sqrt();
        [a[0] / l, a[1] / l, a[2] / l]
    };
    let n = points.len();
    assert!(n >= 2, "a tube needs two points");
    let sides = sides.max(3) as usize;
    let angles: Vec<(f64, f64)> = (0..sides)
        .map(|j| sin_cos(2.0 * std::f64::consts::PI * j as f64 / sides as f64))
        .collect();
    let to_f32 = |a: V| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
    let mut rings: Vec<Vec<Vec3>> = Vec::with_capacity(n);
    let mut u: V = [0.0; 3];
    for i in 0..n {
        let t = unit(sub(points[(i + 1).min(n - 1)], points[i.saturating_sub(1)]));
        u = if i == 0 {
            // Any perpendicular: across the axis least aligned with the tangent.
            let k = (0..3)
                .min_by(|&a, &b| t[a].abs().total_cmp(&t[b].abs()))
                .expect("three axes");
            let mut a = [0.0; 3];
            a[k] = 1.0;
            unit(cross(t, a))
        } else {
            // Parallel transport: last ring's u, made perpendicular to this tangent.
            let d = dot(u, t);
            unit([u[0] - d * t[0], u[1] - d * t[1], u[2] - d * t[2]])
        };
        // w = t x u, so u x w = t: angles increase counter-clockwise seen from +t.
        let w = cross(t, u);
        let (p, r) = (points[i], radius as f64);
        rings.push(
            angles
                .iter()
                .map(|&(s, c)| {
                    to_f32([
                        p[0] + r * (c * u[0] + s * w[0]),
                        p[1] + r * (c * u[1] + s * w[1]),
                        p[2] + r * (c * u[2] + s * w[2]),
                    ])
                })
                .collect(),
        );
    }
    let mut tris = Vec::with_capacity(2 * sides * n);
    let (first, last) = (to_f32(points[0]), to_f32(points[n - 1]));
    for j in 0..sides {
        let jn = (j + 1) % sides;
        tris.push(Triangle::new(first, rings[0][jn], rings[0][j]));
        for i in 0..n - 1 {
            let (a, b) = (&rings[i], &rings[i + 1]);
            tris.extend(quad(a[j], a[jn], b[jn], b[j]));
        }
        tris.push(Triangle::new(last, rings[n - 1][j], rings[n - 1][jn]));
    }
    tris
}

/// Two triangles `(a, b, c)` and `(a, c, d)` split along the a-c diagonal; the
/// diagonal's endpoints are the same values in both.
pub fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> [Triangle; 2] {
    [Triangle::new(a, b, c), Triangle::new(a, c, d)]
}

/// The 12 triangles of the closed box `[min, max]` (outward winding). Corners
/// are taken from one 8-entry table, so shared corners are bit-identical.
pub fn box_mesh(min: Vec3, max: Vec3) -> Vec<Triangle> {
    // Corner index bits: 1 -> x, 2 -> y, 4 -> z take the max coordinate.
    let p = |i: usize| {
        Vec3::new(
            if i & 1 != 0 { max.x } else { min.x },
            if i & 2 != 0 { max.y } else { min.y },
            if i & 4 != 0 { max.z } else { min.z },
        )
    };
    // Faces as corner quads, counter-clockwise seen from outside.
    const FACES: [[usize; 4]; 6] = [
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
    ];
    FACES
        .iter()
        .flat_map(|f| quad(p(f[0]), p(f[1]), p(f[2]), p(f[3])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Every undirected edge (by vertex bit patterns) must be used by exactly two
    /// triangles, once in each direction: a closed, consistently wound mesh.
    fn assert_closed(tris: &[Triangle]) {
        let key = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
        let mut edges: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
        for t in tris {
            let vs = [t.v0, t.v1, t.v2];
            for k in 0..3 {
                let (p, q) = (key(vs[k]), key(vs[(k + 1) % 3]));
                if p == q {
                    continue; // collapsed edge of a zero-area triangle
                }
                let (lo, hi, s) = if p < q { (p, q, 1) } else { (q, p, -1) };
                *edges.entry((lo, hi)).or_insert(0) += s;
            }
        }
        assert!(
            edges.values().all(|&n| n == 0),
            "open or inconsistently wound edge"
        );
    }

    fn assert_outward(tris: &[Triangle], center: Vec3) {
        for t in tris {
            if t.is_degenerate() {
                continue;
            }
            let n = t.normal();
            let g = (t.v0 + t.v1 + t.v2) / 3.0 - center;
            assert!(
                n.x * g.x + n.y * g.y + n.z * g.z > 0.0,
                "inward triangle {t:?}"
            );
        }
    }

    #[test]
    fn sin_cos_is_accurate() {
        for i in 0..=64 {
            let x = std::f64::consts::PI * 2.0 * i as f64 / 64.0;
            let (s, c) = sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 1e-15 && (c - x.cos()).abs() < 1e-15,
                "{x}"
            );
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }

    #[test]
    fn sphere_is_closed_and_outward() {
        let c = Vec3::new(1.0, -2.0, 3.0);
        let s = uv_sphere(c, 2.0, 8, 12);
        assert_eq!(s.len(), 2 * 12 * 7);
        assert_closed(&s);
        assert_outward(&s, c);
        for t in &s {
            for v in [t.v0, t.v1, t.v2] {
                assert!(((v - c).length() - 2.0).abs() < 1e-5);
            }
        }
        // Far from the origin and tiny: still closed (some triangles collapse).
        assert_closed(&uv_sphere(
            Vec3::new(148376.0, 1234.0, -223423.0),
            1.0,
            32,
            64,
        ));
        assert_eq!(uv_sphere(c, 1.0, 0, 0).len(), 2 * 3);
    }

    #[test]
    fn icosphere_is_closed_and_outward() {
        let c = Vec3::new(1.0, -2.0, 3.0);
        for k in 0..4 {
            let s = icosphere(c, 2.0, k);
            assert_eq!(s.len(), 20 << (2 * k));
            assert_closed(&s);
            assert_outward(&s, c);
            for t in &s {
                for v in [t.v0, t.v1, t.v2] {
                    assert!(((v - c).length() - 2.0).abs() < 1e-5);
                }
            }
        }
        // Nearly uniform: the largest triangle is at most ~1.5x the smallest.
        let s = icosphere(Vec3::ZERO, 1.0, 3);
        let areas: Vec<f32> = s.iter().map(|t| t.normal().length()).collect();
        let (lo, hi) = areas
            .iter()
            .fold((f32::MAX, 0.0f32), |(l, h), &a| (l.min(a), h.max(a)));
        assert!(hi / lo < 1.6, "{lo} {hi}");
        assert_closed(&icosphere(Vec3::new(148376.0, 1234.0, -223423.0), 1.0, 3));
    }

    #[test]
    fn tube_is_closed_and_outward() {
        // A bent polyline: the rings turn with it.
        let pts = [
            [0.0, 0.0, 0.0],
            [0.1, 0.02, 0.0],
            [0.18, 0.08, 0.03],
            [0.2, 0.17, 0.09],
            [0.15, 0.25, 0.12],
        ];
        let r = 0.01;
        let t = tube(&pts, r, 5);
        assert_eq!(t.len(), 2 * 5 * 4 + 2 * 5);
        assert_closed(&t);
        // Outward: each side triangle faces away from its segment's axis.
        for (k, tri) in t.iter().enumerate() {
            let (j, i) = (k / 10, k % 10);
            if i == 0 || i == 9 {
                continue; // caps
            }
            let seg = (i - 1) / 2;
            let (a, b) = (pts[seg], pts[seg + 1]);
            let mid = Vec3::new(
                ((a[0] + b[0]) / 2.0) as f32,
                ((a[1] + b[1]) / 2.0) as f32,
                ((a[2] + b[2]) / 2.0) as f32,
            );
            assert_outward(std::slice::from_ref(tri), mid);
            for v in [tri.v0, tri.v1, tri.v2] {
                assert!((v - mid).length() < 0.1, "side {j}: {v}");
            }
        }
        // Every ring vertex lies at the radius from its point.
        for tri in &t {
            for v in [tri.v0, tri.v1, tri.v2] {
                let d = pts
                    .iter()
                    .map(|p| (v - Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)).length())
                    .fold(f32::MAX, f32::min);
                assert!(d < 1e-6 || (d - r).abs() < 1e-6, "{v} at {d}");
            }
        }
    }

    #[test]
    fn box_is_closed_and_outward() {
        let (lo, hi) = (Vec3::new(-1.0, 2.0, -3.0), Vec3::new(4.0, 5.0, 6.0));
        let b = box_mesh(lo, hi);
        assert_eq!(b.len(), 12);
        assert_closed(&b);
        assert_outward(&b, (lo + hi) * 0.5);
        let q = quad(Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Y);
        assert_eq!(q[0].v2, q[1].v1);
        assert_eq!(q[0].v0, q[1].v0);
    }
}
