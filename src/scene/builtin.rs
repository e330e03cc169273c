//! Builtin procedural scenes: deterministic, no files. Every one is a closed
//! room (rays from inside never escape) built from `geom::shapes`, whose shared
//! vertices are bit-identical; the objects in it are closed meshes too.
//!
//! Light intensities: a Lambertian surface at distance D from the light reflects
//! albedo/pi * I/D^2 directly; I ~ 1.5 D^2 for the typical light-to-wall
//! distance D gives ~0.3 direct radiance at albedo 0.7, and the closed room's
//! interreflections (5 hit points) roughly double it. The unit tests check the
//! mean direct radiance seen by the camera stays in a sane band.

use glam::Vec3;

use super::{Builder, Camera, PointLight, RenderSettings, Scene, Xform};
use crate::geom::Triangle;
use crate::geom::shapes::{box_mesh, tube, uv_sphere};
use crate::util::rng::Rng;

pub(crate) const NAMES: &[&str] = &["cornell", "spheres", "tiny", "hairball"];

pub(crate) fn build(name: &str) -> Option<Scene> {
    match name {
        "cornell" => Some(cornell()),
        "spheres" => Some(spheres()),
        "tiny" => Some(tiny()),
        "hairball" => Some(hairball()),
        _ => None,
    }
}

const WHITE: Vec3 = Vec3::new(0.73, 0.73, 0.73);
const RED: Vec3 = Vec3::new(0.65, 0.05, 0.05);
const GREEN: Vec3 = Vec3::new(0.12, 0.45, 0.15);

/// A closed box seen from inside: `box_mesh` with every triangle's winding
/// reversed (normals point into the room; vertices unchanged, so still closed).
/// Faces in order -x, +x, -y, +y, -z, +z, two triangles each.
fn room(min: Vec3, max: Vec3) -> Vec<Triangle> {
    box_mesh(min, max)
        .into_iter()
        .map(|t| Triangle::new(t.v0, t.v2, t.v1))
        .collect()
}

/// Adds a room with one albedo per face (-x, +x, -y, +y, -z, +z).
fn add_room(b: &mut Builder, min: Vec3, max: Vec3, faces: [Vec3; 6]) {
    let ids = faces.map(|a| b.material(a));
    let tris = room(min, max);
    b.add(
        "room",
        tris.into_iter().enumerate().map(|(i, t)| (t, ids[i / 2])),
    );
}

fn finish(
    name: &str,
    b: Builder,
    camera: Camera,
    light: PointLight,
    settings: RenderSettings,
) -> Scene {
    Scene {
        name: name.to_string(),
        triangles: b.triangles,
        tri_material: b.tri_material,
        materials: b.materials,
        camera,
        light,
        // Closed rooms: a miss cannot happen; black makes a leak visible.
        sky: Vec3::ZERO,
        settings,
        warnings: b.warnings,
    }
}

/// Cornell-style box, 2 x 2 wide and high, red left (-x) and green right (+x)
/// walls, lengthened towards the camera (z up to 3) and closed by a front wall
/// behind the camera; a tessellated sphere and a rotated tall box inside.
/// 2,232 triangles.
fn cornell() -> Scene {
    let mut b = Builder::default();
    add_room(
        &mut b,
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 3.0),
        [RED, GREEN, WHITE, WHITE, WHITE, WHITE],
    );
    b.add_mesh(
        "sphere",
        uv_sphere(Vec3::new(-0.45, 0.4, -0.2), 0.4, 24, 48),
        WHITE,
    );
    let mut tall = box_mesh(Vec3::new(-0.3, 0.0, -0.3), Vec3::new(0.3, 1.2, 0.3));
    Xform {
        scale: 1.0,
        rotate_y_deg: 20.0,
        translate: Vec3::new(0.45, 0.0, -0.45),
    }
    .apply(&mut tall);
    b.add_mesh("tall box", tall, WHITE);
    let camera = Camera {
        eye: Vec3::new(0.0, 1.0, 2.9),
        look_at: Vec3::new(0.0, 1.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 40.0,
    };
    let light = PointLight {
        position: Vec3::new(0.0, 1.9, 0.0),
        intensity: Vec3::splat(1.5),
    };
    finish("cornell", b, camera, light, RenderSettings::default())
}

/// Many tessellated spheres of varied size on a jittered 7 x 5 x 7 grid inside
/// a closed room; the camera looks through the cluster, so rays pass many
/// layers (real depth complexity). ~100K triangles.
fn spheres() -> Scene {
    let mut b = Builder::default();
    add_room(
        &mut b,
        Vec3::new(-8.0, 0.0, -8.0),
        Vec3::new(8.0, 10.0, 16.0),
        [WHITE, WHITE, Vec3::splat(0.5), WHITE, WHITE, WHITE],
    );
    const PALETTE: [Vec3; 6] = [
        Vec3::new(0.8, 0.8, 0.8),
        Vec3::new(0.75, 0.25, 0.2),
        Vec3::new(0.2, 0.6, 0.25),
        Vec3::new(0.25, 0.35, 0.75),
        Vec3::new(0.8, 0.7, 0.2),
        Vec3::new(0.5, 0.5, 0.5),
    ];
    let ids = PALETTE.map(|a| b.material(a));
    let mut rng = Rng::new(0x5EED_0F5F_E7E5);
    let (nx, ny, nz) = (7, 5, 7);
    let lo = Vec3::new(-6.0, 0.5, -6.0);
    let cell = Vec3::new(12.0 / nx as f32, 9.0 / ny as f32, 12.0 / nz as f32);
    let half = cell.min_element() * 0.5;
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let r = half * rng.range_f32(0.25, 0.85);
                let slack = half - r;
                let c = Vec3::new(
                    lo.x + (i as f32 + 0.5) * cell.x + rng.range_f32(-slack, slack),
                    lo.y + (j as f32 + 0.5) * cell.y + rng.range_f32(-slack, slack),
                    lo.z + (k as f32 + 0.5) * cell.z + rng.range_f32(-slack, slack),
                );
                let stacks = 8 + rng.below(7) as u32;
                let m = ids[rng.below(PALETTE.len() as u64) as usize];
                let s = uv_sphere(c, r, stacks, 2 * stacks);
                b.add("sphere", s.into_iter().map(|t| (t, m)));
            }
        }
    }
    let camera = Camera {
        eye: Vec3::new(0.0, 5.0, 15.5),
        look_at: Vec3::new(0.0, 5.0, 0.0),
        up: Vec3::Y,
        vfov_deg: 50.0,
    };
    let light = PointLight {
        position: Vec3::new(0.0, 9.7, 9.0),
        intensity: Vec3::splat(200.0),
    };
    finish("spheres", b, camera, light, RenderSettings::default())
}

