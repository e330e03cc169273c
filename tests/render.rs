//! End to end: dual-streaming traversal (functional) agrees with the reference on
//! every ray, ties included; images are deterministic; bad input is named.

use dualstream::accel::AccelCfg;
use dualstream::contract::MemoryMapCfg;
use dualstream::geom::Triangle;
use dualstream::geom::shapes::uv_sphere;
use dualstream::render::traverse::reference_trace;
use dualstream::render::{Mode, RenderCfg, render, trace_rays};
use dualstream::scene::{self, Scene};
use dualstream::util::rng::Rng;
use glam::Vec3;

fn small(name: &str, res: u32) -> Scene {
    let mut s = scene::load(name).unwrap();
    s.settings.width = res;
    s.settings.height = res;
    s
}

/// Small segments so even small scenes have many segments and duplication.
fn cfg(segment_kb: u32) -> RenderCfg {
    RenderCfg {
        accel: AccelCfg {
            segment_bytes: segment_kb << 10,
            ..AccelCfg::default()
        },
        verify: true,
        ..RenderCfg::default()
    }
}

#[test]
fn functional_agrees_with_reference_on_every_ray_and_pixel() {
    for (name, res, kb) in [("tiny", 32, 8), ("cornell", 48, 8), ("cornell", 32, 64)] {
        let s = small(name, res);
        let f = render(&s, Mode::Functional, &cfg(kb), &mut |_| {}).unwrap();
        assert!(
            f.verified_rays > (res * res) as u64,
            "every wavefront verified"
        );
        assert!(
            f.waves.len() >= 5,
            "paths of 5 hit points make 6 wavefronts"
        );
        let r = render(
            &s,
            Mode::Reference,
            &RenderCfg {
                verify: false,
                ..cfg(kb)
            },
            &mut |_| {},
        )
        .unwrap();
        // Same hits, same shading: the images are identical to the bit.
        let bits = |f: &dualstream::render::Frame| {
            f.radiance
                .iter()
                .flat_map(|c| [c.x, c.y, c.z])
                .map(f32::to_bits)
                .collect::<Vec<_>>()
        };
        assert_eq!(
            bits(&f),
            bits(&r),
            "{name}: functional and reference images differ"
        );
        assert_eq!(f.total.rays, r.total.rays);
        // Accounting: every ray is enqueued once into the root and once per exit.
        assert_eq!(f.total.enqueues, f.total.rays + f.total.traversal.exits);
        if f.accel.segments > 1 {
            assert!(
                f.duplication > 1.0,
                "{name}: segments cut rays, so they duplicate"
            );
        }
        assert!(
            f.total.scene_lines > 0
                && f.total.ray_lines() > 0
                && f.total.hit_lines() > 0
                && f.total.shading_lines > 0
        );
        // Light arrives: the image is not black.
        let mean: f32 =
            f.radiance.iter().map(|c| c.x + c.y + c.z).sum::<f32>() / f.radiance.len() as f32;
        assert!(mean > 0.05, "{name}: mean radiance {mean}");
    }
}

