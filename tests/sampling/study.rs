//! `bench speed-error`'s modes against the cycle model, and its references.

use super::*;
use dualstream::sampling::speed_error::{plot, table, tile_sample};
use dualstream::sampling::{SamplingError, estimate};

#[test]
fn every_mode_against_the_cycle_model() {
    let (s, c) = tiny();
    let o = SpeedErrorOpts {
        small_tms: 2,
        sample_every: 4,
        tile: 4,
        ..SpeedErrorOpts::default()
    };
    let rows = run(&s, &c, &o).unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(
        names,
        [
            "cycle",
            "cycle-fixed",
            "functional+estimate",
            "small-chip",
            "quarter-pixels",
            "sampled",
            "sampled-scaled",
            "windows"
        ]
    );
    let r = &rows[0];
    assert!(r.cycles > 0.0 && r.lines > 0.0 && r.energy_j > 0.0);
    assert_eq!((r.err_cycles, r.err_lines, r.err_energy), (0.0, 0.0, 0.0));
    for m in &rows[1..] {
        let want = (m.cycles - r.cycles) / r.cycles;
        assert!((m.err_cycles - want).abs() < 1e-12, "{}", m.mode);
        assert!(m.cycles > 0.0 && m.energy_j > 0.0, "{}", m.mode);
    }
    // Modes that render the same frame render the same image: every ray agrees
    // (time sampling's windows leave the functional model's image untouched).
    for m in rows[1..4].iter().chain(&rows[7..]) {
        assert_eq!(m.image_identical, Some(true), "{}", m.mode);
    }
    assert_eq!(rows[4].image_identical, None);
    // The samples' pixels are the whole frame's, and two samples give an error bar.
    for m in &rows[5..7] {
        assert_eq!(m.image_identical, Some(true), "{}", m.mode);
        let e = m.est_err.expect("two samples estimate their error");
        assert!(e.iter().all(|x| x.is_finite() && *x >= 0.0), "{e:?}");
    }
    assert!(rows[..5].iter().all(|m| m.est_err.is_none()));
    // The stream lines do not depend on timing: the chip with either memory moves
    // as many lines within the timing-dependent hit-record merging.
    assert!(rows[1].err_lines.abs() < 0.1, "{}", rows[1].err_lines);
    let t = table(&rows);
    assert_eq!(t.lines().count(), 9, "{t}");
    assert_eq!(plot(&rows).matches("<circle").count(), 8);
}

#[test]
fn the_estimate_is_at_least_every_resource_bound() {
    let (s, c) = tiny();
    let rc = dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        ..Default::default()
    };
    let f = dualstream::render::render(&s, dualstream::render::Mode::Functional, &rc, &mut |_| {})
        .unwrap();
    let e = estimate(&c, &f);
    assert_eq!(e.binding.len(), f.waves.len());
    let (mut nodes, mut ray_lines) = (0u64, 0u64);
    for w in &f.waves {
        nodes += w.traversal.nodes;
        ray_lines += w.ray_lines();
    }
    // Box tests at one per TM per cycle, ray-stream lines at their lanes per cycle.
    assert!(e.cycles >= nodes as f64 / c.chip.tms as f64);
    let lanes = c.chip.scheduler.ray_lines_per_cycle as f64;
    assert!(e.cycles >= ray_lines as f64 / lanes);
    // Twice the TMs cannot make the compute bounds slower.
    let mut big = c.clone();
    big.chip.tms *= 2;
    assert!(estimate(&big, &f).cycles <= e.cycles);
}

