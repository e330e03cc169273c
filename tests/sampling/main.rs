//! Time sampling (`render --mode windows`) and `bench speed-error`: every
//! faster mode is compared against the full cycle model on the same frame, and
//! the figures are consistent with the modes' own runs. One test binary:
//! `study` (the speed/error modes and references), `windows` (the chip in
//! windows of a functional frame, and the estimate), `borrowing` (wavefronts
//! and root passes estimated from their neighbours, samples of short
//! wavefronts). The helpers they share are here.

use dualstream::config::Config;
use dualstream::sampling::speed_error::{SpeedErrorOpts, run};

#[path = "../common/mod.rs"]
mod common;
use common::Scratch;

mod borrowing;
mod study;
mod windows;

fn tiny() -> (dualstream::scene::Scene, Config) {
    let mut s = dualstream::scene::load("tiny").unwrap();
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 2;
    let mut c = Config::default();
    c.chip.tms = 4;
    c.tm.tps = 4;
    c.accel.segment_bytes = 8 << 10;
    (s, c)
}

/// Renders `s` on the chip with GDDR5 as `render --mode cycle --stats --out` would and
/// writes its statistics and PNG; returns their directory (removed when it is
/// dropped) and their paths.
fn reference_files(
    s: &dualstream::scene::Scene,
    c: &Config,
    tag: &str,
) -> (Scratch, std::path::PathBuf, std::path::PathBuf) {
    use dualstream::render::{self, ChipRun, Mode, RenderCfg};
    let mut g = c.clone();
    g.chip.memory.model = dualstream::units::memory::MemoryModel::Gddr5;
    let rc = RenderCfg {
        accel: g.accel.clone(),
        memory: g.memory.clone(),
        chip: Some(Box::new(ChipRun {
            config: g.clone(),
            sim: Default::default(),
            trace: None,
            follow: None,
            capture: None,
        })),
        ..Default::default()
    };
    let rc = RenderCfg {
        pass_log: true,
        ..rc
    };
    let mut f = render::render(s, Mode::Cycle, &rc, &mut |_| {}).unwrap();
    f.energy = Some(dualstream::render::energy::frame_energy(&g, &f));
    let dir = Scratch::new(&format!("se-ref-{tag}"));
    let (j, p) = (dir.join("ref.json"), dir.join("ref.png"));
    render::output::write_json(&f, None, Some(&j)).unwrap();
    render::output::write_png(&f, &p).unwrap();
    // Beside them, as `render --pass-log passes.csv` writes it.
    render::output::write_pass_log(&f, &dir.join("passes.csv")).unwrap();
    (dir, j, p)
}

/// The windows row against a rendered reference (`reference_files` beside
/// `j`, with its pass log), and the window log it wrote to `log`.
fn windows_against(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
    (j, png): (&std::path::Path, &std::path::Path),
    log: &std::path::Path,
) -> (
    dualstream::sampling::speed_error::ModeResult,
    serde_json::Value,
) {
    use dualstream::sampling::speed_error::Reference;
    let rows = run(
        s,
        c,
        &SpeedErrorOpts {
            modes: Some(vec!["windows".into()]),
            windows: plan,
            window_log: Some(log.to_path_buf()),
            reference: Some({
                let mut r = Reference::load(j, Some(png), s, c).unwrap();
                r.read_passes(&j.parent().unwrap().join("passes.csv"))
                    .unwrap();
                r
            }),
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(log).unwrap()).unwrap();
    (rows[1].clone(), v)
}

fn windows_plan(head: u64, every: u64) -> dualstream::sampling::WindowPlan {
    dualstream::sampling::WindowPlan {
        head,
        root_rays: u64::MAX,
        bounce_root_rays: u64::MAX,
        wave_rays: 0,
        wave_l2_share: 1,
        wave_ray_share: 0.0,
        wave_whole: 0,
        warm: 0,
        measure: every,
        every,
        shade_windows: 1,
        shade_warm: 0,
        shade_warm_cycles: 0,
        shade_measure: u64::MAX,
        shade_head: 0,
        tail_pending: 0,
        tail_warm: 0,
        wave_every: 1,
    }
}

/// The kinds of the windows wavefront `wave` took, in the order they ran, from
/// a window log.
fn window_kinds(v: &serde_json::Value, wave: u64) -> Vec<String> {
    v["record"]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["wave"] == wave)
        .map(|x| x["kind"].as_str().unwrap().to_string())
        .collect()
}

