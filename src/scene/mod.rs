//! Scenes: triangles in world space, Lambertian materials, a pinhole camera and
//! one point light, from a builtin procedural scene, a scene description
//! (.toml) or a bare Wavefront .obj.
//!
//! Everything here is deterministic (no libm trigonometry, fixed iteration
//! order), so the same spec gives bit-identical triangles on every machine.
//! Bad input is reported as an error string that names the problem and the fix;
//! loading never panics.

mod builtin;
mod camera;
mod desc;
mod error;
mod obj;
pub mod search;

use glam::Vec3;

use crate::geom::shapes::sin_cos;
use crate::geom::{Aabb, MAX_COORD, MAX_VIEW_COORD, Triangle, beyond};

pub use camera::Camera;
pub use error::SceneError;

/// Lambertian (diffuse) material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub albedo: Vec3,
}

/// Albedo used when a mesh has no material (no .mtl, or no `Kd`).
pub const DEFAULT_ALBEDO: f32 = 0.7;

/// Radiance of a miss when a scene does not say (dim grey, so open scenes such
/// as a bare OBJ are not lit by the point light alone).
pub const DEFAULT_SKY: f32 = 0.1;

/// Isotropic point light; `intensity` is radiant intensity (W/sr per channel),
/// so a surface at distance D facing the light receives irradiance I / D^2 and
/// a Lambertian surface reflects radiance albedo / pi * I / D^2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    pub position: Vec3,
    pub intensity: Vec3,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Hit points per path (the paper renders 5), 1..=MAX_BOUNCES.
    pub bounces: u32,
    pub seed: u64,
    /// Paths per pixel (1..=MAX_SPP): each traced as rays of its own, the
    /// pixel their average in linear radiance.
    pub spp: u32,
}

pub const MAX_BOUNCES: u32 = 16;
pub const MAX_SPP: u32 = 4096;
/// Paths a frame may hold: ray ids are path ids below the shadow bit (bit 31).
pub const MAX_PATHS: u64 = 1 << 31;
pub const MAX_IMAGE_SIZE: u32 = 16384;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 256,
            height: 256,
            bounces: 5,
            seed: 1,
            spp: 1,
        }
    }
}

impl RenderSettings {
    pub fn validate(&self) -> Result<(), SceneError> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_IMAGE_SIZE).contains(&v) {
                return Err(SceneError::Invalid(format!(
                    "render {name} = {v} is outside 1..={MAX_IMAGE_SIZE}; choose a size in that range"
                )));
            }
        }
        if !(1..=MAX_BOUNCES).contains(&self.bounces) {
            return Err(SceneError::Invalid(format!(
                "render bounces = {} is outside 1..={MAX_BOUNCES} (hit points per path); \
                 use e.g. 5 as in the paper",
                self.bounces
            )));
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(SceneError::Invalid(format!(
                "spp = {} is outside 1..={MAX_SPP} (paths per pixel); use e.g. 1 or 16",
                self.spp
            )));
        }
        let paths = self.width as u64 * self.height as u64 * self.spp as u64;
        if paths > MAX_PATHS {
            return Err(SceneError::Invalid(format!(
                "{}x{} at spp {} is {paths} paths, more than a frame's {MAX_PATHS} (ray ids); lower --spp or the resolution",
                self.width, self.height, self.spp
            )));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub name: String,
    /// World space; degenerate triangles already dropped.
    pub triangles: Vec<Triangle>,
    /// Index into `materials`, one per triangle.
    pub tri_material: Vec<u32>,
    pub materials: Vec<Material>,
    pub camera: Camera,
    pub light: PointLight,
    /// Radiance of a miss.
    pub sky: Vec3,
    pub settings: RenderSettings,
    /// Things the loader changed or assumed, e.g. "dropped 12 degenerate triangles".
    pub warnings: Vec<String>,
}

fn finite(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

fn non_negative(v: Vec3) -> bool {
    finite(v) && v.x >= 0.0 && v.y >= 0.0 && v.z >= 0.0
}

impl Scene {
    /// Bounds of all triangles (empty for no triangles).
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.triangles.iter().flat_map(|t| [t.v0, t.v1, t.v2]))
    }

    /// Checks the invariants consumers rely on.
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.triangles.is_empty() {
            return Err(SceneError::Empty(
                "scene has no triangles; add a mesh".to_string(),
            ));
        }
        if self.triangles.len() > u32::MAX as usize {
            return Err(SceneError::Invalid(
                "scene has more than 2^32 triangles; use a smaller mesh".to_string(),
            ));
        }
        if self.tri_material.len() != self.triangles.len() {
            return Err(SceneError::Invalid(format!(
                "scene has {} triangles but {} material indices; give one per triangle",
                self.triangles.len(),
                self.tri_material.len()
            )));
        }
        if let Some((i, v)) = first_beyond(&self.triangles) {
            return Err(SceneError::BadVertex(format!(
                "triangle {i} has a vertex {}",
                too_far(v)
            )));
        }
        if let Some(i) = self.triangles.iter().position(|t| t.is_degenerate()) {
            return Err(SceneError::Invalid(format!(
                "triangle {i} is degenerate or not finite; drop it before building the scene"
            )));
        }
        if let Some(i) = self
            .tri_material
            .iter()
            .position(|&m| m as usize >= self.materials.len())
        {
            return Err(SceneError::Invalid(format!(
                "triangle {i} uses material {} but there are {} materials",
                self.tri_material[i],
                self.materials.len()
            )));
        }
        for (i, m) in self.materials.iter().enumerate() {
            let a = m.albedo;
            if !(non_negative(a) && a.x <= 1.0 && a.y <= 1.0 && a.z <= 1.0) {
                return Err(SceneError::Invalid(format!(
                    "material {i} albedo {a:?} is outside [0, 1]; an albedo above 1 creates energy"
                )));
            }
        }
        self.camera.validate()?;
        if !finite(self.light.position) || !non_negative(self.light.intensity) {
            return Err(SceneError::Invalid(format!(
                "light {:?} needs a finite position and a finite, non-negative intensity",
                self.light
            )));
        }
        light_in_range(self.light.position)?;
        if !non_negative(self.sky) {
            return Err(SceneError::Invalid(format!(
                "sky {:?} must be finite and non-negative",
                self.sky
            )));
        }
        self.settings.validate()
    }
}