#[test]
fn an_impossible_small_chip_is_named() {
    let (s, c) = tiny();
    let e = run(
        &s,
        &c,
        &SpeedErrorOpts {
            small_tms: 4,
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("--small-tms 4") && e.contains("chip.tms"), "{e}");
}

#[test]
fn two_small_chips_fit_a_serial_and_a_parallel_part() {
    let (s, mut c) = tiny();
    c.chip.tms = 8;
    let rows = run(
        &s,
        &c,
        &SpeedErrorOpts {
            small_tms: 2,
            tile: 4,
            sample_every: 4,
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(names[3..5], ["small-chip", "small-chips-fit"]);
    let fit = &rows[4];
    assert_eq!(fit.image_identical, Some(true));
    assert!(fit.note.contains("2 and 4 TMs"), "{}", fit.note);
    // Both small runs together take longer than the linear mode's one run.
    assert!(fit.wall_s >= rows[3].wall_s);
}

/// A pixel sample renders exactly its pixels, each as in the whole frame.
#[test]
fn a_pixel_sample_renders_its_pixels_as_the_whole_frame_does() {
    let (s, c) = tiny();
    let rc = |pixels: Option<Vec<u32>>| dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        pixels,
        ..Default::default()
    };
    let mode = dualstream::render::Mode::Functional;
    let full = dualstream::render::render(&s, mode, &rc(None), &mut |_| {}).unwrap();
    let pix = tile_sample(16, 16, 4, 4, 1).unwrap();
    assert_eq!(pix.len(), 64, "a quarter of the 16 tiles");
    let part = dualstream::render::render(&s, mode, &rc(Some(pix.clone())), &mut |_| {}).unwrap();
    assert!(part.total.rays < full.total.rays);
    let lit = pix
        .iter()
        .filter(|&&p| full.radiance[p as usize] != glam::Vec3::ZERO)
        .count();
    assert!(lit > 0, "the test needs lit pixels in the sample");
    for p in 0..256u32 {
        let want = if pix.contains(&p) {
            full.radiance[p as usize]
        } else {
            glam::Vec3::ZERO
        };
        assert_eq!(
            part.radiance[p as usize].to_array().map(f32::to_bits),
            want.to_array().map(f32::to_bits),
            "pixel {p}"
        );
    }
    // The samples of the offsets partition the frame.
    let mut all: Vec<u32> = (0..4)
        .flat_map(|o| tile_sample(16, 16, 4, 4, o).unwrap())
        .collect();
    all.sort();
    assert_eq!(all, (0..256).collect::<Vec<u32>>());
    // A bad sample is named.
    for bad in [vec![], vec![3, 3], vec![5, 2], vec![256]] {
        let e = dualstream::render::render(&s, mode, &rc(Some(bad.clone())), &mut |_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("pixel sample"), "{bad:?}: {e}");
    }
}

/// Sampling every tile in one sample is the whole frame: both estimates equal the
/// reference.
#[test]
fn sampling_every_tile_is_the_whole_frame() {
    let (s, c) = tiny();
    let o = SpeedErrorOpts {
        sample_every: 1,
        subsets: 1,
        tile: 4,
        modes: Some(vec!["sampled".into()]),
        ..SpeedErrorOpts::default()
    };
    let rows = run(&s, &c, &o).unwrap();
    assert_eq!(rows.len(), 3);
    for m in &rows[1..] {
        for e in [m.err_cycles, m.err_lines, m.err_energy] {
            assert!(e.abs() < 1e-9, "{}: {e}", m.mode);
        }
        assert_eq!(m.est_err, None, "one sample has no error bar");
    }
}

#[test]
fn bad_speed_error_options_are_named() {
    let (s, c) = tiny();
    let with = |f: &dyn Fn(&mut SpeedErrorOpts)| {
        let mut o = SpeedErrorOpts {
            modes: Some(vec!["sampled".into()]),
            tile: 4,
            sample_every: 4,
            ..SpeedErrorOpts::default()
        };
        f(&mut o);
        run(&s, &c, &o).unwrap_err()
    };
    let says = |f: &dyn Fn(&mut SpeedErrorOpts), what: &str| {
        let e = with(f);
        assert!(matches!(e, SamplingError::Invalid(_)), "{e:?}");
        assert!(e.to_string().contains(what), "{e}");
    };
    says(&|o| o.sample_every = 0, "--sample-every 0");
    says(&|o| o.tile = 0, "--tile 0");
    says(&|o| o.tile = 17, "--tile 17");
    says(&|o| o.subsets = 5, "--subsets 5");
    says(
        &|o| o.modes = Some(vec!["warp".into()]),
        "unknown mode 'warp'",
    );
    assert!(
        with(&|o| {
            o.tile = 16;
            o.sample_every = 4;
            o.subsets = 4
        })
        .to_string()
        .contains("too few")
    );
    // A wavefront sample's L2 share must leave whole sets.
    for share in [0, 3, 1 << 20] {
        let e = with(&|o| {
            o.modes = Some(vec!["windows".into()]);
            o.windows.wave_l2_share = share;
        })
        .to_string();
        assert!(e.contains(&format!("--window-wave-l2 {share}")), "{e}");
    }
    // A share of a segment's lines: finite, not negative.
    for share in [-0.5, f64::NAN, f64::INFINITY] {
        let e = with(&|o| {
            o.modes = Some(vec!["windows".into()]);
            o.windows.wave_ray_share = share;
        })
        .to_string();
        assert!(
            e.contains(&format!("--window-wave-ray-share {share}")),
            "{e}"
        );
    }
}

#[test]
fn a_reference_read_back_gives_the_same_errors() {
    use dualstream::sampling::speed_error::Reference;
    let (s, c) = tiny();
    let (_dir, j, p) = reference_files(&s, &c, "same");
    let modes = Some(vec![
        "functional+estimate".to_string(),
        "sampled".to_string(),
    ]);
    let o = SpeedErrorOpts {
        sample_every: 4,
        tile: 4,
        modes: modes.clone(),
        ..SpeedErrorOpts::default()
    };
    let own = run(&s, &c, &o).unwrap();
    let read = run(
        &s,
        &c,
        &SpeedErrorOpts {
            reference: Some(Reference::load(&j, Some(&p), &s, &c).unwrap()),
            ..o.clone()
        },
    )
    .unwrap();
    assert_eq!(own.len(), read.len());
    for (a, b) in own.iter().zip(&read) {
        assert_eq!(a.mode, b.mode);
        // Same figures and errors (the energy goes through the JSON's decimal text).
        for (x, y) in [
            (a.cycles, b.cycles),
            (a.lines, b.lines),
            (a.err_cycles, b.err_cycles),
            (a.err_lines, b.err_lines),
            (a.err_energy, b.err_energy),
        ] {
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                "{}: {x} {y}",
                a.mode
            );
        }
        assert_eq!(b.image_identical, Some(true), "{}", b.mode);
    }
    // Without the PNG the images are not checked.
    let r = Reference::load(&j, None, &s, &c).unwrap();
    let rows = run(
        &s,
        &c,
        &SpeedErrorOpts {
            reference: Some(r),
            ..o
        },
    )
    .unwrap();
    assert!(rows[1..].iter().all(|m| m.image_identical.is_none()));
}

#[test]
fn a_reference_of_another_frame_is_refused() {
    use dualstream::sampling::speed_error::Reference;
    let (s, c) = tiny();
    let (_dir, j, p) = reference_files(&s, &c, "other");
    // Another resolution is named from the file alone.
    let mut wide = s.clone();
    wide.settings.width = 32;
    let e = Reference::load(&j, Some(&p), &wide, &c)
        .unwrap_err()
        .to_string();
    assert!(e.contains("16x16, not 32x16"), "{e}");
    // Another bounce count is the same size on paper: the traced rays tell.
    let mut deeper = s.clone();
    deeper.settings.bounces = 3;
    let r = Reference::load(&j, Some(&p), &deeper, &c).unwrap();
    let e = run(
        &deeper,
        &c,
        &SpeedErrorOpts {
            reference: Some(r),
            modes: Some(vec!["functional+estimate".to_string()]),
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("rays") && e.contains("re-render"), "{e}");
    // A functional-mode file is not a reference.
    let text = std::fs::read_to_string(&j)
        .unwrap()
        .replace("\"cycle\"", "\"functional\"");
    std::fs::write(&j, text).unwrap();
    let e = Reference::load(&j, None, &s, &c).unwrap_err().to_string();
    assert!(e.contains("not cycle"), "{e}");
}
