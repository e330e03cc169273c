//! `dualstream config`: the configuration in force, or the default one, as TOML.

use clap::Args;

use super::CliError;
use dualstream::config::Config;

#[derive(Args)]
pub struct ConfigArgs {
    /// Print the default configuration as TOML, every key with a comment
    /// (meaning, unit, source; the paper's values marked [DS17 ...]).
    #[arg(long)]
    print_default: bool,
}

pub fn config(config: &Config, a: ConfigArgs) -> Result<(), CliError> {
    if a.print_default {
        print!("{}", Config::default().to_commented_toml());
    } else {
        print!("{}", config.to_toml());
    }
    Ok(())
}
