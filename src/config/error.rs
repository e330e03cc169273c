//! The configuration's error: TOML that does not parse or names an unknown key,
//! an impossible value (the key and the fix named), a check of a lower layer's
//! section, or a config file that cannot be read.

use std::fmt;
use std::path::PathBuf;

use crate::accel::AccelError;
use crate::contract::MapError;
use crate::energy::EnergyError;
use crate::mem::MemError;
use crate::rtl::SimError;
use crate::units::UnitError;
use crate::util::FileError;

#[derive(Debug)]
pub enum ConfigError {
    /// A key no section has (a typo, or a key of another section).
    UnknownKey {
        key: String,
        toml: Box<toml::de::Error>,
    },
    /// TOML that does not parse, or a value of the wrong type or an unknown name
    /// (boxed: toml's error is large, and every layer above carries this one).
    Toml(Box<toml::de::Error>),
    /// A value (or a combination) the model cannot run, the key and the fix named.
    Impossible(String),
    /// A link of `links.*` or `chip.links`.
    Link(SimError),
    /// `memory.*` (the DRAM image).
    Map(MapError),
    /// `accel.*`, `bvh.*`.
    Accel(AccelError),
    /// `mem.*` (the memory system).
    Mem(MemError),
    /// A unit's section (`tm.*`, `chip.l2.*`, ...).
    Unit(UnitError),
    /// `energy.*`.
    Energy(EnergyError),
    /// The config file cannot be read.
    File(FileError),
    /// An error in the config file at `path`.
    InFile {
        path: PathBuf,
        inner: Box<ConfigError>,
    },
}

impl ConfigError {
    /// The error of a TOML text that does not deserialise: an unknown key told
    /// apart from the rest.
    pub(super) fn of_toml(e: toml::de::Error) -> ConfigError {
        let key = e
            .message()
            .strip_prefix("unknown field `")
            .and_then(|r| r.split('`').next())
            .map(str::to_string);
        match key {
            Some(key) => ConfigError::UnknownKey {
                key,
                toml: Box::new(e),
            },
            None => ConfigError::Toml(Box::new(e)),
        }
    }

    /// The error itself, without the file it was read from.
    pub fn root(&self) -> &ConfigError {
        match self {
            ConfigError::InFile { inner, .. } => inner.root(),
            e => e,
        }
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::UnknownKey { toml, .. } | ConfigError::Toml(toml) => {
                write!(f, "config: {toml}")
            }
            ConfigError::Impossible(m) => f.write_str(m),
            ConfigError::Link(e) => write!(f, "{e}"),
            ConfigError::Map(e) => write!(f, "{e}"),
            ConfigError::Accel(e) => write!(f, "{e}"),
            ConfigError::Mem(e) => write!(f, "{e}"),
            ConfigError::Unit(e) => write!(f, "{e}"),
            ConfigError::Energy(e) => write!(f, "{e}"),
            ConfigError::File(e) => write!(f, "{e}"),
            ConfigError::InFile { path, inner } => write!(f, "{inner} ({})", path.display()),
        }
    }
}

impl std::error::Error for ConfigError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ConfigError::UnknownKey { toml, .. } | ConfigError::Toml(toml) => Some(toml.as_ref()),
            ConfigError::Impossible(_) => None,
            ConfigError::Link(e) => Some(e),
            ConfigError::Map(e) => Some(e),
            ConfigError::Accel(e) => Some(e),
            ConfigError::Mem(e) => Some(e),
            ConfigError::Unit(e) => Some(e),
            ConfigError::Energy(e) => Some(e),
            ConfigError::File(e) => Some(e),
            ConfigError::InFile { inner, .. } => Some(inner.as_ref()),
        }
    }
}

macro_rules! wraps {
    ($($t:ty => $v:ident),* $(,)?) => {$(
        impl From<$t> for ConfigError {
            fn from(e: $t) -> ConfigError {
                ConfigError::$v(e)
            }
        }
    )*};
}
wraps!(SimError => Link, MapError => Map, AccelError => Accel, MemError => Mem,
       UnitError => Unit, EnergyError => Energy);
