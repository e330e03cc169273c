//! Where scene files and meshes are looked for: beside the scene file (a
//! mesh's `path` is relative to it), then in the scenes search path — the
//! directories given with `--scenes-dir` (in order), then those in
//! `$DUALSTREAM_SCENES` (separated as `PATH` is). A mesh is found there by its
//! file name, so a scene file written for another layout (`../../shared/
//! scenes/x.obj`) finds `x.obj` in any directory of the path.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The environment variable of the search path.
pub const ENV: &str = "DUALSTREAM_SCENES";

static DIRS: OnceLock<Vec<PathBuf>> = OnceLock::new();

/// Sets the command line's directories (once, before any scene is loaded).
pub fn set_dirs(dirs: Vec<PathBuf>) {
    let _ = DIRS.set(dirs);
}

/// The search path: the command line's directories, then the environment's.
pub fn dirs() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = DIRS.get().cloned().unwrap_or_default();
    if let Some(e) = std::env::var_os(ENV) {
        v.extend(std::env::split_paths(&e).filter(|p| !p.as_os_str().is_empty()));
    }
    v
}

/// `rel` as given (relative to `base`), else its file name in each directory
/// of the search path; `Err` lists every place tried.
pub fn find(base: &Path, rel: &Path) -> Result<PathBuf, Vec<PathBuf>> {
    let first = base.join(rel);
    if first.is_file() {
        return Ok(first);
    }
    let mut tried = vec![first];
    if let Some(name) = rel.file_name() {
        for d in dirs() {
            for p in [d.join(rel), d.join(name)] {
                if p.is_file() {
                    return Ok(p);
                }
                if !tried.contains(&p) {
                    tried.push(p);
                }
            }
        }
    }
    Err(tried)
}

/// The places tried, for an error message, and how to add one.
pub fn tried_text(tried: &[PathBuf]) -> String {
    let list: Vec<String> = tried.iter().map(|p| format!("'{}'", p.display())).collect();
    format!(
        "looked in {}; put the file there, or give its directory with --scenes-dir DIR or ${ENV} (README, \"Scenes and meshes\", says where each mesh is published)",
        list.join(", ")
    )
}
