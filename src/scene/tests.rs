use super::*;
use crate::geom::ray_triangle;
use crate::util::rng::Rng;
use std::path::PathBuf;

fn bits(s: &Scene) -> Vec<u32> {
    s.triangles
        .iter()
        .flat_map(|t| [t.v0, t.v1, t.v2])
        .flat_map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
        .collect()
}

/// Closest hit by brute force: (t, triangle index).
fn closest(s: &Scene, o: Vec3, d: Vec3, tris: usize) -> Option<(f32, usize)> {
    let mut best: Option<(f32, usize)> = None;
    for (i, t) in s.triangles[..tris].iter().enumerate() {
        let tmax = best.map_or(f32::INFINITY, |b| b.0);
        if let Some(h) = ray_triangle(o, d, 0.0, tmax, t)
            && best.is_none_or(|b| h.t < b.0)
        {
            best = Some((h.t, i));
        }
    }
    best
}

/// Rays from random interior points, in random directions and aimed exactly at
/// the corners and edge midpoints of `[lo, hi]`, all hit one of the first
/// `tris` triangles.
fn assert_closed(s: &Scene, lo: Vec3, hi: Vec3, tris: usize, n: usize) {
    let mut rng = Rng::new(3);
    let mut targets = Vec::new();
    for i in 0..27 {
        let pick = |k: usize, a: f32, b: f32| [a, (a + b) * 0.5, b][k];
        targets.push(Vec3::new(
            pick(i % 3, lo.x, hi.x),
            pick(i / 3 % 3, lo.y, hi.y),
            pick(i / 9, lo.z, hi.z),
        ));
    }
    for k in 0..n {
        let o = Vec3::new(
            rng.range_f32(lo.x, hi.x),
            rng.range_f32(lo.y, hi.y),
            rng.range_f32(lo.z, hi.z),
        );
        let d = if k % 2 == 0 {
            targets[k / 2 % targets.len()] - o
        } else {
            Vec3::new(
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
                rng.range_f32(-1.0, 1.0),
            )
        };
        assert!(
            closest(s, o, d, tris).is_some(),
            "{}: ray {o} {d} escaped",
            s.name
        );
    }
}

/// Mean direct radiance (point light, shadow rays, albedo/pi * I cos / D^2) of
/// the camera's primary hits on an n x n grid: a check that scenes are exposed.
fn mean_direct(s: &Scene, n: u32) -> f32 {
    let mut sum = 0.0;
    for py in 0..n {
        for px in 0..n {
            let (o, d) = s.camera.ray(px, py, n, n, (0.5, 0.5));
            let Some((t, i)) = closest(s, o, d, s.triangles.len()) else {
                sum += s.sky.x;
                continue;
            };
            let p = o + d * t;
            let tri = &s.triangles[i];
            let mut nrm = tri.normal().normalize();
            if nrm.dot(d) > 0.0 {
                nrm = -nrm;
            }
            let p = p + nrm * 1e-4;
            let to_l = s.light.position - p;
            let cos = nrm.dot(to_l.normalize());
            if cos <= 0.0 || closest(s, p, to_l, s.triangles.len()).is_some_and(|h| h.0 < 1.0) {
                continue;
            }
            let a = s.materials[s.tri_material[i] as usize].albedo.x;
            sum += a / std::f32::consts::PI * s.light.intensity.x * cos / to_l.length_squared();
        }
    }
    sum / (n * n) as f32
}

#[test]
fn builtins_load_with_expected_sizes() {
    assert!(BUILTINS.contains(&DEFAULT_SCENE));
    let want = [
        ("cornell", 1000, 5000),
        ("spheres", 50_000, 200_000),
        ("tiny", 20, 100),
        ("hairball", 200_000, 500_000),
    ];
    assert_eq!(BUILTINS.len(), want.len());
    for (name, lo, hi) in want {
        let s = load(name).unwrap();
        s.validate().unwrap();
        let n = s.triangles.len();
        assert!((lo..=hi).contains(&n), "{name}: {n} triangles");
        assert_eq!(s.tri_material.len(), n);
        assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        assert!(s.bounds().contains(s.camera.eye) && s.bounds().contains(s.light.position));
    }
    assert_eq!(load("tiny").unwrap().triangles.len(), 48);
    assert_eq!(load("cornell").unwrap().triangles.len(), 2232);
    assert_eq!(load("hairball").unwrap().triangles.len(), 300_012);
}