#[test]
fn same_seed_same_image_and_statistics() {
    let s = small("cornell", 24);
    let a = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    let b = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    assert_eq!(a.radiance, b.radiance);
    assert_eq!(a.waves, b.waves);
    let mut s2 = s.clone();
    s2.settings.seed = 99;
    let c = render(&s2, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    assert_ne!(a.radiance, c.radiance);
}

/// A closed sphere far from the origin, finely tessellated so that segments are
/// many, with rays aimed exactly at vertices and edge midpoints: both traversals
/// must pick the same (t, id), ties on shared edges included.
#[test]
fn ties_on_shared_edges_and_vertices_resolve_identically() {
    let c = Vec3::new(148376.0, 1234.0, -223423.0);
    let tris = uv_sphere(c, 5.0, 24, 48);
    let mut sc = scene::load("tiny").unwrap();
    sc.tri_material = vec![0; tris.len()];
    sc.triangles = tris.clone();
    let mut rng = Rng::new(3);
    let mut rays = Vec::new();
    for (k, t) in tris.iter().enumerate().step_by(7) {
        let targets = [t.v0, (t.v0 + t.v1) * 0.5, (t.v1 + t.v2) * 0.5, t.v2];
        let target = targets[k % 4];
        // From outside and from the centre.
        let o = if k % 2 == 0 {
            c + Vec3::new(rng.range_f32(-20.0, 20.0), rng.range_f32(-20.0, 20.0), 30.0)
        } else {
            c
        };
        rays.push((o, (target - o).normalize(), false));
    }
    for kb in [8, 64] {
        let rc = cfg(kb);
        let (got, st) = trace_rays(&sc, &rc, Mode::Functional, &rays).unwrap();
        assert!(st.traversal.exits > 0 || kb == 64);
        let prep = dualstream::render::prepare(&sc, &rc).unwrap();
        let mut hits = 0;
        for (i, &(o, d, sh)) in rays.iter().enumerate() {
            let want = reference_trace(&prep.bvh, &sc.triangles, o, d, sh);
            assert_eq!(
                (got[i].t.to_bits(), got[i].tri_id),
                (want.t.to_bits(), want.tri_id),
                "ray {i}"
            );
            hits += want.is_hit() as u32;
        }
        assert_eq!(hits as usize, rays.len(), "a closed sphere: every ray hits");
    }
}

#[test]
fn bad_input_is_named() {
    let mut s = small("tiny", 8);
    s.settings.width = 0;
    assert!(
        render(&s, Mode::Functional, &cfg(8), &mut |_| {})
            .unwrap_err()
            .to_string()
            .contains("width")
    );
    let mut s = small("tiny", 8);
    s.settings.bounces = 17;
    assert!(
        render(&s, Mode::Functional, &cfg(8), &mut |_| {})
            .unwrap_err()
            .to_string()
            .contains("bounces")
    );
    let s = small("tiny", 8);
    let e = render(&s, Mode::Functional, &cfg(3), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("multiple of the DRAM row"), "{e}");
    // A pool of one row runs dry: a clear error, not a hang or a crash.
    let rc = RenderCfg {
        memory: MemoryMapCfg {
            bucket_pool_bytes: 8192,
            ..MemoryMapCfg::default()
        },
        ..cfg(8)
    };
    let s = small("cornell", 32);
    let e = render(&s, Mode::Functional, &rc, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("ran dry") && e.contains("bucket_pool_bytes"),
        "{e}"
    );
    // A DRAM too small for the scene.
    let rc = RenderCfg {
        memory: MemoryMapCfg {
            capacity_bytes: 64 << 20,
            ..MemoryMapCfg::default()
        },
        ..cfg(8)
    };
    let e = render(&s, Mode::Functional, &rc, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("more than the configured DRAM"), "{e}");
    let _ = Triangle::new(Vec3::ZERO, Vec3::X, Vec3::Y);
}

#[test]
fn paper_comparison_rows() {
    use dualstream::report::paper::{TABLE2, compare, table};
    let s = small("tiny", 16);
    let f = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    let rows = compare(&TABLE2[1], &f);
    // Timing, rate, rays, DRAM energy (paper and physical presets), on-chip and compute
    // energy, bandwidth, five line counts, duplication.
    assert_eq!(rows.len(), 14);
    for metric in [
        "DRAM energy (J)",
        "DRAM energy, physical preset (J)",
        "average bandwidth (GB/s)",
    ] {
        let r = rows.iter().find(|r| r.metric == metric).unwrap();
        assert!(
            r.ours.is_none() && r.note.contains("cycle"),
            "{metric} needs the chip: no invented figures"
        );
    }
    let dup = rows.iter().find(|r| r.metric == "ray duplication").unwrap();
    assert_eq!(dup.paper, TABLE2[1].duplication);
    assert!((dup.ratio.unwrap() - f.duplication / TABLE2[1].duplication).abs() < 1e-12);
    // At 16x16, not the paper's 1024x1024: a rate or ratio keeps its ratio, a
    // frame's total (it scales with the pixels) has none, and the table says so.
    assert!(dup.scale_free && !dup.at_paper_resolution);
    let lines = rows.iter().find(|r| r.key == "lines_millions").unwrap();
    assert!(!lines.scale_free && lines.ours.is_some() && lines.ratio.is_none());
    let text = table(&rows);
    let line = text
        .lines()
        .find(|l| l.contains("$ lines transferred"))
        .unwrap();
    assert!(
        line.contains("scales with resolution; paper at 1024x1024"),
        "{line}"
    );
    // At the paper's resolution every figure has its ratio.
    let mut big = f.clone();
    (big.width, big.height) = (1024, 1024);
    let at = compare(&TABLE2[1], &big);
    let lines = at.iter().find(|r| r.key == "lines_millions").unwrap();
    assert!(lines.at_paper_resolution && lines.ratio.is_some());
    assert!(!table(&at).contains("scales with resolution"));
    let time = rows
        .iter()
        .find(|r| r.metric == "render time (ms)")
        .unwrap();
    assert!(
        time.ours.is_none() && time.note.contains("cycle"),
        "no invented figures"
    );
    assert!(table(&rows).contains("Dragon Box"));
    let figs = dualstream::report::paper::figures(&rows);
    assert_eq!(figs.len(), 2);
    assert!(figs[0].1.contains("Figure 7") && figs[1].1.contains("Figure 8"));
    // Dragon Box ours and paper: 2 groups of 4 stream bars, plus 4 legend boxes.
    assert_eq!(figs[1].1.matches("<rect x=").count(), 2 * 4 + 4);
}

#[test]
fn cycle_rows_add_the_time_and_dram_energy_figures() {
    use dualstream::report::paper::{TABLE2, compare, figures};
    use dualstream::units::memory::MemoryModel;
    let s = small("tiny", 8);
    let mut c = dualstream::config::Config::default();
    c.chip.tms = 2;
    c.tm.tps = 4;
    c.chip.memory.model = MemoryModel::Gddr5;
    let rc = RenderCfg {
        chip: Some(Box::new(dualstream::render::ChipRun {
            config: c,
            ..Default::default()
        })),
        ..cfg(8)
    };
    let f = render(&s, Mode::Cycle, &rc, &mut |_| {}).unwrap();
    // Leakage: off by default; on, a separate figure over the render time that
    // leaves the totals alone.
    let mut c = rc.chip.as_ref().unwrap().config.clone();
    let off = dualstream::render::energy::frame_energy(&c, &f);
    assert_eq!(off.leakage_j, None);
    c.energy.leakage = true;
    let on = dualstream::render::energy::frame_energy(&c, &f);
    let secs = f.chip.as_ref().unwrap().total_cycles as f64 * 1e-9;
    let want = dualstream::render::energy::leakage_w(&c) * secs;
    assert!((on.leakage_j.unwrap() - want).abs() <= 1e-12 * want.max(1.0));
    assert_eq!((on.compute_j, on.onchip_j), (off.compute_j, off.onchip_j));
    let rows = compare(&TABLE2[1], &f);
    let time = rows
        .iter()
        .find(|r| r.metric == "render time (ms)")
        .unwrap();
    let cycles = f.chip.as_ref().unwrap().total_cycles as f64;
    assert!(
        (time.ours.unwrap() - cycles * 1e-6).abs() < 1e-12,
        "1 GHz core"
    );
    let figs = figures(&rows);
    let names: Vec<&str> = figs.iter().map(|f| f.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "fig4_render_time.svg",
            "fig5_dram_energy.svg",
            "fig7_ray_duplication.svg",
            "fig8_memory_traffic.svg"
        ]
    );
    assert!(figs[0].1.contains("Figure 4") && figs[1].1.contains("Figure 5"));
    // One scene: ours and paper bars plus the two legend boxes.
    assert_eq!(figs[0].1.matches("<rect x=").count(), 2 + 2);
}

