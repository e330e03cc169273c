//! Scene descriptions (.toml): meshes (OBJ files or procedural), camera,
//! light, sky and render settings. Unknown keys are errors, so typos do not
//! silently fall back to defaults. Errors name the file and line.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;
use toml::Spanned;

use super::{
    Builder, Camera, DEFAULT_SKY, PointLight, RenderSettings, Scene, SceneError, Xform, line_of,
    obj,
};
use crate::geom::shapes::{box_mesh, quad, uv_sphere};
use crate::util::FileError;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Desc {
    name: Option<String>,
    sky: Option<Spanned<[f32; 3]>>,
    camera: Option<Spanned<CamDesc>>,
    light: Option<Spanned<LightDesc>>,
    #[serde(default)]
    render: RenderDesc,
    #[serde(default)]
    mesh: Vec<Spanned<MeshDesc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CamDesc {
    eye: [f32; 3],
    look_at: [f32; 3],
    #[serde(default = "y_up")]
    up: [f32; 3],
    vfov: f32,
}

fn y_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightDesc {
    position: [f32; 3],
    intensity: [f32; 3],
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RenderDesc {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    bounces: Option<Spanned<u32>>,
    seed: Option<u64>,
}

/// One `[[mesh]]`: either `path` (an .obj, relative to the scene file) or
/// `builtin` = "sphere" {center, radius, stacks = 16, slices = 32} |
/// "box" {min, max} | "quad" {corners = 4 points, counter-clockwise}.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshDesc {
    path: Option<String>,
    builtin: Option<String>,
    center: Option<[f32; 3]>,
    radius: Option<f32>,
    stacks: Option<u32>,
    slices: Option<u32>,
    min: Option<[f32; 3]>,
    max: Option<[f32; 3]>,
    corners: Option<[[f32; 3]; 4]>,
    scale: Option<f32>,
    translate: Option<[f32; 3]>,
    rotate_y: Option<f32>,
    albedo: Option<[f32; 3]>,
}

fn v3(a: [f32; 3]) -> Vec3 {
    Vec3::from_array(a)
}

fn finite(a: &[f32]) -> bool {
    a.iter().all(|x| x.is_finite())
}

pub(crate) fn load(path: &Path) -> Result<Scene, SceneError> {
    let shown = path.display().to_string();
    let src = std::fs::read_to_string(path).map_err(|e| {
        let msg = format!("cannot read scene file '{shown}' ({e}); check the path");
        SceneError::File(FileError::new(path, e, msg))
    })?;
    parse(&src, &shown, path.parent().unwrap_or(Path::new("")))
}

/// Parses scene text; `shown` names it in errors, mesh paths are relative to `dir`.
pub(crate) fn parse(src: &str, shown: &str, dir: &Path) -> Result<Scene, SceneError> {
    let d: Desc = toml::from_str(src).map_err(|e| {
        // toml's message does not name the key; quote the line it points at.
        match e.span() {
            Some(s) => {
                let n = line_of(src, s.start);
                let text = src.lines().nth(n - 1).unwrap_or("").trim();
                SceneError::BadDesc(format!("{shown}:{n}: {} (in `{text}`)", e.message().trim()))
            }
            None => SceneError::BadDesc(format!("{shown}: {}", e.message().trim())),
        }
    })?;
    let at = |start: usize| format!("{shown}:{}", line_of(src, start));

    let mut s = RenderSettings::default();
    let r = &d.render;
    for (field, name) in [
        (&r.width, "width"),
        (&r.height, "height"),
        (&r.bounces, "bounces"),
    ] {
        if let Some(v) = field {
            let probe = match name {
                "width" => RenderSettings {
                    width: *v.get_ref(),
                    ..s
                },
                "height" => RenderSettings {
                    height: *v.get_ref(),
                    ..s
                },
                _ => RenderSettings {
                    bounces: *v.get_ref(),
                    ..s
                },
            };
            probe.validate().map_err(|e| e.at(at(v.span().start)))?;
            s = probe;
        }
    }
    if let Some(seed) = r.seed {
        s.seed = seed;
    }

    let mut b = Builder::default();
    if d.mesh.is_empty() {
        return Err(SceneError::Empty(format!(
            "{shown}: scene has no triangles (no [[mesh]] entries); add one, e.g. [[mesh]] path = \"model.obj\""
        )));
    }
    for (k, m) in d.mesh.iter().enumerate() {
        let here = format!("{}: mesh {}", at(m.span().start), k + 1);
        add_mesh(&mut b, m.get_ref(), dir, &here)?;
    }
    if b.triangles.is_empty() {
        return Err(SceneError::Empty(format!(
            "{shown}: scene has no triangles (all were degenerate)"
        )));
    }

    let aspect = s.width as f32 / s.height as f32;
    // The copyable snippet is reported only for what is missing.
    let (auto_cam, auto_light) = b
        .auto_view(aspect, d.camera.is_none(), d.light.is_none())
        .map_err(|e| e.at(shown))?;
    let camera = match &d.camera {
        Some(c) => {
            let cd = c.get_ref();
            let cam = Camera {
                eye: v3(cd.eye),
                look_at: v3(cd.look_at),
                up: v3(cd.up),
                vfov_deg: cd.vfov,
            };
            cam.validate().map_err(|e| e.at(at(c.span().start)))?;
            cam
        }
        None => auto_cam,
    };
    let light = match &d.light {
        Some(l) => {
            let ld = l.get_ref();
            if !finite(&ld.position)
                || !finite(&ld.intensity)
                || ld.intensity.iter().any(|&x| x < 0.0)
            {
                return Err(SceneError::BadDesc(format!(
                    "{}: light position {:?} and intensity {:?} must be finite, intensity >= 0",
                    at(l.span().start),
                    ld.position,
                    ld.intensity
                )));
            }
            super::light_in_range(v3(ld.position)).map_err(|e| e.at(at(l.span().start)))?;
            PointLight {
                position: v3(ld.position),
                intensity: v3(ld.intensity),
            }
        }
        None => auto_light,
    };
    let sky = match &d.sky {
        Some(v) => {
            let a = *v.get_ref();
            if !finite(&a) || a.iter().any(|&x| x < 0.0) {
                return Err(SceneError::BadDesc(format!(
                    "{}: sky {a:?} must be finite and >= 0",
                    at(v.span().start)
                )));
            }
            v3(a)
        }
        None => Vec3::splat(DEFAULT_SKY),
    };
    let name = d.name.clone().unwrap_or_else(|| {
        Path::new(shown)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    Ok(Scene {
        name,
        triangles: b.triangles,
        tri_material: b.tri_material,
        materials: b.materials,
        camera,
        light,
        sky,
        settings: s,
        warnings: b.warnings,
    })
}

fn add_mesh(b: &mut Builder, m: &MeshDesc, dir: &Path, here: &str) -> Result<(), SceneError> {
    let albedo = match m.albedo {
        Some(a) if !(finite(&a) && a.iter().all(|&x| (0.0..=1.0).contains(&x))) => {
            return Err(SceneError::BadDesc(format!(
                "{here}: albedo {a:?} must be three numbers in [0, 1]"
            )));
        }
        a => a.map(v3),
    };
    let xf = Xform {
        scale: m.scale.unwrap_or(1.0),
        rotate_y_deg: m.rotate_y.unwrap_or(0.0),
        translate: v3(m.translate.unwrap_or([0.0; 3])),
    };
    let ok = xf.scale.is_finite()
        && xf.scale > 0.0
        && xf.rotate_y_deg.is_finite()
        && xf.translate.is_finite();
    if !ok {
        return Err(SceneError::BadDesc(format!(
            "{here}: scale must be finite and > 0, rotate_y and translate finite"
        )));
    }
    let kind = match (&m.path, &m.builtin) {
        (Some(p), None) => {
            let unused = [
                ("center", m.center.is_some()),
                ("radius", m.radius.is_some()),
                ("stacks", m.stacks.is_some()),
                ("slices", m.slices.is_some()),
                ("min", m.min.is_some()),
                ("max", m.max.is_some()),
                ("corners", m.corners.is_some()),
            ];
            if let Some((k, _)) = unused.iter().find(|u| u.1) {
                return Err(SceneError::BadDesc(format!(
                    "{here}: `{k}` applies only to builtin meshes; remove it"
                )));
            }
            let full = super::search::find(dir, Path::new(p)).map_err(|tried| {
                SceneError::BadDesc(format!(
                    "{here}: mesh file '{p}' not found (a path is relative to the scene file); {}",
                    super::search::tried_text(&tried)
                ))
            })?;
            obj::load_into(b, &full, &xf, albedo).map_err(|e| e.at(here))?;
            return Ok(());
        }
        (None, Some(k)) => k.as_str(),
        (Some(_), Some(_)) => {
            return Err(SceneError::BadDesc(format!(
                "{here}: give either `path` or `builtin`, not both"
            )));
        }
        (None, None) => {
            return Err(SceneError::BadDesc(format!(
                "{here}: a mesh needs `path = \"file.obj\"` or `builtin = \"sphere\" | \"box\" | \"quad\"`"
            )));
        }
    };
    let allowed: &[&str] = match kind {
        "sphere" => &["center", "radius", "stacks", "slices"],
        "box" => &["min", "max"],
        "quad" => &["corners"],
        _ => {
            return Err(SceneError::BadDesc(format!(
                "{here}: unknown builtin mesh '{kind}'; use \"sphere\", \"box\" or \"quad\""
            )));
        }
    };
    let given = [
        ("center", m.center.is_some()),
        ("radius", m.radius.is_some()),
        ("stacks", m.stacks.is_some()),
        ("slices", m.slices.is_some()),
        ("min", m.min.is_some()),
        ("max", m.max.is_some()),
        ("corners", m.corners.is_some()),
    ];
    if let Some((k, _)) = given.iter().find(|(k, g)| *g && !allowed.contains(k)) {
        return Err(SceneError::BadDesc(format!(
            "{here}: `{k}` does not apply to builtin \"{kind}\" (it takes {allowed:?})"
        )));
    }
    let need = |k: &str| SceneError::BadDesc(format!("{here}: builtin \"{kind}\" needs `{k}`"));
    let tris = match kind {
        "sphere" => {
            let c = m.center.ok_or_else(|| need("center"))?;
            let r = m.radius.ok_or_else(|| need("radius"))?;
            let (st, sl) = (m.stacks.unwrap_or(16), m.slices.unwrap_or(32));
            let ok = finite(&c)
                && r.is_finite()
                && r > 0.0
                && (2..=1024).contains(&st)
                && (3..=2048).contains(&sl);
            if !ok {
                return Err(SceneError::BadDesc(format!(
                    "{here}: sphere needs a finite center, radius > 0, stacks in 2..=1024, slices in 3..=2048"
                )));
            }
            uv_sphere(v3(c), r, st, sl)
        }
        "box" => {
            let (lo, hi) = (
                m.min.ok_or_else(|| need("min"))?,
                m.max.ok_or_else(|| need("max"))?,
            );
            if !finite(&lo) || !finite(&hi) || (0..3).any(|i| lo[i] >= hi[i]) {
                return Err(SceneError::BadDesc(format!(
                    "{here}: box needs finite min < max on every axis, got {lo:?}..{hi:?}"
                )));
            }
            box_mesh(v3(lo), v3(hi))
        }
        _ => {
            let c = m.corners.ok_or_else(|| need("corners"))?;
            if !c.iter().all(|p| finite(p)) {
                return Err(SceneError::BadDesc(format!(
                    "{here}: quad corners must be finite"
                )));
            }
            quad(v3(c[0]), v3(c[1]), v3(c[2]), v3(c[3])).to_vec()
        }
    };
    let mut tris = tris;
    xf.apply(&mut tris);
    if tris
        .iter()
        .any(|t| !(t.v0.is_finite() && t.v1.is_finite() && t.v2.is_finite()))
    {
        return Err(SceneError::BadVertex(format!(
            "{here}: coordinates overflow after the transform; use a smaller scale"
        )));
    }
    if let Some((i, v)) = super::first_beyond(&tris) {
        return Err(SceneError::BadVertex(format!(
            "{here}: builtin \"{kind}\" triangle {} has a vertex {}",
            i + 1,
            super::too_far(v)
        )));
    }
    b.add_mesh(
        here,
        tris,
        albedo.unwrap_or(Vec3::splat(super::DEFAULT_ALBEDO)),
    );
    Ok(())
}
