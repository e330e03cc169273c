//! `dualstream hdl`: the Verilog skeleton of every unit, or a self-checking
//! testbench of one unit from captured vectors.

use std::path::PathBuf;

use clap::Args;

use super::CliError;
use dualstream::config::Config;
use dualstream::rtl::tbgen::{self, TbGen, TbMode};

#[derive(Args)]
pub struct HdlArgs {
    #[arg(long, default_value = "hdl")]
    out: PathBuf,
    /// Write a SystemVerilog testbench of this unit (its module name:
    /// staging_buffer, hit_record_updater, ...) into --out instead of the
    /// skeletons: `tb_<module>.sv`, replaying --vectors.
    #[arg(long, value_name = "MODULE", requires = "vectors")]
    testbench: Option<String>,
    /// The vector file the testbench replays (`--capture` on render or tb).
    #[arg(long, value_name = "FILE")]
    vectors: Option<PathBuf>,
    /// order: each output delivers the model's payloads in the model's
    /// order; cycle: every token in the model's cycle.
    #[arg(long, default_value = "cycle")]
    mode: String,
    /// The testbench stops after this many mismatches.
    #[arg(long, default_value_t = 10)]
    max_mismatches: u32,
    /// Order mode: cycles after the vectors' end to wait for owed outputs.
    #[arg(long, default_value_t = 10_000)]
    timeout: u32,
}

pub fn hdl(config: &Config, a: HdlArgs) -> Result<(), CliError> {
    if let Some(unit) = &a.testbench {
        return testbench(config, unit, &a);
    }
    if a.vectors.is_some() {
        return Err(CliError::Usage(
            "--vectors is the input of a testbench: add --testbench MODULE".into(),
        ));
    }
    for p in dualstream::machine::hdl::write_hdl(config, &a.out)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn testbench(config: &Config, unit: &str, a: &HdlArgs) -> Result<(), CliError> {
    let mode = TbMode::parse(&a.mode).ok_or_else(|| {
        CliError::Usage(format!("unknown --mode '{}'; use order or cycle", a.mode))
    })?;
    let decls = dualstream::machine::hdl::catalog_checked(config)?;
    let Some(d) = decls.iter().find(|d| d.module == unit) else {
        let names: Vec<&str> = decls.iter().map(|d| d.module).collect();
        return Err(CliError::Usage(format!(
            "--testbench: no unit '{unit}'; the modules are {}",
            names.join(", ")
        )));
    };
    let vpath = a.vectors.as_ref().expect("clap requires --vectors");
    let text = read_head(vpath).map_err(|e| {
        CliError::Usage(format!(
            "cannot read the vector file '{}': {e}; give the file `--capture` wrote",
            vpath.display()
        ))
    })?;
    let h = tbgen::parse_header(&text)
        .and_then(|h| tbgen::check_header(d, &h).map(|_| h))
        .map_err(|e| CliError::Usage(format!("--vectors '{}': {e}", vpath.display())))?;
    let abs = std::fs::canonicalize(vpath).unwrap_or_else(|_| vpath.clone());
    let fires = match mode {
        TbMode::Order => std::fs::File::open(vpath)
            .and_then(|f| tbgen::count_fires(std::io::BufReader::new(f), d.ports.len()))
            .map_err(|e| {
                CliError::Usage(format!(
                    "cannot read the vector file '{}': {e}",
                    vpath.display()
                ))
            })?,
        TbMode::Cycle => Vec::new(),
    };
    let g = TbGen {
        fires,
        mode,
        vectors: abs.display().to_string(),
        max_mismatches: a.max_mismatches,
        timeout: a.timeout,
        params: h.params.clone(),
    };
    let sv = tbgen::emit_testbench(d, &g);
    std::fs::create_dir_all(&a.out)
        .map_err(|e| super::unwritable(&a.out, e, "; choose a writable --out"))?;
    let p = a.out.join(format!("tb_{}.sv", d.module));
    super::write_file(&p, &sv)?;
    println!(
        "wrote {} ({} mode, vectors of {}, {} cycles)",
        p.display(),
        mode.name(),
        h.instance,
        h.rows.map_or("?".into(), |r| r.to_string())
    );
    println!(
        "run: verilator --binary -j 1 hdl/ds_pkg.sv YOUR_{m}.sv {p} --top-module tb_{m} -o tb_{m} && obj_dir/tb_{m}",
        m = d.module,
        p = p.display()
    );
    println!(
        " or: iverilog -g2012 -o tb_{m}.vvp hdl/ds_pkg.sv YOUR_{m}.sv {p} && vvp -n tb_{m}.vvp",
        m = d.module,
        p = p.display()
    );
    Ok(())
}

/// The header of a vector file (its lines up to the first row).
fn read_head(p: &std::path::Path) -> std::io::Result<String> {
    use std::io::BufRead;
    let f = std::io::BufReader::new(std::fs::File::open(p)?);
    let mut s = String::new();
    for l in f.lines() {
        let l = l?;
        if !l.starts_with("//") {
            break;
        }
        s.push_str(&l);
        s.push('\n');
    }
    Ok(s)
}
