//! The configuration: every latency, interval, size and clock of the model. The
//! defaults are the paper's Table 1 and section 5.1 (Shkurko et al. 2017); each
//! default names its source. Loaded from TOML; unknown keys are errors.

mod chip;
mod doc;
mod error;

pub use chip::{ChipCfg, EarlyTermination, Shading};
pub use error::ConfigError;

use serde::{Deserialize, Serialize};

use crate::rtl::{LinkCfg, PipeCfg};

/// Clock domains on the common picosecond time base.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClockCfg {
    /// Core clock period: 1 GHz [DS17 Table 1].
    pub core_ps: u64,
    /// DRAM command clock period, ps: GDDR5 at 8 Gb/s per pin has CK = 2 GHz,
    /// 500 ps (hardware reference sheet, conventions); the DRAMsim3 preset's
    /// tCK = 0.667 ns is 667.
    pub dram_ps: u64,
}

impl Default for ClockCfg {
    fn default() -> Self {
        ClockCfg {
            core_ps: 1000,
            dram_ps: 500,
        }
    }
}

/// Links between units.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinksCfg {
    /// Request and response links inside a TM (TP <-> shared pipelines). One
    /// register stage (delay 1) and two entries so a pipeline with interval 1 is
    /// never throttled by its links.
    pub tm: LinkCfg,
}

impl Default for LinksCfg {
    fn default() -> Self {
        LinksCfg {
            tm: LinkCfg { depth: 2, delay: 1 },
        }
    }
}

/// The whole model configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub clocks: ClockCfg,
    pub links: LinksCfg,
    /// Ray-box pipeline: initiation interval 1, latency 8 [DS17 §5.1]. One issue
    /// tests one box (the TP issues the two children of a BVH2 node back to back).
    pub box_pipe: PipeCfg,
    /// Ray-triangle pipeline (Plücker test): interval 18, latency 31 [DS17 §5.1].
    pub tri_pipe: PipeCfg,
    /// TM-shared divider for the inverse ray direction. simtrax's 65 nm FPINV has a
    /// 16-cycle latency, one per TM (hardware reference §1.2). Pipelined with one
    /// divide issued per cycle, the three components of a direction take 3 issue
    /// cycles: interval 3, and the last component is done 16 + 2 = 18 cycles after
    /// the first was accepted.
    pub divider: PipeCfg,
    /// BVH build and segment (treelet) formation.
    pub accel: crate::accel::AccelCfg,
    /// The DRAM image's layout (the data contract): what lies where, its
    /// capacity and row (both must match `[mem.geometry]`), ray buckets. Not
    /// timing: that is `[mem]`.
    pub memory: crate::contract::MemoryMapCfg,
    /// The GDDR5 device and its controllers (geometry, timing, address
    /// mapping, FR-FCFS controller, energy), used when `[chip.memory] model =
    /// "gddr5"` and by `dualstream dram`.
    pub mem: crate::mem::MemCfg,
    /// The thread multiprocessor: TPs and their cost table, L1, staging buffer.
    pub tm: crate::units::tm::TmCfg,
    /// On-chip and compute energy per access and per operation (65 nm).
    pub energy: crate::energy::EnergyCfg,
    /// The chip top: TMs, stream scheduler, scene buffer, hit record updater, memory.
    pub chip: ChipCfg,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            clocks: ClockCfg::default(),
            links: LinksCfg::default(),
            box_pipe: PipeCfg {
                latency: 8,
                interval: 1,
            },
            tri_pipe: PipeCfg {
                latency: 31,
                interval: 18,
            },
            divider: PipeCfg {
                latency: 18,
                interval: 3,
            },
            accel: crate::accel::AccelCfg::default(),
            memory: crate::contract::MemoryMapCfg::default(),
            mem: crate::mem::MemCfg::default(),
            tm: crate::units::tm::TmCfg::default(),
            energy: crate::energy::EnergyCfg::default(),
            chip: ChipCfg::default(),
        }
    }
}

impl Config {
    /// What a TM is built from (`units::tm::build`).
    pub fn tm_spec(&self) -> crate::units::tm::TmSpec {
        crate::units::tm::TmSpec {
            tm: self.tm.clone(),
            box_pipe: self.box_pipe,
            tri_pipe: self.tri_pipe,
            divider: self.divider,
            link: self.links.tm,
            core_ps: self.clocks.core_ps,
        }
    }

    /// Parses TOML; missing keys take their defaults, unknown keys are errors.
    pub fn from_toml(text: &str) -> Result<Config, ConfigError> {
        let c: Config = toml::from_str(text).map_err(ConfigError::of_toml)?;
        c.validate()?;
        Ok(c)
    }