/// 48 triangles: a room, a box and a coarse sphere, for fast tests.
fn tiny() -> Scene {
    let mut b = Builder::default();
    add_room(
        &mut b,
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 1.0),
        [RED, GREEN, WHITE, WHITE, WHITE, WHITE],
    );
    b.add_mesh(
        "box",
        box_mesh(Vec3::new(0.1, 0.0, -0.6), Vec3::new(0.6, 0.7, -0.1)),
        WHITE,
    );
    b.add_mesh(
        "sphere",
        uv_sphere(Vec3::new(-0.4, 0.35, -0.3), 0.35, 3, 6),
        WHITE,
    );
    let camera = Camera {
        eye: Vec3::new(0.0, 1.0, 0.95),
        look_at: Vec3::new(0.0, 0.7, -1.0),
        up: Vec3::Y,
        vfov_deg: 70.0,
    };
    let light = PointLight {
        position: Vec3::new(0.0, 1.8, 0.0),
        intensity: Vec3::splat(3.5),
    };
    let settings = RenderSettings {
        width: 32,
        height: 32,
        ..RenderSettings::default()
    };
    finish("tiny", b, camera, light, settings)
}

/// Hairs in the hairball: [`HAIR_POINTS`] points each, [`HAIR_SIDES`] sides.
const HAIRS: usize = 2500;
const HAIR_POINTS: usize = 12;
const HAIR_SIDES: u32 = 5;
/// Radius of the ball the hairs stay in, and of a hair.
const BALL_RADIUS: f64 = 1.0;
const HAIR_RADIUS: f32 = 0.005;

/// High depth complexity, like the paper's Hairball: 2,500 thin capped tubes
/// (random walks of 11 steps of 0.12, each step's direction the last one's
/// jittered, turned back towards the centre at the ball's surface) filling a ball of radius 1 at the origin,
/// in a closed room. A ray through the ball crosses about a dozen hairs, so
/// most rays pass many segments behind their closest hit. 300,000 triangles.
fn hairball() -> Scene {
    let mut b = Builder::default();
    add_room(
        &mut b,
        Vec3::new(-3.0, -2.0, -3.0),
        Vec3::new(3.0, 3.0, 5.0),
        [WHITE, WHITE, Vec3::splat(0.5), WHITE, WHITE, WHITE],
    );
    const PALETTE: [Vec3; 4] = [
        Vec3::new(0.55, 0.35, 0.2),
        Vec3::new(0.7, 0.55, 0.3),
        Vec3::new(0.35, 0.2, 0.12),
        Vec3::new(0.8, 0.75, 0.6),
    ];
    let ids = PALETTE.map(|a| b.material(a));
    let mut rng = Rng::new(0x04A1_BA11_5EED);
    // Uniform in [-1, 1) (f64 from 53 random bits).
    let mut uni = move || (rng.next_u64() >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0;
    let len = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    let inside = BALL_RADIUS - 2.0 * HAIR_RADIUS as f64;
    for h in 0..HAIRS {
        // A start in the ball and a direction, both by rejection.
        let mut p = loop {
            let c = [uni(), uni(), uni()];
            if len(c) < 0.95 * inside {
                break c;
            }
        };
        let mut d = loop {
            let c = [uni(), uni(), uni()];
            let l = len(c);
            if l > 0.1 && l < 1.0 {
                break c.map(|x| x / l);
            }
        };
        let mut pts = vec![p];
        while pts.len() < HAIR_POINTS {
            let j = [uni(), uni(), uni()];
            let mut e = [0.0; 3];
            for k in 0..3 {
                e[k] = d[k] + 0.6 * j[k];
            }
            let l = len(e);
            if l < 1e-3 {
                continue;
            }
            d = e.map(|x| x / l);
            let mut q = [0.0; 3];
            for k in 0..3 {
                q[k] = p[k] + 0.12 * d[k];
            }
            if len(q) > inside {
                // Turn back into the ball: point the walk at its centre.
                let l = len(p);
                d = p.map(|x| -x / l);
                continue;
            }
            p = q;
            pts.push(p);
        }
        let m = ids[h % PALETTE.len()];
        b.add(
            "hair",
            tube(&pts, HAIR_RADIUS, HAIR_SIDES)
                .into_iter()
                .map(|t| (t, m)),
        );
    }
    let camera = Camera {
        eye: Vec3::new(0.0, 0.3, 3.2),
        look_at: Vec3::ZERO,
        up: Vec3::Y,
        vfov_deg: 42.0,
    };
    let light = PointLight {
        position: Vec3::new(1.5, 2.6, 3.0),
        intensity: Vec3::splat(30.0),
    };
    finish("hairball", b, camera, light, RenderSettings::default())
}
