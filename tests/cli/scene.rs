//! `dualstream scene info`: the structure the chip would get.

use crate::run;

#[test]
fn scene_info_prints_the_structure() {
    let o = run(&["scene", "info", "cornell"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for k in [
        "triangles",
        "BVH nodes",
        "segments",
        "children per segment",
        "BVH build",
    ] {
        assert!(out.contains(k), "{out}");
    }
}

/// The scenes search path: a mesh missing beside its scene file is found by
/// its file name in a `--scenes-dir` directory or one of
/// `$DUALSTREAM_SCENES`, and so is a scene file; missing everywhere, the
/// error lists every place tried and how to add one.
#[test]
fn scenes_search_path_finds_meshes_and_scene_files() {
    use std::process::Command;
    let t = crate::common::Scratch::new("cli-scene-search");
    let (scenes, meshes) = (t.join("scenes"), t.join("meshes"));
    std::fs::create_dir_all(&scenes).unwrap();
    std::fs::create_dir_all(&meshes).unwrap();
    // A scene written for another layout: its mesh is not where it says.
    std::fs::write(
        scenes.join("tri.toml"),
        "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 45.0\n\n[[mesh]]\npath = \"../../elsewhere/tri.obj\"\n",
    )
    .unwrap();
    std::fs::write(
        meshes.join("tri.obj"),
        "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let info = |args: &[&str], env: Option<&std::path::Path>| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_dualstream"));
        c.current_dir(&*t)
            .env_remove("DUALSTREAM_SCENES")
            .args(args);
        if let Some(e) = env {
            c.env("DUALSTREAM_SCENES", e);
        }
        c.output().unwrap()
    };
    let o = info(&["scene", "info", "scenes/tri.toml"], None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    for n in ["tri.obj", "looked in", "--scenes-dir", "DUALSTREAM_SCENES"] {
        assert!(err.contains(n), "{n}: {err}");
    }
    let m = meshes.to_str().unwrap();
    let o = info(
        &["--scenes-dir", m, "scene", "info", "scenes/tri.toml"],
        None,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("1 triangles")
            || String::from_utf8_lossy(&o.stdout).contains("triangles")
    );
    let o = info(&["scene", "info", "scenes/tri.toml"], Some(&meshes));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The scene file by name, from the search path.
    let s = scenes.to_str().unwrap();
    let o = info(
        &[
            "--scenes-dir",
            s,
            "--scenes-dir",
            m,
            "scene",
            "info",
            "tri.toml",
        ],
        None,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Output into a pipe closed early (`| head -1`) ends the program quietly, as
/// SIGPIPE would, instead of a panic.
#[test]
fn a_closed_stdout_is_no_panic() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let mut c = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(["config", "--print-default"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Close the read end at once: the first write fails.
    drop(c.stdout.take());
    let mut err = String::new();
    c.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    let status = c.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        status.code() == Some(141) || status.success(),
        "{status:?}: {err}"
    );
}