    pub fn load(path: &std::path::Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            let msg = format!(
                "cannot read config '{}': {e}; check the path given to --config",
                path.display()
            );
            ConfigError::File(crate::util::FileError::new(path, e, msg))
        })?;
        Config::from_toml(&text).map_err(|e| ConfigError::InFile {
            path: path.to_path_buf(),
            inner: Box::new(e),
        })
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("config serialises")
    }

    /// [`Config::to_toml`] with every key's doc comment (its meaning, unit
    /// and source, from the struct that holds it) above it.
    pub fn to_commented_toml(&self) -> String {
        doc::commented(&self.to_toml()).0
    }

    /// Rejects impossible configurations with a message naming the key and the fix.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.clocks.core_ps == 0 || self.clocks.dram_ps == 0 {
            return Err(ConfigError::Impossible("clocks: a clock period of 0 ps is impossible; give a positive period (core_ps = 1000 is 1 GHz)".into()));
        }
        self.links.tm.validate("links.tm")?;
        for (name, p) in [
            ("box_pipe", &self.box_pipe),
            ("tri_pipe", &self.tri_pipe),
            ("divider", &self.divider),
        ] {
            validate_pipe(name, p, &self.links.tm)?;
        }
        self.memory.validate()?;
        self.accel.validate(self.memory.row_bytes)?;
        self.mem.validate()?;
        // The DRAM image (`memory`) lives in the device (`mem.geometry`): one row
        // size and one capacity. (`dualstream dram --preset` swaps the device for a
        // trace replay only, after this check.)
        let g = &self.mem.geometry;
        if self.memory.row_bytes != g.row_bytes() {
            return Err(ConfigError::Impossible(format!(
                "memory.row_bytes = {} differs from the device's row, mem.geometry.columns x burst = {} x {} B = {} B; set memory.row_bytes = {} or change mem.geometry",
                self.memory.row_bytes,
                g.columns,
                g.burst_bytes(),
                g.row_bytes(),
                g.row_bytes()
            )));
        }
        if self.memory.capacity_bytes != g.capacity() {
            return Err(ConfigError::Impossible(format!(
                "memory.capacity_bytes = {} differs from the device's capacity, mem.geometry channels x banks x rows x row = {} x {} x {} x {} B = {} B; set memory.capacity_bytes = {} or change mem.geometry",
                self.memory.capacity_bytes,
                g.channels,
                g.banks(),
                g.rows,
                g.row_bytes(),
                g.capacity(),
                g.capacity()
            )));
        }
        self.tm.validate(&self.links.tm)?;
        self.energy.validate()?;
        self.chip.validate(self.accel.segment_bytes)?;
        Ok(())
    }
}

fn validate_pipe(name: &str, p: &PipeCfg, out_link: &LinkCfg) -> Result<(), ConfigError> {
    if p.latency == 0 {
        return Err(ConfigError::Impossible(format!(
            "{name}.latency = 0 is impossible: a registered unit needs at least one cycle; set latency >= {}",
            out_link.delay + 1
        )));
    }
    if p.latency <= out_link.delay {
        return Err(ConfigError::Impossible(format!(
            "{name}.latency = {} does not exceed the output link delay ({}, links.tm.delay), which is part of it; set latency >= {}",
            p.latency,
            out_link.delay,
            out_link.delay + 1
        )));
    }
    if p.interval == 0 {
        return Err(ConfigError::Impossible(format!(
            "{name}.interval = 0 is impossible: at most one request per cycle; set interval >= 1"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_the_paper_and_round_trips() {
        let c = Config::default();
        assert_eq!((c.box_pipe.latency, c.box_pipe.interval), (8, 1));
        assert_eq!((c.tri_pipe.latency, c.tri_pipe.interval), (31, 18));
        let back = Config::from_toml(&c.to_toml()).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn impossible_configs_are_named() {
        let e = Config::from_toml("[box_pipe]\nlatency = 0\ninterval = 1\n").unwrap_err();
        assert!(matches!(e, ConfigError::Impossible(_)), "{e:?}");
        assert!(e.to_string().contains("box_pipe.latency = 0"), "{e}");
        let e = Config::from_toml("[tri_pipe]\nlatency = 31\ninterval = 0\n").unwrap_err();
        assert!(e.to_string().contains("tri_pipe.interval = 0"), "{e}");
        let e = Config::from_toml("[links.tm]\ndepth = 2\ndelay = 0\n").unwrap_err();
        assert!(
            matches!(&e, ConfigError::Link(crate::rtl::SimError::LinkCfg { what, .. }) if what == "links.tm"),
            "{e:?}"
        );
        assert!(e.to_string().contains("combinational"), "{e}");
        let e = Config::from_toml("[clocks]\ncore_ps = 0\n").unwrap_err();
        assert!(e.to_string().contains("period of 0"), "{e}");
        let e = Config::from_toml("[box_pipe]\nlatncy = 3\ninterval = 1\n").unwrap_err();
        assert!(
            matches!(&e, ConfigError::UnknownKey { key, .. } if key == "latncy"),
            "{e:?}"
        );
        assert!(e.to_string().contains("latncy"), "{e}");
    }

    #[test]
    fn early_termination_is_chosen_by_name_and_others_refused() {
        assert_eq!(
            Config::default().chip.early_termination,
            EarlyTermination::None
        );
        for e in EarlyTermination::ALL {
            let c = Config::from_toml(&format!("[chip]\nearly_termination = \"{e}\"\n")).unwrap();
            assert_eq!(c.chip.early_termination, e);
            assert_eq!(Config::from_toml(&c.to_toml()).unwrap(), c);
        }
        let e = Config::from_toml("[chip]\nearly_termination = \"always\"\n").unwrap_err();
        assert!(matches!(e, ConfigError::Toml(_)), "{e:?}");
        let m = e.to_string();
        assert!(
            m.contains("early_termination") && m.contains("always"),
            "{m}"
        );
        for v in ["none", "pre", "post", "both"] {
            assert!(m.contains(&format!("`{v}`")), "{m}");
        }
    }
}