#[test]
fn builtins_are_closed() {
    let c = load("cornell").unwrap();
    let n = c.triangles.len();
    assert_closed(
        &c,
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 3.0),
        n,
        300,
    );
    let t = load("tiny").unwrap();
    assert_closed(
        &t,
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 1.0),
        48,
        300,
    );
    // spheres: the room alone (its first 12 triangles) must hold every ray.
    let s = load("spheres").unwrap();
    assert_closed(
        &s,
        Vec3::new(-8.0, 0.0, -8.0),
        Vec3::new(8.0, 10.0, 16.0),
        12,
        300,
    );
    // hairball: the room (its first 12 triangles) holds every ray; each hair is
    // a closed tube (`geom::shapes::tube`'s test), so none leaks into a hair.
    let h = load("hairball").unwrap();
    assert_closed(
        &h,
        Vec3::new(-3.0, -2.0, -3.0),
        Vec3::new(3.0, 3.0, 5.0),
        12,
        300,
    );
    // And the test can fail: without one wall triangle rays escape.
    let mut open = c.clone();
    open.triangles.remove(6); // half of the ceiling
    let escaped = (0..200).any(|k| {
        let d = Vec3::new(0.01 * k as f32 - 1.0, 1.0, 0.3);
        closest(&open, Vec3::new(0.0, 1.0, 1.0), d, open.triangles.len()).is_none()
    });
    assert!(escaped);
}

#[test]
fn builtins_are_reasonably_exposed() {
    let room = manifest("scenes/builtin_room.toml");
    for name in ["tiny", "cornell", &room] {
        let s = load(name).unwrap();
        let m = mean_direct(&s, 16);
        println!("{name} mean direct radiance {m}");
        assert!((0.05..0.6).contains(&m), "{name}: mean direct radiance {m}");
    }
}

#[test]
#[ignore = "slow in debug builds; run with --release to tune light intensities"]
fn spheres_exposure() {
    for (name, n) in [("spheres", 24), ("hairball", 16)] {
        let s = load(name).unwrap();
        let m = mean_direct(&s, n);
        println!("{name} mean direct radiance {m}");
        assert!((0.05..0.6).contains(&m), "{name}: {m}");
    }
}

/// The hairball is what the paper's Hairball is for: depth. Rays from the
/// camera through the ball's middle cross many hair surfaces.
#[test]
fn hairball_has_high_depth_complexity() {
    let s = load("hairball").unwrap();
    let ball = s.triangles.len() - 12;
    let mut crossings = 0usize;
    let n = 16;
    for k in 0..n {
        let o = s.camera.eye;
        let d = Vec3::new(0.02 * k as f32 - 0.16, 0.01 * k as f32 - 0.18, 0.0) - o;
        crossings += s.triangles[12..12 + ball]
            .iter()
            .filter(|t| ray_triangle(o, d, 0.0, f32::INFINITY, t).is_some())
            .count();
    }
    let mean = crossings as f32 / n as f32;
    assert!(mean > 10.0, "{mean} hair surfaces per ray");
}

#[test]
fn loading_is_deterministic() {
    for name in BUILTINS {
        assert_eq!(bits(&load(name).unwrap()), bits(&load(name).unwrap()));
    }
    let p = manifest("scenes/builtin_room.toml");
    assert_eq!(bits(&load(&p).unwrap()), bits(&load(&p).unwrap()));
}

#[test]
fn unknown_spec_is_a_clear_error() {
    let e = load("nosuch").unwrap_err();
    assert!(
        matches!(&e, SceneError::Unknown { spec } if spec == "nosuch"),
        "{e:?}"
    );
    let e = e.to_string();
    assert!(e.contains("cornell") && e.contains(".toml"), "{e}");
    for p in ["/nonexistent/dir/x.obj", "/nonexistent/dir/x.toml"] {
        let e = load(p).unwrap_err();
        match &e {
            SceneError::File(f) => {
                assert_eq!(f.path, Path::new(p));
                assert_eq!(f.kind(), std::io::ErrorKind::NotFound);
            }
            e => panic!("expected an unreadable file, got {e:?}"),
        }
        // The I/O error stays reachable as the source.
        let io = std::error::Error::source(&e)
            .and_then(|s| s.source())
            .and_then(|s| s.downcast_ref::<std::io::Error>());
        assert_eq!(io.map(|e| e.kind()), Some(std::io::ErrorKind::NotFound));
        assert!(e.to_string().contains(p), "{e}");
    }
}