/// A long cycle-mode frame is announced with its time and the faster mode; a
/// short one is not, and the cycle estimate follows pixels, hit points and TMs.
#[test]
fn long_cycle_frames_are_announced() {
    use dualstream::render::{estimated_frame_cycles, long_frame_note};
    let mut s = scene::load("cornell").unwrap().settings;
    (s.width, s.height) = (256, 256);
    assert_eq!(long_frame_note(&s, 128), None);
    (s.width, s.height) = (2048, 2048);
    let n = long_frame_note(&s, 128).expect("a 2048x2048 frame takes hours");
    assert!(n.contains("--mode windows") && n.contains(" h"), "{n}");
    // Cornell 64x64, 5 hit points, 128 TMs ran 157,769 cycles (GDDR5).
    let c = estimated_frame_cycles(64 * 64, 5, 128);
    assert!((100_000..250_000).contains(&c), "{c}");
    assert_eq!(estimated_frame_cycles(64 * 64, 5, 64), 2 * c);
    assert_eq!(estimated_frame_cycles(64 * 64, 1, 128) * 5, c);
}

/// FNV-1a over the bits of a frame's linear radiance.
fn radiance_hash(r: &[Vec3]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in r
        .iter()
        .flat_map(|v| v.to_array())
        .flat_map(|x| x.to_bits().to_le_bytes())
    {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

fn mse(a: &[Vec3], b: &[Vec3]) -> f64 {
    let d: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared() as f64)
        .sum();
    d / a.len() as f64
}

fn with_spp(name: &str, res: u32, spp: u32) -> Scene {
    let mut s = small(name, res);
    s.settings.spp = spp;
    s
}

#[test]
fn one_path_per_pixel_is_the_frame_without_samples() {
    // The hash of the 16x16 Cornell box's radiance as the tracer gave it before
    // paths per pixel existed: main at 751863a, `render --res 16x16 --hdr`, its
    // PFM's rows in raster order. A change to the path tracer that means to
    // change the image updates it.
    let s = with_spp("cornell", 16, 1);
    let f = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    assert_eq!(f.spp, 1);
    assert_eq!(
        radiance_hash(&f.radiance),
        3_729_596_587_598_536_822,
        "spp 1 changed the image"
    );
}

#[test]
fn more_paths_per_pixel_are_less_noisy_deterministic_and_counted() {
    let run = |spp: u32, seed: u64| {
        // The Cornell box's point light near the ceiling makes fireflies
        // that a few paths do not average out; the tiny scene has none.
        let mut s = with_spp("tiny", 24, spp);
        s.settings.seed = seed;
        render(&s, Mode::Functional, &RenderCfg::default(), &mut |_| {}).unwrap()
    };
    // The reference on another seed: its noise is not the samples'.
    let reference = run(64, 7).radiance;
    let (one, four) = (run(1, 1), run(4, 1));
    let (e1, e4) = (
        mse(&one.radiance, &reference),
        mse(&four.radiance, &reference),
    );
    assert!(e4 < 0.5 * e1, "spp 4 MSE {e4} not well below spp 1's {e1}");
    // Four paths a pixel: about four times the rays, all counted.
    assert_eq!(four.spp, 4);
    assert!(
        four.total.rays > 3 * one.total.rays,
        "{} vs {}",
        four.total.rays,
        one.total.rays
    );
    // The same seed, the same image and counts, bit for bit.
    let again = run(4, 1);
    assert_eq!(again.radiance, four.radiance);
    assert_eq!(again.waves, four.waves);
    assert_ne!(run(4, 2).radiance, four.radiance);
}

#[test]
fn paths_per_pixel_on_the_chip_match_the_functional_frame() {
    // The chip traces a pixel's paths as rays of their own: the same image as
    // the functional model's (every ray verified), twice the primary rays.
    let s = with_spp("tiny", 8, 2);
    let mut rc = cfg(8);
    rc.chip = RenderCfg::for_chip(&dualstream::config::Config::default(), Default::default()).chip;
    let chip = render(&s, Mode::Cycle, &rc, &mut |_| {}).unwrap();
    let func = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap();
    assert_eq!(chip.radiance, func.radiance);
    assert_eq!(chip.waves[0].rays, 2 * 64);
}

#[test]
fn paths_per_pixel_out_of_range_are_named() {
    for spp in [0, 5000] {
        let s = with_spp("tiny", 8, spp);
        let e = render(&s, Mode::Functional, &cfg(8), &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("spp"), "{e}");
    }
}
