//! The committed scene files that use the meshes in `shared/scenes/` (beside
//! the repository). Ignored by default: they need shared/ and the big meshes
//! take seconds to parse. Run with `cargo test --release --test scene -- --ignored`.

use dualstream::scene::{self, Scene};

fn scene_file(name: &str) -> String {
    format!("{}/scenes/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str) -> Scene {
    let s = scene::load(&scene_file(name)).unwrap_or_else(|e| panic!("{e}"));
    s.validate().unwrap();
    // Shown with --nocapture: what a user of the file would see.
    println!(
        "{name}: {} triangles, {} materials, warnings {:?}",
        s.triangles.len(),
        s.materials.len(),
        s.warnings
    );
    s
}

#[test]
fn builtin_only_scene_file_loads_without_shared() {
    let s = load("builtin_room.toml");
    assert_eq!(s.name, "Builtin room");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
#[ignore = "needs shared/scenes beside the repository"]
fn cornell_box_obj() {
    let s = load("cornell_box.toml");
    assert_eq!(s.triangles.len(), 36);
    // leftWall, rightWall, floor/ceiling/back/boxes (same Kd), light.
    assert!(s.materials.len() >= 3, "{:?}", s.materials);
    assert!(
        s.warnings.iter().any(|w| w.contains("Ke")),
        "{:?}",
        s.warnings
    );
    let b = s.bounds();
    assert!(b.contains(s.light.position) && !b.contains(s.camera.eye));
}

#[test]
#[ignore = "needs shared/scenes beside the repository; parses 871K triangles"]
fn dragon_and_dragon_box() {
    let d = load("dragon.toml");
    let db = load("dragon_box.toml");
    // Some of the scan's triangles may be degenerate; none may be lost otherwise.
    assert!(
        (860_000..=871_414).contains(&d.triangles.len()),
        "{}",
        d.triangles.len()
    );
    assert_eq!(db.triangles.len(), d.triangles.len() + 12);
    // The box encloses the dragon, the eye and the light.
    let b = db.bounds();
    assert!(b.contains(db.camera.eye) && b.contains(db.light.position));
    let dragon = d.bounds();
    assert!(dragon.min.cmpgt(b.min).all() && dragon.max.cmplt(b.max).all());
}

#[test]
#[ignore = "needs shared/scenes beside the repository"]
fn dabrovic_sponza() {
    let s = load("dabrovic_sponza.toml");
    assert!(
        (60_000..=66_454).contains(&s.triangles.len()),
        "{}",
        s.triangles.len()
    );
    assert!(s.bounds().contains(s.camera.eye));
}

#[test]
#[ignore = "needs shared/scenes beside the repository; parses ~2M triangles"]
fn every_shared_obj_loads_bare() {
    let dir = format!("{}/../shared/scenes", env!("CARGO_MANIFEST_DIR"));
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "obj"))
        .collect();
    names.sort();
    assert!(names.len() >= 10, "{names:?}");
    for p in names {
        let s = scene::load(p.to_str().unwrap()).unwrap_or_else(|e| panic!("{e}"));
        s.validate().unwrap();
        println!("{}: {} triangles", s.name, s.triangles.len());
        assert!(s.warnings.iter().any(|w| w.contains("[camera]")));
    }
}
