//! The header every JSON output carries (`render --stats`, `report --json`,
//! `bench ... --json`): what made it — the tool and its revision, the command,
//! the machine, the run's parameters and the full configuration — so a file
//! found later says what it measured. Everything but `wall_s` and `machine` is
//! a function of the inputs: two runs of one command give equal headers apart
//! from those two.

use serde::Serialize;

use crate::config::Config;

/// The provenance of one output file.
#[derive(Clone, Debug, Serialize)]
pub struct RunHeader {
    pub tool: &'static str,
    pub version: &'static str,
    /// The git revision of the source checkout the binary was built in
    /// (`target/` inside it), with `-dirty` if it has uncommitted changes;
    /// `None` for an installed binary.
    pub git_revision: Option<String>,
    /// The command line, program name first.
    pub command: Vec<String>,
    pub run: RunParams,
    /// Wall time of the whole command, seconds.
    pub wall_s: f64,
    pub machine: Machine,
    /// FNV-1a of the configuration's TOML (`dualstream config`), hex: equal
    /// hashes, equal configurations.
    pub config_hash: String,
    /// The configuration in force (file, defaults and command-line overrides).
    pub config: Config,
}

/// The run's parameters; `None` where a command has none (a report over
/// several scenes has no single scene).
#[derive(Clone, Debug, Default, Serialize)]
pub struct RunParams {
    pub scene: Option<String>,
    /// `[width, height]`, pixels.
    pub resolution: Option<[u32; 2]>,
    pub mode: Option<String>,
    pub seed: Option<u64>,
    /// Hit points per path.
    pub bounces: Option<u32>,
    /// Paths per pixel (`render --spp`).
    pub spp: Option<u32>,
    /// `--threads` as given (`auto` or N).
    pub threads: Option<String>,
}

/// Where it ran.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    pub host: Option<String>,
    pub os: &'static str,
    pub arch: &'static str,
    /// Logical cores available to the process.
    pub cores: usize,
    pub cpu: Option<String>,
}

impl Machine {
    pub fn this() -> Machine {
        let read = |p: &str| std::fs::read_to_string(p).ok();
        let cpu = read("/proc/cpuinfo").and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        });
        Machine {
            host: read("/proc/sys/kernel/hostname").map(|h| h.trim().to_string()),
            os: std::env::consts::OS,
            arch: std::env::consts::ARCH,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            cpu,
        }
    }
}

impl RunHeader {
    /// The header for a command that ran `wall_s` seconds with `config`.
    pub fn new(config: &Config, run: RunParams, wall_s: f64) -> RunHeader {
        RunHeader {
            tool: env!("CARGO_PKG_NAME"),
            version: env!("CARGO_PKG_VERSION"),
            git_revision: git_revision(),
            command: std::env::args().collect(),
            run,
            wall_s,
            machine: Machine::this(),
            config_hash: format!("{:016x}", crate::util::fnv1a(config.to_toml().as_bytes())),
            config: config.clone(),
        }
    }
}

/// An object with `header` as its first key and the object's own keys after
/// it, in their order (a reader of the files from before finds them).
#[derive(Serialize)]
pub struct Headed<'a, T: Serialize> {
    pub header: &'a RunHeader,
    #[serde(flatten)]
    pub body: &'a T,
}

/// A list (a report's rows, a benchmark's runs) under `key`, after `header`.
pub struct HeadedList<'a, T: Serialize> {
    pub header: &'a RunHeader,
    pub key: &'static str,
    pub body: &'a T,
}

impl<T: Serialize> Serialize for HeadedList<'_, T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = s.serialize_map(Some(2))?;
        m.serialize_entry("header", self.header)?;
        m.serialize_entry(self.key, self.body)?;
        m.end()
    }
}

/// The revision of the checkout holding the running binary: the nearest
/// directory above it with a `Cargo.toml` of this package and a `.git`.
fn git_revision() -> Option<String> {
    let exe = std::env::current_exe().ok()?;
    let root = exe.ancestors().skip(1).find(|d| {
        d.join(".git").exists()
            && std::fs::read_to_string(d.join("Cargo.toml"))
                .is_ok_and(|t| t.contains(concat!("name = \"", env!("CARGO_PKG_NAME"), "\"")))
    })?;
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .arg("-C")
            .arg(root)
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let rev = git(&["rev-parse", "HEAD"])?;
    let dirty =
        git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
    Some(if dirty { format!("{rev}-dirty") } else { rev })
}