#[test]
fn xform_keeps_shared_vertices_identical() {
    let mut b = crate::geom::shapes::box_mesh(Vec3::ZERO, Vec3::ONE);
    let before = b.clone();
    let x = Xform {
        scale: 2.5,
        rotate_y_deg: 90.0,
        translate: Vec3::new(1.0, 2.0, 3.0),
    };
    x.apply(&mut b);
    // Rotating +x by +90 degrees about +y gives -z.
    let f = |p: Vec3| {
        let mut t = [Triangle::new(p, p, p)];
        x.apply(&mut t);
        t[0].v0
    };
    assert!((f(Vec3::X) - Vec3::new(1.0, 2.0, 0.5)).length() < 1e-6);
    // Whole turns added or subtracted change nothing (angles are reduced first).
    for turns in [-3.0, 2.0, 1000.0] {
        let mut t = before.clone();
        Xform {
            rotate_y_deg: 90.0 + 360.0 * turns,
            ..x
        }
        .apply(&mut t);
        assert_eq!(t, b);
    }
    for (t0, t1) in before.iter().zip(&b) {
        for (a, c) in before.iter().zip(&b) {
            for (p, q) in [(t0.v0, t1.v0), (t0.v1, t1.v1), (t0.v2, t1.v2)] {
                for (r, s) in [(a.v0, c.v0), (a.v1, c.v1), (a.v2, c.v2)] {
                    assert_eq!(p == r, q == s);
                }
            }
        }
    }
}

// ---------------------------------------------------------------- TOML

fn manifest(rel: &str) -> String {
    format!("{}/{rel}", env!("CARGO_MANIFEST_DIR"))
}

fn parse(src: &str) -> Result<Scene, SceneError> {
    let s = desc::parse(src, "t.toml", Path::new("."))?;
    s.validate()?;
    Ok(s)
}

use std::path::Path;

const GOOD: &str = r#"
name = "t"
sky = [0.1, 0.2, 0.3]
[camera]
eye = [0.0, 1.0, 5.0]
look_at = [0.0, 1.0, 0.0]
vfov = 45.0
[light]
position = [0.0, 3.0, 0.0]
intensity = [2.0, 2.0, 2.0]
[render]
width = 64
height = 32
bounces = 3
seed = 9
[[mesh]]
builtin = "box"
min = [-1.0, 0.0, -1.0]
max = [1.0, 2.0, 1.0]
albedo = [0.5, 0.5, 0.5]
[[mesh]]
builtin = "sphere"
center = [0.0, 1.0, 0.0]
radius = 0.5
stacks = 4
slices = 6
rotate_y = 45.0
translate = [0.0, 0.0, 0.1]
"#;

#[test]
fn toml_good_file() {
    let s = parse(GOOD).unwrap();
    assert_eq!(s.name, "t");
    assert_eq!(s.triangles.len(), 12 + 2 * 6 * 3);
    assert_eq!(s.sky, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(
        s.settings,
        RenderSettings {
            width: 64,
            height: 32,
            bounces: 3,
            seed: 9,
            spp: 1,
        }
    );
    assert_eq!(s.camera.up, Vec3::Y, "up defaults to +y");
    assert_eq!(s.materials.len(), 2);
    assert_eq!(
        s.materials[s.tri_material[0] as usize].albedo,
        Vec3::splat(0.5)
    );
    assert_eq!(
        s.materials[s.tri_material[12] as usize].albedo,
        Vec3::splat(DEFAULT_ALBEDO)
    );
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    // The committed builtin-only scene loads from disk.
    let r = load(&manifest("scenes/builtin_room.toml")).unwrap();
    assert_eq!(r.triangles.len(), 12 + 2 * 960 + 12 + 2);
    assert_eq!((r.settings.width, r.settings.height), (128, 96));
}

/// Replaces the first occurrence of `from` in GOOD and returns the error.
fn bad(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from}");
    parse(&GOOD.replacen(from, to, 1)).unwrap_err().to_string()
}