/// Builtin procedural scenes (no files needed).
pub const BUILTINS: &[&str] = builtin::NAMES;
pub const DEFAULT_SCENE: &str = "cornell";

/// `spec` is a builtin name, a path to a scene description (.toml) or a path to
/// a Wavefront .obj.
pub fn load(spec: &str) -> Result<Scene, SceneError> {
    if let Some(s) = builtin::build(spec) {
        return Ok(s);
    }
    let given = std::path::Path::new(spec);
    let ext = given
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    // A scene file not where it is named is looked for in the search path;
    // missing everywhere, the loader's own error names the path as given.
    let found = match ext.as_deref() {
        Some("toml" | "obj") => search::find(std::path::Path::new(""), given).ok(),
        _ => None,
    };
    let path = found.as_deref().unwrap_or(given);
    let scene = match ext.as_deref() {
        Some("toml") => desc::load(path)?,
        Some("obj") => obj::load_bare(path)?,
        _ => {
            return Err(SceneError::Unknown {
                spec: spec.to_string(),
            });
        }
    };
    scene.validate().map_err(|e| e.at(spec))?;
    Ok(scene)
}

/// Scale, then rotate about +y, then translate; computed in f64 and rounded
/// once, a function of the vertex value only, so bit-identical shared vertices
/// stay bit-identical (closed meshes stay closed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Xform {
    pub scale: f32,
    pub rotate_y_deg: f32,
    pub translate: Vec3,
}

impl Xform {
    pub const IDENTITY: Xform = Xform {
        scale: 1.0,
        rotate_y_deg: 0.0,
        translate: Vec3::ZERO,
    };

    /// Where `p` goes.
    pub fn point(&self, p: Vec3) -> Vec3 {
        if *self == Xform::IDENTITY {
            return p;
        }
        self.map(self.sin_cos(), p)
    }

    pub fn apply(&self, tris: &mut [Triangle]) {
        if *self == Xform::IDENTITY {
            return;
        }
        let sc = self.sin_cos();
        for tri in tris {
            *tri = Triangle::new(
                self.map(sc, tri.v0),
                self.map(sc, tri.v1),
                self.map(sc, tri.v2),
            );
        }
    }

    /// Sine and cosine of the rotation.
    fn sin_cos(&self) -> (f64, f64) {
        // Reduce first: sin_cos is accurate only for small arguments.
        let deg = (self.rotate_y_deg as f64).rem_euclid(360.0);
        sin_cos(deg * (std::f64::consts::PI / 180.0))
    }

    fn map(&self, (s, c): (f64, f64), p: Vec3) -> Vec3 {
        let k = self.scale as f64;
        let t = self.translate;
        let (x, y, z) = (p.x as f64 * k, p.y as f64 * k, p.z as f64 * k);
        // Right-handed rotation about +y: x' = c x + s z, z' = -s x + c z.
        Vec3::new(
            (c * x + s * z + t.x as f64) as f32,
            (y + t.y as f64) as f32,
            (c * z - s * x + t.z as f64) as f32,
        )
    }
}

/// Accumulates meshes into a scene.
#[derive(Default)]
pub(crate) struct Builder {
    pub triangles: Vec<Triangle>,
    pub tri_material: Vec<u32>,
    pub materials: Vec<Material>,
    pub warnings: Vec<String>,
}

impl Builder {
    pub fn material(&mut self, albedo: Vec3) -> u32 {
        if let Some(i) = self.materials.iter().position(|m| m.albedo == albedo) {
            return i as u32;
        }
        self.materials.push(Material { albedo });
        (self.materials.len() - 1) as u32
    }

