//! `dualstream hdl`: the Verilog skeleton of every unit.

use std::path::PathBuf;

use clap::Args;

use super::CliError;
use dualstream::config::Config;

#[derive(Args)]
pub struct HdlArgs {
    #[arg(long, default_value = "hdl")]
    out: PathBuf,
}

pub fn hdl(config: &Config, a: HdlArgs) -> Result<(), CliError> {
    for p in dualstream::machine::hdl::write_hdl(config, &a.out)? {
        println!("wrote {}", p.display());
    }
    Ok(())
}
