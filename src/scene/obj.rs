//! Wavefront OBJ loading (tobj) with validation.
//!
//! tobj reports only an error kind (no line, no index) and accepts `nan`/`inf`
//! coordinates, so on any problem this module re-reads the file to point at the
//! offending line; the fast path reads it once.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::Vec3;

use super::{Builder, DEFAULT_ALBEDO, DEFAULT_SKY, RenderSettings, Scene, SceneError, Xform};
use crate::geom::Triangle;
use crate::util::FileError;

const OPTIONS: tobj::LoadOptions = tobj::LoadOptions {
    triangulate: true,
    single_index: false,
    ignore_points: true,
    ignore_lines: true,
};

/// Loads the .obj at `path` into `b`, transformed by `xform`. `albedo` overrides
/// the .mtl materials. Returns the number of triangles read (before degenerate
/// ones are dropped).
pub(crate) fn load_into(
    b: &mut Builder,
    path: &Path,
    xform: &Xform,
    albedo: Option<Vec3>,
) -> Result<usize, SceneError> {
    let geometry = read_geometry(path)?;
    let (models, mats) = parse(b, path, &geometry)?;
    let mat_ids = scene_materials(b, path, &mats, albedo)?;
    let tris = triangles(b, path, &models, &mat_ids, albedo)?;
    let n = tris.len();
    place(b, path, xform, tris)?;
    Ok(n)
}