#[test]
fn toml_errors_name_line_and_fix() {
    let cases = [
        ("seed = 9", "seed = 9\nsamples = 4", ":16:", "samples"),
        ("bounces = 3", "bounces = 17", ":14:", "1..=16"),
        ("bounces = 3", "bounces = 0", ":14:", "1..=16"),
        ("width = 64", "width = 0", ":12:", "width"),
        ("height = 32", "height = 16385", ":13:", "height"),
        (
            "look_at = [0.0, 1.0, 0.0]",
            "look_at = [0.0, 1.0, 5.0]",
            ":4:",
            "same point",
        ),
        ("vfov = 45.0", "vfov = nan", ":4:", "vfov"),
        (
            "eye = [0.0, 1.0, 5.0]",
            "eye = [0.0, nan, 5.0]",
            ":4:",
            "not finite",
        ),
        (
            "vfov = 45.0",
            "vfov = 45.0\nup = [0.0, 0.0, 1.0]",
            ":4:",
            "parallel",
        ),
        (
            "builtin = \"box\"\nmin = [-1.0, 0.0, -1.0]\nmax = [1.0, 2.0, 1.0]",
            "path = \"no/such.obj\"",
            ":16: mesh 1",
            "no/such.obj",
        ),
        (
            "builtin = \"box\"",
            "path = \"x.obj\"",
            ":16: mesh 1",
            "`min` applies only",
        ),
        (
            "builtin = \"box\"",
            "builtin = \"cone\"",
            "mesh 1",
            "unknown builtin",
        ),
        ("radius = 0.5", "radius = -1.0", ":21:", "radius > 0"),
        ("min = [-1.0, 0.0, -1.0]", "corners = 3", ":18:", "corners"),
        (
            "albedo = [0.5, 0.5, 0.5]",
            "albedo = [1.5, 0.5, 0.5]",
            "mesh 1",
            "[0, 1]",
        ),
        (
            "intensity = [2.0, 2.0, 2.0]",
            "intensity = [-2.0, 2.0, 2.0]",
            ":8:",
            "intensity",
        ),
        (
            "sky = [0.1, 0.2, 0.3]",
            "sky = [0.1, 0.2]",
            ":3:",
            "length 3",
        ),
    ];
    for (from, to, at, what) in cases {
        let e = bad(from, to);
        assert!(e.starts_with("t.toml"), "{e}");
        assert!(e.contains(at) && e.contains(what), "{to}: {e}");
    }
    let e = parse("name = \"x\"\n").unwrap_err();
    assert!(matches!(e.root(), SceneError::Empty(_)), "{e:?}");
    assert!(e.to_string().contains("no triangles"), "{e}");
}

#[test]
fn toml_without_camera_or_light_frames_the_bounds() {
    let src = GOOD.split("[render]").collect::<Vec<_>>();
    let mut s = src[0].split("[camera]").next().unwrap().to_string();
    s += "[render]";
    s += src[1];
    let sc = parse(&s).unwrap();
    assert_eq!(sc.camera.look_at, sc.bounds().centroid());
    assert!(sc.camera.eye.z > sc.bounds().max.z);
    assert!(sc.light.position.y > sc.bounds().max.y);
    assert!(
        sc.warnings
            .iter()
            .any(|w| w.contains("[camera]") && w.contains("[light]"))
    );
}

// ---------------------------------------------------------------- OBJ

/// A fresh temp dir with the given files.
fn temp(name: &str, files: &[(&str, &str)]) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dualstream-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    for (f, text) in files {
        std::fs::write(d.join(f), text).unwrap();
    }
    d
}

fn load_obj(name: &str, files: &[(&str, &str)]) -> Result<Scene, SceneError> {
    let d = temp(name, files);
    let r = load(d.join(files[0].0).to_str().unwrap());
    let _ = std::fs::remove_dir_all(&d);
    r
}

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";

