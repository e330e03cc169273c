//! `dualstream dram`: the memory system alone: replay a DRAMsim3-format trace
//! and print statistics, or generate a trace (random, stream, mixed).

use std::path::PathBuf;

use clap::Args;

use super::{CliError, unwritable};
use dualstream::config::Config;
use dualstream::util::FileError;

#[derive(Args)]
pub struct DramArgs {
    /// Replay this trace (`<hex address> <READ|WRITE> <cycle>` per line).
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Memory preset: paper (16 x 32-bit GDDR5, the default) or dramsim3-gddr5
    /// (DRAMsim3 running its GDDR5_8Gb_x32.ini: its device and its controller
    /// rules). Without it, the config's [mem] is used.
    #[arg(long)]
    preset: Option<String>,
    /// Energy preset: paper, physical or dramsim3 (default: the preset's own).
    #[arg(long)]
    energy: Option<String>,
    /// Record the DRAM commands and run the independent timing checker.
    #[arg(long)]
    check: bool,
    /// Generate a trace: random, stream or mixed (written to --out, or replayed).
    #[arg(long)]
    generate: Option<String>,
    /// Requests to generate.
    #[arg(long, default_value_t = 100_000)]
    requests: u64,
    /// Where to write the generated trace.
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// DRAM cycles between generated requests (0: all at cycle 0, unthrottled).
    #[arg(long, default_value_t = 0)]
    interval: u64,
    /// Fraction of generated random/stream requests that are writes.
    #[arg(long, default_value_t = 0.0)]
    write_fraction: f64,
}

/// `dualstream dram`: generate and/or replay a trace on the memory model.
pub fn dram(mut config: Config, a: DramArgs) -> Result<(), CliError> {
    use dualstream::mem::{MemCfg, config::EnergyCfg, replay, trace};
    // The config as given must hold together (the DRAM image fits its device);
    // a preset then replaces the device for this replay only (the image is unused).
    config.validate()?;
    let preset = match &a.preset {
        Some(p) => {
            let (m, tck) = MemCfg::preset(p)?;
            config.mem = m;
            config.clocks.dram_ps = tck;
            p.clone()
        }
        None => "config".to_string(),
    };
    if let Some(e) = &a.energy {
        config.mem.energy = EnergyCfg::by_name(e, &config.mem.geometry)?;
    }
    config.mem.validate()?;
    let m = &config.mem;
    let reqs = match (&a.trace, &a.generate) {
        (Some(_), Some(_)) => {
            return Err(CliError::Usage(
                "give either --trace FILE or --generate KIND, not both".into(),
            ));
        }
        (None, None) => {
            return Err(CliError::Usage(
                "nothing to do: give --trace FILE to replay, or --generate random|stream|mixed"
                    .into(),
            ));
        }
        (Some(t), None) => trace::read_file(t, m.geometry.capacity())?,
        (None, Some(kind)) => {
            if a.requests == 0 {
                return Err(CliError::Usage(
                    "--requests 0 generates nothing; give at least 1".into(),
                ));
            }
            let g = trace::generate(kind, a.requests, a.seed, m, a.interval, a.write_fraction)?;
            if let Some(out) = &a.out {
                let f = std::fs::File::create(out)
                    .map_err(|e| unwritable(out, e, "; choose a writable --out"))?;
                let mut w = std::io::BufWriter::new(f);
                trace::write(&g, &mut w)
                    .and_then(|_| std::io::Write::flush(&mut w))
                    .map_err(|e| {
                        let msg = format!("writing '{}' failed: {e}", out.display());
                        CliError::File(FileError::new(out, e, msg))
                    })?;
                println!("wrote {} requests to {}", g.len(), out.display());
                return Ok(());
            }
            g
        }
    };
    let opts = replay::ReplayOptions {
        check: a.check,
        preset,
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let r = replay::replay(m, config.clocks.dram_ps, &reqs, &opts)?;
    let wall = t0.elapsed().as_secs_f64();
    print!("{}", r.report);
    println!(
        "  wall time {wall:.3} s, {:.0} simulated requests per second",
        reqs.len() as f64 / wall.max(1e-9)
    );
    if let Some(v) = &r.report.violations
        && !v.is_empty()
    {
        return Err(CliError::Failed(format!(
            "the timing checker found {} violations",
            v.len()
        )));
    }
    Ok(())
}
