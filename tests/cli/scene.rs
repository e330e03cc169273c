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