#[test]
fn obj_bare_renders_with_framing_and_copyable_view() {
    let s = load_obj("bare", &[("q.obj", QUAD)]).unwrap();
    assert_eq!(s.name, "q");
    assert_eq!(s.triangles.len(), 2, "quad triangulated");
    assert_eq!(
        s.materials[s.tri_material[0] as usize].albedo,
        Vec3::splat(DEFAULT_ALBEDO)
    );
    assert_eq!(s.camera.vfov_deg, 45.0);
    assert!(s.camera.eye.z > 0.0 && s.camera.look_at == Vec3::new(0.5, 0.5, 0.0));
    // The warning's TOML reproduces the camera and light exactly.
    let w = s.warnings.iter().find(|w| w.contains("[camera]")).unwrap();
    let snippet = &w[w.find("[camera]").unwrap()..];
    let mut src = snippet.to_string();
    src += "[[mesh]]\nbuiltin = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\n";
    let again = parse(&src).unwrap();
    assert_eq!(again.camera, s.camera);
    assert_eq!(again.light, s.light);
    assert!(mean_direct(&s, 8) > 0.0);
}

#[test]
fn obj_nan_vertex_is_an_error_naming_file_line_and_vertex() {
    for bad in ["nan", "inf", "-inf", "1e39"] {
        let text = format!("v 0 0 0\nv 1 {bad} 0\nv 0 1 0\nf 1 2 3\n");
        let e = load_obj("nan", &[("n.obj", &text)]).unwrap_err();
        assert!(matches!(e.root(), SceneError::BadVertex(_)), "{e:?}");
        let e = e.to_string();
        assert!(
            e.contains("n.obj:2:") && e.contains("vertex 2"),
            "{bad}: {e}"
        );
    }
}

#[test]
fn obj_index_errors_name_the_line() {
    let cases = [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            ":4:",
            "face index 9",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            ":4:",
            "face index 0",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
            ":4:",
            "face index -4",
        ),
        ("v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n", ":2:", "three numbers"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n",
            ":4:",
            "not a vertex index",
        ),
    ];
    for (text, at, what) in cases {
        let e = load_obj("idx", &[("i.obj", text)]).unwrap_err();
        assert!(matches!(e, SceneError::MalformedObj(_)), "{e:?}");
        let e = e.to_string();
        assert!(
            e.contains(&format!("i.obj{at}")) && e.contains(what),
            "{text}: {e}"
        );
    }
    // Bad texture/normal indices (tobj would overflow on them) are ignored:
    // the model uses positions only.
    let s = load_obj(
        "vtvn",
        &[(
            "t.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/0/0 2/-9/-9 3/5/5\n",
        )],
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 1);
    // Negative (relative) indices that are in range are fine.
    let s = load_obj(
        "rel",
        &[("r.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n")],
    )
    .unwrap();
    assert_eq!(s.triangles.len(), 1);
}

#[test]
fn obj_without_triangles_is_an_error() {
    for text in ["", "v 0 0 0\nv 1 0 0\n", "v 0 0 0\nv 1 0 0\nl 1 2\np 1\n"] {
        let e = load_obj("zero", &[("z.obj", text)]).unwrap_err();
        assert!(matches!(e, SceneError::Empty(_)), "{e:?}");
        let e = e.to_string();
        assert!(e.contains("no triangles") && e.contains("z.obj"), "{e}");
    }
    let e = load_obj("alldeg", &[("d.obj", "v 0 0 0\nv 1 0 0\nf 1 2 1\n")]).unwrap_err();
    assert!(matches!(e, SceneError::Empty(_)), "{e:?}");
    assert!(e.to_string().contains("no triangles"), "{e}");
}

#[test]
fn obj_degenerate_triangles_are_dropped_with_a_warning() {
    let text = format!("{QUAD}v 2 0 0\nf 1 2 5\nf 1 1 3\n");
    let s = load_obj("deg", &[("d.obj", &text)]).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("dropped 2 degenerate")),
        "{:?}",
        s.warnings
    );
}

