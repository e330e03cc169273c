//! `dualstream report paper`: our figures next to the paper's Table 2, with
//! optional JSON and SVG figures.

use std::path::PathBuf;

use clap::Args;

use dualstream::config::Config;
use dualstream::render::Mode;
use dualstream::render::header::{HeadedList, RunHeader, RunParams};
use dualstream::report::paper;
use dualstream::rtl::Threads;
use dualstream::units::memory::MemoryModel;
use dualstream::util::FileError;

use super::progress::{Meter, quiet};
use super::{CliError, parse_res, render_cfg, unwritable};
use dualstream::sampling;

#[derive(Args)]
pub struct ReportArgs {
    #[command(flatten)]
    pub threads: super::ThreadsArg,
    /// What to report: paper.
    what: String,
    /// Resolution (the paper's is 1024x1024).
    #[arg(long, default_value = "1024x1024")]
    res: String,
    /// Write the comparison as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write paper-style figures (SVG) into this directory.
    #[arg(long)]
    plots: Option<PathBuf>,
    /// functional (counts only, fast), cycle (the chip with GDDR5: also
    /// render time, rays/s, bandwidth and DRAM energy; about an hour for the
    /// three scenes at 1024x1024) or windows (time sampling: the cycle
    /// model's figures estimated from windows of the chip, within 3% of it
    /// on these scenes (docs/speed-error.md), in minutes; same image).
    #[arg(long, default_value = "functional", value_parser = ["functional", "cycle", "windows"])]
    mode: String,
    /// Early ray termination (overrides `[chip] early_termination`): none,
    /// pre, post or both, as for render. Functional mode only so far.
    #[arg(long, value_enum, value_name = "CHOICE")]
    early_termination: Option<super::EarlyTermArg>,
}