/// The file as text with its `vt`/`vn` lines blanked.
fn read_geometry(path: &Path) -> Result<String, SceneError> {
    let shown = path.display();
    let bytes = std::fs::read(path).map_err(|e| {
        let msg = format!("cannot open OBJ file '{shown}' ({e}); check the path (paths in a scene file are relative to that file)");
        SceneError::File(FileError::new(path, e, msg))
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        SceneError::MalformedObj(format!(
            "{shown}: not UTF-8 text (bad byte at offset {}); save it as ASCII/UTF-8",
            e.utf8_error().valid_up_to()
        ))
    })?;
    // tobj indexes texture coordinates and normals without overflow checks (a
    // bad `vt`/`vn` index panics in debug builds) and the model uses neither,
    // so those lines are blanked (kept as empty lines: numbering unchanged).
    Ok(text
        .lines()
        .map(|l| match l.split_whitespace().next() {
            Some("vt" | "vn") => "",
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n"))
}

/// tobj's models and the materials of the libraries it could read (a warning
/// names each library it could not).
fn parse(
    b: &mut Builder,
    path: &Path,
    geometry: &str,
) -> Result<(Vec<tobj::Model>, Vec<tobj::Material>), SceneError> {
    let shown = path.display();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    // Which material libraries the file asked for, whether they loaded, and
    // syntax errors in them (tobj panics on a short `Kd` line, so they are
    // checked here first).
    let libs: RefCell<Vec<(PathBuf, Option<String>)>> = RefCell::new(Vec::new());
    let bad_mtl: RefCell<Option<String>> = RefCell::new(None);
    let loaded = tobj::load_obj_buf(&mut geometry.as_bytes(), &OPTIONS, |p| {
        let full = dir.join(p);
        let r = match std::fs::read_to_string(&full) {
            Err(e) => Err((tobj::LoadError::OpenFileFailed, e.to_string())),
            Ok(src) => match check_mtl(&full, &src) {
                Err(msg) => {
                    bad_mtl.borrow_mut().get_or_insert(msg);
                    Err((
                        tobj::LoadError::MaterialParseError,
                        "syntax error".to_string(),
                    ))
                }
                Ok(()) => tobj::load_mtl_buf(&mut src.as_bytes()).map_err(|e| (e, e.to_string())),
            },
        };
        libs.borrow_mut()
            .push((full, r.as_ref().err().map(|e| e.1.clone())));
        r.map_err(|e| e.0)
    });
    if let Some(msg) = bad_mtl.into_inner() {
        return Err(SceneError::MalformedObj(msg));
    }
    let (models, mats) = loaded.map_err(|e| SceneError::MalformedObj(diagnose(path, &e)))?;
    // tobj returns the readable libraries' materials, numbered in file order.
    let mats = mats.unwrap_or_default();
    for (lib, err) in libs.into_inner() {
        if let Some(e) = err {
            b.warnings.push(format!(
                "{shown}: material library '{}' could not be read ({e}); its materials get albedo {DEFAULT_ALBEDO} grey",
                lib.display()
            ));
        }
    }
    Ok((models, mats))
}

/// Scene material index for each tobj material (the libraries in order, as
/// tobj numbers them).
fn scene_materials(
    b: &mut Builder,
    path: &Path,
    mats: &[tobj::Material],
    albedo: Option<Vec3>,
) -> Result<Vec<u32>, SceneError> {
    let shown = path.display();
    // Materials are created on first use (Builder::material deduplicates).
    let grey = Vec3::splat(DEFAULT_ALBEDO);
    let mut mat_ids = Vec::with_capacity(mats.len());
    for m in mats {
        let id = match (albedo, m.diffuse) {
            (Some(a), _) => b.material(a),
            (None, Some(kd)) => {
                let kd = Vec3::from_array(kd);
                if !(kd.is_finite() && kd.min_element() >= 0.0) {
                    return Err(SceneError::MalformedObj(format!(
                        "{shown}: material '{}' has Kd {kd:?}; give three numbers in [0, 1]",
                        m.name
                    )));
                }
                if kd.max_element() > 1.0 {
                    b.warnings.push(format!(
                        "{shown}: material '{}' Kd {kd:?} clamped to 1 (an albedo above 1 creates energy)",
                        m.name
                    ));
                }
                b.material(kd.min(Vec3::ONE))
            }
            (None, None) => {
                b.warnings.push(format!(
                    "{shown}: material '{}' has no Kd; using albedo {DEFAULT_ALBEDO} grey",
                    m.name
                ));
                b.material(grey)
            }
        };
        if let Some(ke) = m.emissive
            && ke.iter().any(|&k| k != 0.0)
        {
            b.warnings.push(format!(
                "{shown}: material '{}' emission Ke {ke:?} ignored (the only light is the scene's point light)",
                m.name
            ));
        }
        mat_ids.push(id);
    }
    Ok(mat_ids)
}

/// Every face as a triangle with its scene material (`albedo`, else grey, for
/// faces without one from an .mtl).
fn triangles(
    b: &mut Builder,
    path: &Path,
    models: &[tobj::Model],
    mat_ids: &[u32],
    albedo: Option<Vec3>,
) -> Result<Vec<(Triangle, u32)>, SceneError> {
    let shown = path.display();
    let fallback = albedo.unwrap_or(Vec3::splat(DEFAULT_ALBEDO));
    let mut tris = Vec::new();
    let mut no_material = 0usize;
    for model in models {
        let mesh = &model.mesh;
        if mesh.positions.iter().any(|c| !c.is_finite()) {
            return Err(SceneError::BadVertex(non_finite_vertex(path)));
        }
        let m = match mesh.material_id.and_then(|i| mat_ids.get(i)) {
            Some(&m) => m,
            None => {
                no_material += mesh.indices.len() / 3;
                b.material(fallback)
            }
        };
        let p = |i: u32| {
            let i = i as usize * 3;
            mesh.positions
                .get(i..i + 3)
                .map(|s| Vec3::new(s[0], s[1], s[2]))
                .ok_or_else(|| {
                    SceneError::MalformedObj(format!(
                        "{shown}: tobj returned an index out of range; report this file"
                    ))
                })
        };
        for f in mesh.indices.chunks_exact(3) {
            tris.push((Triangle::new(p(f[0])?, p(f[1])?, p(f[2])?), m));
        }
    }
    if no_material > 0 && albedo.is_none() {
        b.warnings.push(format!(
            "{shown}: {no_material} triangles have no material from an .mtl (no mtllib, a missing \
             library, or a usemtl name it lacks); using albedo {DEFAULT_ALBEDO} grey"
        ));
    }
    if tris.is_empty() {
        return Err(SceneError::Empty(format!(
            "{shown}: scene has no triangles (the file has no `f` faces with 3 or more vertices); check that it is a mesh OBJ"
        )));
    }
    Ok(tris)
}

/// Moves the triangles to world space by `xform`, checks they stay within the
/// datapath's range and adds them to `b`.
fn place(
    b: &mut Builder,
    path: &Path,
    xform: &Xform,
    tris: Vec<(Triangle, u32)>,
) -> Result<(), SceneError> {
    let shown = path.display();
    let mut only: Vec<Triangle> = tris.iter().map(|t| t.0).collect();
    xform.apply(&mut only);
    if only
        .iter()
        .any(|t| !(t.v0.is_finite() && t.v1.is_finite() && t.v2.is_finite()))
    {
        return Err(SceneError::BadVertex(format!(
            "{shown}: coordinates overflow after scale/translate {xform:?}; use a smaller scale"
        )));
    }
    if let Some((_, v)) = super::first_beyond(&only) {
        return Err(SceneError::BadVertex(vertex_beyond(path, xform, v)));
    }
    b.add(
        &shown.to_string(),
        only.into_iter().zip(tris.into_iter().map(|t| t.1)),
    );
    Ok(())
}

/// A bare .obj: the mesh plus a camera and light that frame it.
pub(crate) fn load_bare(path: &Path) -> Result<Scene, SceneError> {
    let mut b = Builder::default();
    load_into(&mut b, path, &Xform::IDENTITY, None)?;
    if b.triangles.is_empty() {
        return Err(SceneError::Empty(format!(
            "{}: scene has no triangles (all were degenerate)",
            path.display()
        )));
    }
    let settings = RenderSettings::default();
    let (camera, light) = b
        .auto_view(settings.width as f32 / settings.height as f32, true, true)
        .map_err(|e| e.at(path.display().to_string()))?;
    Ok(Scene {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        triangles: b.triangles,
        tri_material: b.tri_material,
        materials: b.materials,
        camera,
        light,
        sky: Vec3::splat(DEFAULT_SKY),
        settings,
        warnings: b.warnings,
    })
}

/// tobj panics on `Ka`/`Kd`/`Ks`/`Ke`/`Tf` lines with fewer than three values;
/// find them first and say where (a `String`: tobj's material callback carries
/// it, and `parse` wraps it as `SceneError::MalformedObj`).
fn check_mtl(path: &Path, src: &str) -> Result<(), String> {
    for (n, line) in src.lines().enumerate() {
        let mut w = line.split_whitespace();
        if let Some(k @ ("Ka" | "Kd" | "Ks" | "Ke" | "Tf")) = w.next()
            && w.take(3).count() < 3
        {
            return Err(format!(
                "{}:{}: `{k}` needs three numbers r g b, got '{}'; fix the material library",
                path.display(),
                n + 1,
                line.trim()
            ));
        }
    }
    Ok(())
}

/// Lines of the file, lossily decoded (only used on the error path).
fn lines(path: &Path) -> Vec<String> {
    std::fs::read(path)
        .map(|bytes| {
            String::from_utf8_lossy(&bytes)
                .lines()
                .map(str::to_owned)
                .collect()
        })
        .unwrap_or_default()
}

/// The first `v` line whose coordinates are not finite (after the optional w).
fn non_finite_vertex(path: &Path) -> String {
    let mut k = 0usize;
    for (n, line) in lines(path).iter().enumerate() {
        let mut w = line.split_whitespace();
        if w.next() != Some("v") {
            continue;
        }
        k += 1;
        let c: Vec<f32> = w.take(4).filter_map(|s| s.parse().ok()).collect();
        let scale = if c.len() == 4 { c[3] } else { 1.0 };
        if c.iter().take(3).any(|x| !(x / scale).is_finite()) {
            return format!(
                "{}:{}: vertex {k} has a non-finite coordinate ('{}'); replace it with finite numbers",
                path.display(),
                n + 1,
                line.trim()
            );
        }
    }
    format!(
        "{}: a vertex has a non-finite coordinate (NaN or inf); replace it with finite numbers",
        path.display()
    )
}

/// Names the `v` line of the vertex that lands at `world` (beyond the
/// datapath's range) after `xform`: the limit, where it is and the fix.
fn vertex_beyond(path: &Path, xform: &Xform, world: Vec3) -> String {
    let shown = path.display();
    let why = super::too_far(world);
    let mut k = 0usize;
    for (n, line) in lines(path).iter().enumerate() {
        let mut w = line.split_whitespace();
        if w.next() != Some("v") {
            continue;
        }
        k += 1;
        let c: Vec<f32> = w.take(3).filter_map(|s| s.parse().ok()).collect();
        if c.len() == 3 && xform.point(Vec3::new(c[0], c[1], c[2])) == world {
            let placed = if *xform == Xform::IDENTITY {
                String::new()
            } else {
                " (after the mesh's scale/rotate/translate)".to_string()
            };
            return format!(
                "{shown}:{}: vertex {k} ('{}'){placed} lies {why}",
                n + 1,
                line.trim()
            );
        }
    }
    format!("{shown}: a vertex lies {why}")
}

/// Turns a tobj error into a message with the file, line and fix.
fn diagnose(path: &Path, e: &tobj::LoadError) -> String {
    let shown = path.display();
    let text = lines(path);
    let total_v = text
        .iter()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count();
    let mut nv = 0usize;
    for (n, line) in text.iter().enumerate() {
        let at = format!("{shown}:{}", n + 1);
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                nv += 1;
                let c: Vec<&str> = w.collect();
                if c.len() < 3 || c.iter().take(3).any(|s| s.parse::<f32>().is_err()) {
                    return format!(
                        "{at}: vertex line '{}' needs three numbers x y z; fix or remove it",
                        line.trim()
                    );
                }
            }
            Some("f") => {
                for tok in w {
                    let v = tok.split('/').next().unwrap_or("");
                    let Ok(i) = v.parse::<i64>() else {
                        return format!(
                            "{at}: face entry '{tok}' is not a vertex index; write f i j k with 1-based indices"
                        );
                    };
                    let ok = match i {
                        0 => false,
                        i if i > 0 => i as usize <= total_v,
                        i => i.unsigned_abs() as usize <= nv,
                    };
                    if !ok {
                        return format!(
                            "{at}: face index {i} is out of range: the file has {total_v} vertices ({nv} so far; \
                             indices are 1-based, negative ones count back from the last vertex); fix the face or add the vertex"
                        );
                    }
                }
            }
            _ => {}
        }
    }
    format!("{shown}: cannot load OBJ ({e}); check the file's syntax")
}