#[test]
fn obj_materials_from_mtl_and_missing_mtl_warns() {
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\nnewmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl hot\nKd 2 0.5 0.5\n";
    let obj = format!(
        "mtllib m.mtl\n{QUAD}usemtl red\nf 1 2 3\nusemtl glow\nf 1 3 4\nusemtl hot\nf 2 3 4\nusemtl nosuch\nf 1 2 4\n"
    );
    let s = load_obj("mtl", &[("m.obj", &obj), ("m.mtl", mtl)]).unwrap();
    let alb: Vec<Vec3> = s
        .tri_material
        .iter()
        .map(|&m| s.materials[m as usize].albedo)
        .collect();
    assert_eq!(
        alb,
        [
            // The quad before the first usemtl has no material.
            Vec3::splat(DEFAULT_ALBEDO),
            Vec3::splat(DEFAULT_ALBEDO),
            Vec3::new(0.8, 0.1, 0.1),
            Vec3::splat(0.5),
            Vec3::new(1.0, 0.5, 0.5),
            Vec3::splat(DEFAULT_ALBEDO)
        ]
    );
    let has = |w: &str| s.warnings.iter().any(|x| x.contains(w));
    assert!(
        has("emission") && has("clamped") && has("3 triangles have no material"),
        "{:?}",
        s.warnings
    );

    // mtllib that does not exist: a warning, grey albedo.
    let s = load_obj("nomtl", &[("m.obj", &obj)]).unwrap();
    assert!(
        s.materials
            .iter()
            .all(|m| m.albedo == Vec3::splat(DEFAULT_ALBEDO))
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("m.mtl") && w.contains("could not be read")),
        "{:?}",
        s.warnings
    );
    // usemtl without any mtllib (like dragon_box.obj): a warning, grey albedo.
    let s = load_obj(
        "nolib",
        &[("b.obj", &format!("{QUAD}usemtl walls\nf 1 2 3\n"))],
    )
    .unwrap();
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("3 triangles have no material")),
        "{:?}",
        s.warnings
    );

    // A short Kd line (tobj itself would panic) is an error naming the line.
    let e = load_obj(
        "shortkd",
        &[("m.obj", &obj), ("m.mtl", "newmtl red\nKa 1 1 1\nKd 0.5\n")],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("m.mtl:3:") && e.contains("Kd"), "{e}");
    // Kd NaN in the .mtl is an error naming the material.
    let e = load_obj(
        "nanmtl",
        &[("m.obj", &obj), ("m.mtl", "newmtl red\nKd nan 0 0\n")],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("red") && e.contains("Kd"), "{e}");
}

#[test]
fn toml_mesh_paths_are_relative_to_the_scene_file() {
    let scene = "[[mesh]]\npath = \"sub/q.obj\"\nscale = 2.0\nalbedo = [0.2, 0.3, 0.4]\n";
    let d = temp("rel-toml", &[("s.toml", scene)]);
    std::fs::create_dir_all(d.join("sub")).unwrap();
    std::fs::write(d.join("sub/q.obj"), format!("mtllib none.mtl\n{QUAD}")).unwrap();
    let s = load(d.join("s.toml").to_str().unwrap());
    let e = load(d.join("missing.toml").to_str().unwrap())
        .unwrap_err()
        .to_string();
    std::fs::write(d.join("bad.toml"), "[[mesh]]\npath = \"sub/nope.obj\"\n").unwrap();
    let e2 = load(d.join("bad.toml").to_str().unwrap())
        .unwrap_err()
        .to_string();
    let _ = std::fs::remove_dir_all(&d);
    let s = s.unwrap();
    assert_eq!(s.name, "s");
    assert_eq!(s.bounds().max, Vec3::new(2.0, 2.0, 0.0));
    assert_eq!(
        s.materials,
        vec![Material {
            albedo: Vec3::new(0.2, 0.3, 0.4)
        }]
    );
    assert!(e.contains("missing.toml"), "{e}");
    assert!(
        e2.contains("bad.toml:1") && e2.contains("sub/nope.obj") && e2.contains("relative"),
        "{e2}"
    );
}

// ---------------------------------------------------------------- coordinate range

/// The error names the f32 limit and the fix, not a symptom of the overflow.
fn names_the_range(e: &str, limit: &str) {
    assert!(
        e.contains(limit) && e.contains("f32 datapath"),
        "should name the limit {limit}: {e}"
    );
    for symptom in ["degenerate", "parallel", "no triangles", "same point"] {
        assert!(!e.contains(symptom), "names a symptom ({symptom}): {e}");
    }
}