/// A window log's trace parts of wavefront `wave` (all but shading and
/// emission): name, cycles, borrowed.
fn trace_parts(v: &serde_json::Value, wave: u64) -> Vec<(String, f64, bool)> {
    v["parts"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["wave"] == wave && p["part"] != "shade" && p["part"] != "emit")
        .map(|p| {
            (
                p["part"].as_str().unwrap().to_string(),
                p["cycles"].as_f64().unwrap(),
                p["borrowed"].as_bool().unwrap(),
            )
        })
        .collect()
}

/// Two rows' errors in cycles, lines and energy, side by side.
fn figure_errors(
    a: &dualstream::sampling::speed_error::ModeResult,
    b: &dualstream::sampling::speed_error::ModeResult,
) -> [(&'static str, f64, f64); 3] {
    [
        ("cycles", a.err_cycles, b.err_cycles),
        ("lines", a.err_lines, b.err_lines),
        ("energy", a.err_energy, b.err_energy),
    ]
}

/// A small plan for the borrowing tests: windows of 6 admissions after 2 of
/// warm-up every 4, the tail from 2 pending queues, wavefronts traced every
/// `wave_every`, root windows of `root_rays`.
fn borrowing_plan(wave_every: u64, root_rays: u64) -> dualstream::sampling::WindowPlan {
    let mut plan = windows_plan(4, 6);
    plan.warm = 2;
    plan.measure = 6;
    plan.tail_pending = 2;
    plan.wave_every = wave_every;
    plan.root_rays = root_rays;
    plan.bounce_root_rays = root_rays;
    plan
}

/// The spheres without their room (its 12 triangles come first) at 16x16, 4
/// bounces: most bounce rays escape, so each wavefront has far fewer rays
/// than the last.
fn open_spheres() -> dualstream::scene::Scene {
    let mut s = dualstream::scene::load("spheres").unwrap();
    s.triangles.drain(..12);
    s.tri_material.drain(..12);
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 4;
    s
}

/// Part `part` of wavefront `wave` in a window log.
fn part_of<'a>(v: &'a serde_json::Value, wave: u64, part: &str) -> &'a serde_json::Value {
    v["parts"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["wave"] == wave && p["part"] == part)
        .unwrap()
}

/// The windows of one kind, in the order they ran.
fn of_kind(
    r: &dualstream::sampling::WindowRecord,
    kind: dualstream::sampling::SampleKind,
) -> Vec<&dualstream::sampling::WindowSample> {
    r.samples.iter().filter(|x| x.kind == kind).collect()
}

fn render_windows(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
) -> (
    dualstream::render::Frame,
    dualstream::sampling::WindowRecord,
) {
    render_windows_on(s, c, plan, 1)
}

/// With `threads` simulator threads (above one: the windows run side by side).
fn render_windows_on(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
    threads: usize,
) -> (
    dualstream::render::Frame,
    dualstream::sampling::WindowRecord,
) {
    let rc = dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        chip: Some(Box::new(dualstream::render::ChipRun {
            config: c.clone(),
            sim: dualstream::rtl::SimOptions {
                threads,
                ..Default::default()
            },
            ..Default::default()
        })),
        ..Default::default()
    };
    dualstream::sampling::render_windows(s, &rc, &plan).unwrap()
}

/// The Cornell box, 16x16, 2 bounces, on the tiny chip with GDDR5, in segments
/// of one DRAM row: a wavefront has passes to take over.
fn cornell_in_rows() -> (dualstream::scene::Scene, Config) {
    let (_, mut c) = tiny();
    let mut s = dualstream::scene::load("cornell").unwrap();
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 2;
    c.chip.memory.model = dualstream::units::memory::MemoryModel::Gddr5;
    c.accel.segment_bytes = c.memory.row_bytes as u32;
    (s, c)
}