/// `dualstream report paper`: renders the three paper scenes and prints the
/// comparison table.
pub fn report(mut config: Config, threads: Threads, a: ReportArgs) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    super::EarlyTermArg::apply(a.early_termination, &mut config);
    let sampled = a.mode == "windows";
    let mode = match a.mode.as_str() {
        "functional" | "windows" => Mode::Functional,
        "cycle" => Mode::Cycle,
        m => {
            return Err(CliError::Usage(format!(
                "unknown report mode '{m}'; use --mode functional, cycle or windows"
            )));
        }
    };
    let et = config.chip.early_termination;
    if (mode != Mode::Functional || sampled) && et != dualstream::config::EarlyTermination::None {
        return Err(CliError::Usage(dualstream::render::only_functional(et)));
    }
    if a.what != "paper" {
        return Err(CliError::Usage(format!(
            "unknown report '{}'; available: paper",
            a.what
        )));
    }
    let (w, h) = parse_res(&a.res)?;
    let mut rows = Vec::new();
    // One step per scene (in this command's one mode).
    let mut bar = Meter::new("report", paper::TABLE2.len() as u64 * 1000);
    for (k, row) in paper::TABLE2.iter().enumerate() {
        // The scene files: in the search path (--scenes-dir,
        // $DUALSTREAM_SCENES), else the repository's scenes/.
        let path = dualstream::scene::search::dirs()
            .into_iter()
            .chain([PathBuf::from("scenes")])
            .map(|d| d.join(row.scene_file))
            .find(|p| p.is_file())
            .unwrap_or_else(|| PathBuf::from(row.scene_file));
        let spec = path
            .to_str()
            .ok_or_else(|| CliError::Usage("scene path is not UTF-8".into()))?;
        let mut sc = dualstream::scene::load(spec).map_err(|e| CliError::Hinted {
            error: Box::new(e.into()),
            hint: "(the paper scenes are scenes/*.toml and need their meshes: run from the repository root, or give the directories with --scenes-dir or $DUALSTREAM_SCENES)",
        })?;
        sc.settings.width = w;
        sc.settings.height = h;
        sc.settings.validate()?;
        let how = if sampled {
            "time sampling".to_string()
        } else {
            format!("{mode:?}")
        };
        let what = format!("{} at {w}x{h} ({how})", row.scene);
        let done = k as u64 * 1000;
        bar.set(done, || what.clone());
        let mut cfg = config.clone();
        if mode == Mode::Cycle {
            // Time, bandwidth and DRAM energy need the GDDR5 model.
            cfg.chip.memory.model = MemoryModel::Gddr5;
        }
        let t0 = std::time::Instant::now();
        let est = dualstream::render::estimated_frame_cycles(
            w as u64 * h as u64,
            sc.settings.bounces,
            cfg.chip.tms,
        );
        if sampled {
            let plan = sampling::default_windows();
            let ts = sampling::time_sampled_progress(
                &sc,
                &cfg,
                render_cfg(&cfg, threads),
                &plan,
                &mut |p| {
                    let f = (p.wave as u64 * 1000
                        + p.segment as u64 * 1000 / p.segments.max(1) as u64)
                        / p.waves_max.max(1) as u64;
                    bar.set(done + f, || {
                        format!(
                            "{what}: wavefront {}/{}, {} windows done",
                            p.wave, p.waves_max, p.windows_done
                        )
                    });
                },
            )?;
            let e = &ts.estimate;
            say(format!(
                "{what}: {:.1} s ({} windows, {:.0} s in the chips: {}){}",
                t0.elapsed().as_secs_f64(),
                e.windows,
                e.chip_s,
                sampling::kind_times_text(&e.chip_s_by_kind),
                e.se_text().map(|t| format!("; {t}")).unwrap_or_default()
            ));
            rows.extend(paper::compare_sampled(row, &ts.frame, e));
            continue;
        }
        let mut frame =
            dualstream::render::render(&sc, mode, &render_cfg(&cfg, threads), &mut |p| {
                // Cycle mode: simulated cycles against the frame's estimate.
                let f = if mode == Mode::Cycle {
                    (p.cycles * 1000 / est.max(1)).min(999)
                } else {
                    (p.wave as u64 * 1000 + (p.done * 1000).checked_div(p.known).unwrap_or(0))
                        / p.waves_max.max(1) as u64
                };
                bar.set(done + f, || {
                    format!("{what}: wavefront {}/{}", p.wave, p.waves_max)
                });
            })?;
        say(format!("{what}: {:.1} s", t0.elapsed().as_secs_f64()));
        frame.energy = Some(dualstream::render::energy::frame_energy(&cfg, &frame));
        rows.extend(paper::compare(row, &frame));
    }
    bar.finish("every scene done");
    if (w, h) != paper::PAPER_RES {
        println!(
            "at {w}x{h}, not the paper's 1024x1024: a frame's totals (time, rays, energy, lines) grow with its pixels and get no ratio (\"scale_free\": false in the JSON); rates and ratios compare"
        );
    }
    print!("{}", paper::table(&rows));
    let run = RunParams {
        resolution: Some([w, h]),
        mode: Some(a.mode.clone()),
        threads: Some(a.threads.threads.clone()),
        ..RunParams::default()
    };
    let header = RunHeader::new(&config, run, started.elapsed().as_secs_f64());
    write_outputs(&rows, &header, a.json, a.plots)
}

/// A scene's time on stderr, unless `--quiet`.
fn say(s: String) {
    if !quiet() {
        eprintln!("{s}");
    }
}

/// The comparison as JSON and the figures as SVG, if asked for.
fn write_outputs(
    rows: &[paper::Compared],
    header: &RunHeader,
    json: Option<PathBuf>,
    plots: Option<PathBuf>,
) -> Result<(), CliError> {
    if let Some(p) = json {
        let v = HeadedList {
            header,
            key: "rows",
            body: &rows,
        };
        let text = serde_json::to_string_pretty(&v).expect("rows serialise");
        std::fs::write(&p, text).map_err(|e| unwritable(&p, e, "; choose a writable --json"))?;
        println!("comparison: {}", p.display());
    }
    if let Some(dir) = plots {
        std::fs::create_dir_all(&dir).map_err(|e| {
            let msg = format!(
                "cannot create '{}': {e}; choose a writable --plots directory",
                dir.display()
            );
            CliError::File(FileError::new(&dir, e, msg))
        })?;
        for (name, svg) in paper::figures(rows) {
            let p = dir.join(name);
            std::fs::write(&p, svg).map_err(|e| unwritable(&p, e, ""))?;
            println!("figure: {}", p.display());
        }
    }
    Ok(())
}