#[test]
fn obj_beyond_the_coordinate_range_names_the_vertex_and_the_fix() {
    // Near 1e38 every cross product overflows: the triangles used to be dropped
    // as zero-area and the file refused as "all degenerate".
    let huge = "v 1e38 0 0\nv 0 1e38 0\nv 0 0 1e38\nv 1e38 1e38 0\nf 1 2 3\nf 1 2 4\n";
    let e = load_obj("huge", &[("h.obj", huge)])
        .unwrap_err()
        .to_string();
    names_the_range(&e, "1e6");
    assert!(
        e.contains("h.obj:1:") && e.contains("vertex 1") && e.contains("scale or recentre"),
        "{e}"
    );
    // One small triangle far out: the automatic framing used to overflow and
    // blame the camera's up vector.
    let far = "v 1e38 0 0\nv 1e38 1 0\nv 1e38 0 1\nf 1 2 3\n";
    let e = load_obj("far", &[("f.obj", far)]).unwrap_err().to_string();
    names_the_range(&e, "1e6");
    assert!(e.contains("f.obj:1:") && e.contains("vertex 1"), "{e}");
    // The vertex named is the first one out of range, just past the limit.
    let past = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1000001 0 0\nf 1 2 3\nf 2 4 3\n";
    let e = load_obj("past", &[("p.obj", past)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("p.obj:4:") && e.contains("vertex 4"), "{e}");
    // At the limit is fine.
    let at = "v 0 0 0\nv 1000000 0 0\nv 0 -1000000 0\nf 1 2 3\n";
    assert!(load_obj("at", &[("a.obj", at)]).is_ok());
}

#[test]
fn toml_meshes_camera_and_light_beyond_the_range_are_named() {
    let cases = [
        // A mesh moved out of range by its transform.
        (
            "translate = [0.0, 0.0, 0.1]",
            "translate = [3e6, 0.0, 0.1]",
            ":21: mesh 2",
            "1e6",
        ),
        (
            "center = [0.0, 1.0, 0.0]",
            "center = [0.0, 1e38, 0.0]",
            ":21: mesh 2",
            "1e6",
        ),
        (
            "eye = [0.0, 1.0, 5.0]",
            "eye = [0.0, 1.0, 2e7]",
            ":4:",
            "1e7",
        ),
        (
            "look_at = [0.0, 1.0, 0.0]",
            "look_at = [-1e38, 1.0, 0.0]",
            ":4:",
            "1e7",
        ),
        (
            "position = [0.0, 3.0, 0.0]",
            "position = [0.0, 3e7, 0.0]",
            ":8:",
            "1e7",
        ),
    ];
    for (from, to, at, limit) in cases {
        let e = bad(from, to);
        assert!(e.starts_with("t.toml") && e.contains(at), "{to}: {e}");
        names_the_range(&e, limit);
    }
    let e = bad("eye = [0.0, 1.0, 5.0]", "eye = [0.0, 1.0, 2e7]");
    assert!(e.contains("camera eye"), "{e}");
    let e = bad("position = [0.0, 3.0, 0.0]", "position = [0.0, 3e7, 0.0]");
    assert!(e.contains("light position"), "{e}");
    // An up vector whose square underflows is not "the zero vector".
    let e = bad("vfov = 45.0", "vfov = 45.0\nup = [0.0, 1e-30, 0.0]");
    assert!(
        e.contains("cannot be normalised") && e.contains(":4:"),
        "{e}"
    );
}

#[test]
fn automatic_framing_out_of_range_is_named() {
    // A mesh at the limit through a tall, narrow image: the framing camera would
    // stand beyond the view limit.
    let src = "[render]\nwidth = 1\nheight = 1000\n[[mesh]]\nbuiltin = \"box\"\n\
               min = [-1e6, -1e6, -1e6]\nmax = [1e6, 1e6, 1e6]\n";
    let e = parse(src).unwrap_err().to_string();
    assert!(e.contains("framing") && e.contains("[camera]"), "{e}");
    names_the_range(&e, "1e7");
    // The same mesh through a square image frames within range.
    let sq = src.replace("width = 1\n", "width = 1000\n");
    let s = parse(&sq).unwrap();
    assert!(s.camera.eye.z < crate::geom::MAX_VIEW_COORD);
}

#[test]
fn scene_validation_checks_the_range_too() {
    let mut s = load("cornell").unwrap();
    s.triangles[5].v1.y = 1e38;
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("triangle 5"), "{e}");
    names_the_range(&e, "1e6");
    let mut s = load("cornell").unwrap();
    s.light.position.x = -2e7;
    let e = s.validate().unwrap_err().to_string();
    assert!(e.contains("light position"), "{e}");
    names_the_range(&e, "1e7");
}