    /// Adds triangles with one material each, dropping degenerate ones (with a
    /// warning naming `source`). Meshes from files are checked against the
    /// datapath's range first ([`first_beyond`]): out there, areas overflow and
    /// every triangle would look degenerate.
    pub fn add(&mut self, source: &str, tris: impl IntoIterator<Item = (Triangle, u32)>) {
        let mut dropped = 0usize;
        for (t, m) in tris {
            if t.is_degenerate() {
                dropped += 1;
            } else {
                self.triangles.push(t);
                self.tri_material.push(m);
            }
        }
        if dropped > 0 {
            self.warnings.push(format!(
                "{source}: dropped {dropped} degenerate triangles (zero area)"
            ));
        }
    }

    pub fn add_mesh(&mut self, source: &str, tris: Vec<Triangle>, albedo: Vec3) {
        let m = self.material(albedo);
        self.add(source, tris.into_iter().map(|t| (t, m)));
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.triangles.iter().flat_map(|t| [t.v0, t.v1, t.v2]))
    }

    /// Camera and light framing the bounds, with a warning giving them as TOML
    /// so the user can copy them into a scene file. An error if the framing
    /// leaves the datapath's range (only a mesh near [`MAX_COORD`] seen through
    /// a tall, narrow image can do that).
    pub fn auto_view(
        &mut self,
        aspect: f32,
        need_camera: bool,
        need_light: bool,
    ) -> Result<(Camera, PointLight), SceneError> {
        let b = self.bounds();
        let cam = Camera::frame(&b, 45.0, aspect);
        if need_camera && beyond(cam.eye, MAX_VIEW_COORD) {
            return Err(SceneError::Invalid(format!(
                "framing the meshes automatically puts the camera eye at {}, beyond \
                 ±{MAX_VIEW_COORD:e}, the f32 datapath's limit for the camera and light; give a \
                 [camera] or scale the meshes down",
                arr(cam.eye)
            )));
        }
        let r = (b.extent().length() * 0.5).max(1e-6);
        let c = b.centroid();
        // Above and in front of the object, so the faces the camera sees are lit.
        let pos = Vec3::new(c.x, c.y + 2.0 * r, c.z + r);
        // Direct radiance ~ albedo/pi * I / D^2 with D^2 = 5 r^2 to the centre:
        // I = 8 r^2 gives ~0.35 for albedo 0.7 (reasonably exposed).
        let i = 8.0 * r * r;
        let light = PointLight {
            position: pos,
            intensity: Vec3::splat(i),
        };
        if need_light && beyond(light.position, MAX_VIEW_COORD) {
            return Err(SceneError::Invalid(format!(
                "framing the meshes automatically puts the light at {}, beyond \
                 ±{MAX_VIEW_COORD:e}, the f32 datapath's limit for the camera and light; give a \
                 [light] or scale the meshes down",
                arr(light.position)
            )));
        }
        let mut toml = String::new();
        if need_camera {
            toml += &format!(
                "[camera]\neye = {}\nlook_at = {}\nup = {}\nvfov = {:?}\n",
                arr(cam.eye),
                arr(cam.look_at),
                arr(cam.up),
                cam.vfov_deg
            );
        }
        if need_light {
            toml += &format!(
                "[light]\nposition = {}\nintensity = {}\n",
                arr(light.position),
                arr(light.intensity)
            );
        }
        if !toml.is_empty() {
            self.warnings.push(format!(
                "no camera/light given: framed the bounds automatically; to keep or \
                 edit them, put this in a scene file:\n{toml}"
            ));
        }
        Ok((cam, light))
    }
}

/// The first triangle (index) with a vertex beyond [`MAX_COORD`], and that vertex.
pub(crate) fn first_beyond(tris: &[Triangle]) -> Option<(usize, Vec3)> {
    tris.iter().enumerate().find_map(|(i, t)| {
        [t.v0, t.v1, t.v2]
            .into_iter()
            .find(|&v| beyond(v, MAX_COORD))
            .map(|v| (i, v))
    })
}

/// Where a vertex beyond [`MAX_COORD`] is, what is wrong and the fix: follows
/// "vertex k lies" or "triangle k has a vertex".
pub(crate) fn too_far(v: Vec3) -> String {
    format!(
        "at {}, beyond ±{MAX_COORD:e}, the coordinate limit of the f32 datapath (its \
         intersection test multiplies coordinate differences up to five deep; larger ones \
         overflow); scale or recentre the mesh (`scale`, `translate` in a scene file)",
        arr(v)
    )
}

/// A light position within [`MAX_VIEW_COORD`].
pub(crate) fn light_in_range(p: Vec3) -> Result<(), SceneError> {
    if beyond(p, MAX_VIEW_COORD) {
        return Err(SceneError::Invalid(format!(
            "light position {} is beyond ±{MAX_VIEW_COORD:e}, the f32 datapath's limit for the \
             camera and light (shadow rays run from the surfaces to the light unnormalised); \
             move the light closer, or scale and recentre the scene",
            arr(p)
        )));
    }
    Ok(())
}

/// `[x, y, z]` with round-trip float formatting, for TOML snippets.
fn arr(v: Vec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

/// 1-based line of byte offset `pos` in `src`.
pub(crate) fn line_of(src: &str, pos: usize) -> usize {
    src.as_bytes()[..pos.min(src.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

#[cfg(test)]
mod tests;
