//! Early ray termination in functional mode: every choice verifies against the
//! reference, gives the image of `none` to the bit and deterministic
//! statistics; what it says it saved is exactly what `none` does more; the
//! modes without it refuse it.

use dualstream::config::{Config, EarlyTermination};
use dualstream::render::{Frame, Mode, RenderCfg, WaveStats, render};
use dualstream::rtl::SimOptions;
use dualstream::scene::{self, Scene};

fn small(name: &str, res: u32) -> Scene {
    let mut s = scene::load(name).unwrap();
    s.settings.width = res;
    s.settings.height = res;
    s
}

fn cfg(et: EarlyTermination) -> RenderCfg {
    let mut c = Config::default();
    c.chip.early_termination = et;
    RenderCfg {
        verify: true,
        ..RenderCfg::for_chip(&c, SimOptions::default())
    }
}

fn bits(f: &Frame) -> Vec<u32> {
    f.radiance
        .iter()
        .flat_map(|c| [c.x.to_bits(), c.y.to_bits(), c.z.to_bits()])
        .collect()
}

/// A wavefront's counts as `none` would have them, from this run's counts
/// and what its early termination says it saved and added.
fn without(w: &WaveStats) -> [u64; 8] {
    let (t, e) = (&w.traversal, &w.early);
    [
        w.enqueues + e.ghost_enqueues,
        w.ray_lines() + e.ray_lines_removed,
        w.scene_lines + e.scene_lines_removed,
        w.hit_lines() + e.hit_lines_removed - e.records_read - e.hit_lines_added,
        t.box_tests - e.pre_box_tests + e.box_tests_avoided,
        t.tri_tests + e.tri_tests_avoided,
        w.segments_loaded + e.segments_removed,
        w.rays,
    ]
}

#[test]
fn every_choice_is_exact_and_accounts_for_its_savings() {
    for (name, res) in [("cornell", 32), ("hairball", 32)] {
        let s = small(name, res);
        let none = render(
            &s,
            Mode::Functional,
            &cfg(EarlyTermination::None),
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(none.total.early, Default::default());
        for et in EarlyTermination::ALL {
            let f = render(&s, Mode::Functional, &cfg(et), &mut |_| {}).unwrap();
            // --verify passed on every wavefront; the image is `none`'s.
            assert!(f.verified_rays >= (res * res) as u64, "{name} {et}");
            assert_eq!(bits(&f), bits(&none), "{name} {et}: image");
            assert_eq!(f.early_termination, et);
            assert_eq!(f.waves.len(), none.waves.len(), "{name} {et}");
            for (k, (a, b)) in f.waves.iter().zip(&none.waves).enumerate() {
                assert_eq!(without(a), without(b), "{name} {et}: wavefront {k}");
                assert_eq!((a.hits, a.occluded), (b.hits, b.occluded));
            }
            // Deterministic: the same statistics again, to the count.
            let g = render(&s, Mode::Functional, &cfg(et), &mut |_| {}).unwrap();
            assert_eq!(g.waves, f.waves, "{name} {et}: statistics");
            let e = &f.total.early;
            if et.pre() {
                // One read and one box test per ray copy at a segment.
                assert!(e.records_read >= e.pre_box_tests, "{name} {et}");
                assert_eq!(e.pre_box_tests, f.total.enqueues, "{name} {et}");
            } else {
                assert_eq!((e.rays_dropped, e.pre_box_tests), (0, 0), "{name} {et}");
            }
            if !et.post() {
                assert_eq!(e.enqueues_avoided, 0, "{name} {et}");
            }
            if name == "hairball" && et.pre() {
                // High depth complexity: most copies behind a hit are dropped.
                assert!(e.rays_dropped * 5 > f.total.enqueues, "{et}: {e:?}");
                assert!(
                    e.tri_tests_avoided * 3 > none.total.traversal.tri_tests,
                    "{et}: {e:?}"
                );
                assert!(f.total.traversal.box_tests < none.total.traversal.box_tests);
            }
            if name == "hairball" && et.post() {
                assert!(e.enqueues_avoided > 0, "{et}: {e:?}");
            }
        }
    }
}

#[test]
fn modes_without_early_termination_refuse_it() {
    let s = small("tiny", 8);
    for mode in [Mode::Cycle, Mode::Reference] {
        let e = render(&s, mode, &cfg(EarlyTermination::Pre), &mut |_| {}).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("early termination `pre` is in functional mode only so far")
                && m.contains("early_termination = \"none\""),
            "{mode:?}: {m}"
        );
    }
    let plan = dualstream::sampling::default_windows();
    let e =
        dualstream::sampling::render_windows(&s, &cfg(EarlyTermination::Both), &plan).unwrap_err();
    assert!(
        e.to_string().contains("`both` is in functional mode only"),
        "{e}"
    );
}
