//! Memory-system configuration: DRAM geometry, timing (in DRAM command-clock
//! cycles), address mapping, controller queues and energy figures. Every default
//! names its source in `../shared/docs/hardware-reference.md` (cited as HWREF §n).
//!
//! The DRAM command clock period is `clocks.dram_ps` of the main config (tCK).
//!
//! Row size. The paper's "8 KB row buffer" (DS17 §5.1) is a system view: simtrax
//! models one 8 KB row per 32-bit channel, while a physical GDDR5 device page is
//! 2-4 KB (HWREF §2.1). `geometry.columns` x the burst size is the row that one
//! ACT opens in one bank; the default is the paper's 8 KB.

use serde::{Deserialize, Serialize};

use super::MemError;
use crate::rtl::LinkCfg;

/// Banks, rows and the data bus of one channel, and the number of channels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeometryCfg {
    /// Independent channels: 16 x 32 bit [DS17 §5.1].
    pub channels: u32,
    /// Bank groups per channel: 4 [Micron4Gb, Elpida1Gb; HWREF §2.2].
    pub bank_groups: u32,
    /// Banks in each bank group: 4 (16 banks) [HWREF §2.2].
    pub banks_per_group: u32,
    /// Rows per bank. 2048 gives the paper's 4 GB with 16 channels x 16 banks x
    /// 8 KB rows [DS17 §5.1] (simtrax's gddr5_8ch.cfg has 8192, i.e. 16 GB).
    pub rows: u32,
    /// Column commands (bursts) per row: 256 x 32 B = the paper's 8 KB row.
    pub columns: u32,
    /// Data bus width of a channel in bits: 32 [DS17 §5.1].
    pub bus_bits: u32,
    /// Burst length: BL8 is the only GDDR5 burst [HWREF §2.2].
    pub burst_length: u32,
    /// Data transfers per command clock: 4 for GDDR5 (8 Gb/s per pin on a 2 GHz
    /// CK) [HWREF conventions].
    pub transfers_per_ck: u32,
    /// Bytes of one request (a cache line): 64 B [DS17 §2.1; HWREF §6]. A request
    /// larger than a burst takes several column commands to the same row.
    pub line_bytes: u32,
}

impl Default for GeometryCfg {
    fn default() -> Self {
        GeometryCfg {
            channels: 16,
            bank_groups: 4,
            banks_per_group: 4,
            rows: 2048,
            columns: 256,
            bus_bits: 32,
            burst_length: 8,
            transfers_per_ck: 4,
            line_bytes: 64,
        }
    }
}

impl GeometryCfg {
    pub fn banks(&self) -> u32 {
        self.bank_groups * self.banks_per_group
    }
    /// Bytes moved by one column command.
    pub fn burst_bytes(&self) -> u32 {
        self.bus_bits / 8 * self.burst_length
    }
    /// Data-bus cycles of one burst (BL8 on GDDR5: 2).
    pub fn burst_cycles(&self) -> u32 {
        self.burst_length / self.transfers_per_ck
    }
    /// Column commands per request.
    pub fn bursts_per_line(&self) -> u32 {
        self.line_bytes / self.burst_bytes()
    }
    /// Bytes one ACT opens in one bank.
    pub fn row_bytes(&self) -> u64 {
        self.columns as u64 * self.burst_bytes() as u64
    }
    pub fn lines_per_row(&self) -> u64 {
        self.row_bytes() / self.line_bytes as u64
    }
    /// Total capacity in bytes.
    pub fn capacity(&self) -> u64 {
        self.channels as u64 * self.banks() as u64 * self.rows as u64 * self.row_bytes()
    }
    /// Peak bytes per command-clock cycle of one channel.
    pub fn peak_bytes_per_cycle(&self) -> f64 {
        (self.bus_bits / 8 * self.transfers_per_ck) as f64
    }

    pub fn validate(&self) -> Result<(), MemError> {
        let pow2 = [
            ("channels", self.channels),
            ("bank_groups", self.bank_groups),
            ("banks_per_group", self.banks_per_group),
            ("rows", self.rows),
            ("columns", self.columns),
            ("line_bytes", self.line_bytes),
        ];
        for (k, v) in pow2 {
            if v == 0 {
                return Err(MemError::Config(format!(
                    "mem.geometry.{k} = 0: a memory needs at least one; set {k} >= 1"
                )));
            }
            if !v.is_power_of_two() {
                return Err(MemError::Config(format!(
                    "mem.geometry.{k} = {v} is not a power of two, which the address mapping needs (each field is a bit slice); use {}",
                    v.next_power_of_two()
                )));
            }
        }
        if self.bus_bits == 0 || !self.bus_bits.is_multiple_of(8) {
            return Err(MemError::Config(format!(
                "mem.geometry.bus_bits = {} must be a positive multiple of 8 (32 for a GDDR5 x32 channel)",
                self.bus_bits
            )));
        }
        if self.transfers_per_ck == 0 || self.burst_length == 0 {
            return Err(MemError::Config("mem.geometry: burst_length and transfers_per_ck must be >= 1 (GDDR5: BL 8, 4 transfers per CK)".into()));
        }
        if !self.burst_length.is_multiple_of(self.transfers_per_ck) {
            return Err(MemError::Config(format!(
                "mem.geometry.burst_length = {} is not a whole number of command cycles at {} transfers per CK; use a multiple of transfers_per_ck",
                self.burst_length, self.transfers_per_ck
            )));
        }
        let b = self.burst_bytes();
        if !b.is_power_of_two() {
            return Err(MemError::Config(format!(
                "mem.geometry: a burst of {b} B (bus_bits / 8 x burst_length) is not a power of two; the address mapping needs one"
            )));
        }
        if self.line_bytes < b || !self.line_bytes.is_multiple_of(b) {
            return Err(MemError::Config(format!(
                "mem.geometry.line_bytes = {} is not a whole number of {b} B bursts; set line_bytes to a multiple of {b}",
                self.line_bytes
            )));
        }
        if self.row_bytes() < self.line_bytes as u64 {
            return Err(MemError::Config(format!(
                "mem.geometry: a row of {} B (columns x burst) is smaller than a {} B line; raise columns",
                self.row_bytes(),
                self.line_bytes
            )));
        }
        if self.bursts_per_line() > 255 {
            return Err(MemError::Config(
                "mem.geometry.line_bytes: more than 255 bursts per line; lower line_bytes".into(),
            ));
        }
        if self.capacity().checked_mul(1).is_none() || self.capacity() > 1 << 48 {
            return Err(MemError::Config(
                "mem.geometry: capacity above 256 TB; check rows and columns".into(),
            ));
        }
        Ok(())
    }
}

/// DRAM timing constraints in command-clock cycles. Keys use the JEDEC/DRAMsim3
/// names so a DRAMsim3 `.ini` [timing] section can be copied over.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimingCfg {
    /// Read latency (RD command to first data).
    #[serde(rename = "CL")]
    pub cl: u32,
    /// Write latency (WR command to first data).
    #[serde(rename = "CWL")]
    pub cwl: u32,
    /// ACT to RD, same bank.
    #[serde(rename = "tRCDRD")]
    pub rcd_rd: u32,
    /// ACT to WR, same bank.
    #[serde(rename = "tRCDWR")]
    pub rcd_wr: u32,
    /// PRE to ACT, same bank.
    #[serde(rename = "tRP")]
    pub rp: u32,
    /// ACT to PRE, same bank.
    #[serde(rename = "tRAS")]
    pub ras: u32,
    /// ACT to ACT, same bank.
    #[serde(rename = "tRC")]
    pub rc: u32,
    /// Column to column, different bank group.
    #[serde(rename = "tCCD_S")]
    pub ccd_s: u32,
    /// Column to column, same bank group.
    #[serde(rename = "tCCD_L")]
    pub ccd_l: u32,
    /// ACT to ACT, different bank group.
    #[serde(rename = "tRRD_S")]
    pub rrd_s: u32,
    /// ACT to ACT, same bank group.
    #[serde(rename = "tRRD_L")]
    pub rrd_l: u32,
    /// At most four ACTs in any window of tFAW.
    #[serde(rename = "tFAW")]
    pub faw: u32,
    /// At most 32 ACTs in any window of t32AW (0: not enforced).
    #[serde(rename = "t32AW")]
    pub t32aw: u32,
    /// Write recovery: end of write data to PRE, same bank.
    #[serde(rename = "tWR")]
    pub wr: u32,
    /// End of write data to RD, different bank group.
    #[serde(rename = "tWTR_S")]
    pub wtr_s: u32,
    /// End of write data to RD, same bank group.
    #[serde(rename = "tWTR_L")]
    pub wtr_l: u32,
    /// RD to PRE, same bank.
    #[serde(rename = "tRTP")]
    pub rtp: u32,
    /// PRE to PRE, any bank (0: not enforced).
    #[serde(rename = "tPPD")]
    pub ppd: u32,
    /// Bus turnaround bubble added to read-to-write (as DRAMsim3's tRTRS).
    #[serde(rename = "tRTRS")]
    pub rtrs: u32,
    /// Average refresh interval (one all-bank REF per tREFI).
    #[serde(rename = "tREFI")]
    pub refi: u32,
    /// All-bank refresh cycle time.
    #[serde(rename = "tRFC")]
    pub rfc: u32,
}

impl Default for TimingCfg {
    /// The one consistent 8 Gb/s set at tCK = 0.5 ns (HWREF §2.3, derived from
    /// DRAMsim3 GDDR5_8Gb_x32 and Ramulator GDDR5_7000). tRTP 3 and tRRD 10 are
    /// the conservative ends of §2.3's ranges; tPPD 2 is Ramulator's (§2.1 D);
    /// tRFC 74 is DRAMsim3's (no GDDR5 datasheet value was found, §2.3); tREFI
    /// 3900 = 1.95 us [Micron4Gb]; tRTRS 1 is DRAMsim3's.
    fn default() -> Self {
        TimingCfg {
            cl: 24,
            cwl: 7,
            rcd_rd: 24,
            rcd_wr: 20,
            rp: 24,
            ras: 56,
            rc: 80,
            ccd_s: 2,
            ccd_l: 3,
            rrd_s: 10,
            rrd_l: 10,
            faw: 40,
            t32aw: 360,
            wr: 24,
            wtr_s: 10,
            wtr_l: 10,
            rtp: 3,
            ppd: 2,
            rtrs: 1,
            refi: 3900,
            rfc: 74,
        }
    }
}

impl TimingCfg {
    pub fn validate(&self, g: &GeometryCfg) -> Result<(), MemError> {
        let pos = [
            ("CL", self.cl),
            ("CWL", self.cwl),
            ("tRCDRD", self.rcd_rd),
            ("tRCDWR", self.rcd_wr),
            ("tRP", self.rp),
            ("tRAS", self.ras),
            ("tRC", self.rc),
            ("tCCD_S", self.ccd_s),
            ("tCCD_L", self.ccd_l),
            ("tRRD_S", self.rrd_s),
            ("tRRD_L", self.rrd_l),
            ("tRFC", self.rfc),
            ("tREFI", self.refi),
        ];
        for (k, v) in pos {
            if v == 0 {
                return Err(MemError::Config(format!(
                    "mem.timing.{k} = 0: every DRAM command takes at least one cycle; give the datasheet value in DRAM clock cycles"
                )));
            }
        }
        if self.rc < self.ras + self.rp {
            return Err(MemError::Config(format!(
                "mem.timing: tRC = {} < tRAS + tRP = {} + {} = {}; a bank cannot be activated again before it is precharged, so set tRC >= {}",
                self.rc,
                self.ras,
                self.rp,
                self.ras + self.rp,
                self.ras + self.rp
            )));
        }
        if self.ccd_l < self.ccd_s {
            return Err(MemError::Config(format!(
                "mem.timing: tCCD_L = {} < tCCD_S = {}; the same bank group is never faster than another, so set tCCD_L >= tCCD_S",
                self.ccd_l, self.ccd_s
            )));
        }
        if self.rrd_l < self.rrd_s {
            return Err(MemError::Config(format!(
                "mem.timing: tRRD_L = {} < tRRD_S = {}; set tRRD_L >= tRRD_S",
                self.rrd_l, self.rrd_s
            )));
        }
        if self.wtr_l < self.wtr_s {
            return Err(MemError::Config(format!(
                "mem.timing: tWTR_L = {} < tWTR_S = {}; set tWTR_L >= tWTR_S",
                self.wtr_l, self.wtr_s
            )));
        }
        if self.faw != 0 && self.faw < self.rrd_s {
            return Err(MemError::Config(format!(
                "mem.timing: tFAW = {} < tRRD_S = {}; four activates cannot fit in less than one activate gap; set tFAW >= tRRD_S",
                self.faw, self.rrd_s
            )));
        }
        if self.refi <= self.rfc {
            return Err(MemError::Config(format!(
                "mem.timing: tREFI = {} <= tRFC = {}; the DRAM would refresh all the time; tREFI must exceed tRFC",
                self.refi, self.rfc
            )));
        }
        if self.cl + g.burst_cycles() + self.rtrs < self.cwl {
            return Err(MemError::Config(format!(
                "mem.timing: CWL = {} exceeds CL + burst + tRTRS; check the write latency",
                self.cwl
            )));
        }
        Ok(())
    }
}

/// How a channel controller queues and schedules.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CtrlPolicy {
    /// Read and write queues scheduled FR-FCFS with write drain between
    /// watermarks (`mem::ctrl`; the chip's `mem_ctrl` unit).
    Frfcfs,
    /// DRAMsim3's controller (`mem::dramsim3`): transaction queues feeding
    /// per-bank command queues served round robin, writes acknowledged when the
    /// write buffer takes them. Trace replay only (`dualstream dram`).
    Dramsim3,
}

/// Controller queues and policies.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CtrlCfg {
    /// `frfcfs` (the default) or `dramsim3`.
    pub policy: CtrlPolicy,
    /// Read queue entries per channel: 64, GPGPU-Sim's FR-FCFS scheduler queue
    /// (HWREF §5.2). `dramsim3`: the read transaction queue (its
    /// `trans_queue_size`, 32).
    pub read_queue: u32,
    /// Write queue entries per channel: 96, USIMM's GDDR5 configs (HWREF §5.2).
    /// `dramsim3`: the write buffer (`trans_queue_size`, 32).
    pub write_queue: u32,
    /// Start draining writes at this many queued writes: 40 (USIMM, HWREF §5.2).
    /// `dramsim3`: a full write buffer (= write_queue).
    pub write_high: u32,
    /// Stop draining at this many: 20 (USIMM, HWREF §5.2). `dramsim3`: also drain
    /// when more than this many writes wait and every command queue is empty
    /// (DRAMsim3's constant 8); a drain moves the writes present at its start.
    pub write_low: u32,
    /// `dramsim3` only: commands per bank queue (its `cmd_queue_size`, 8, with
    /// `queue_structure = PER_BANK`).
    pub cmd_queue: u32,
    /// Completed requests waiting for the response port, including reads whose
    /// data is on the bus. A request's last column command issues only when a slot
    /// is free. 32 covers CL + burst at full rate (13 lines) twice; no source.
    /// `dramsim3` has no such limit (its return queue is unbounded).
    pub resp_buffer: u32,
    /// Request link into a channel controller.
    pub req_link: LinkCfg,
    /// Response link out of a channel controller.
    pub resp_link: LinkCfg,
}

impl Default for CtrlCfg {
    fn default() -> Self {
        CtrlCfg {
            policy: CtrlPolicy::Frfcfs,
            read_queue: 64,
            write_queue: 96,
            write_high: 40,
            write_low: 20,
            cmd_queue: 8,
            resp_buffer: 32,
            req_link: LinkCfg::default(),
            resp_link: LinkCfg::default(),
        }
    }
}

impl CtrlCfg {
    pub fn validate(&self) -> Result<(), MemError> {
        if self.read_queue == 0 || self.write_queue == 0 || self.resp_buffer == 0 {
            return Err(MemError::Config(
                "mem.ctrl: read_queue, write_queue and resp_buffer must hold at least one entry"
                    .into(),
            ));
        }
        if self.read_queue > 4096 || self.write_queue > 4096 || self.resp_buffer > 4096 {
            return Err(MemError::Config(
                "mem.ctrl: queues above 4096 entries are not a buildable FR-FCFS CAM; lower them"
                    .into(),
            ));
        }
        if self.policy == CtrlPolicy::Dramsim3 {
            if self.cmd_queue == 0 || self.cmd_queue > 4096 {
                return Err(MemError::Config(format!(
                    "mem.ctrl.cmd_queue = {}: a bank's command queue needs 1 to 4096 entries (DRAMsim3: 8)",
                    self.cmd_queue
                )));
            }
            if self.write_high != self.write_queue {
                return Err(MemError::Config(format!(
                    "mem.ctrl: policy dramsim3 drains writes when the write buffer is full, so write_high = {} must equal write_queue = {}",
                    self.write_high, self.write_queue
                )));
            }
        }
        if self.write_low >= self.write_high || self.write_high > self.write_queue {
            return Err(MemError::Config(format!(
                "mem.ctrl: write watermarks need write_low < write_high <= write_queue (now {} / {} / {}); e.g. 20 / 40 / 96",
                self.write_low, self.write_high, self.write_queue
            )));
        }
        self.req_link.validate("mem.ctrl.req_link")?;
        self.resp_link.validate("mem.ctrl.resp_link")?;
        Ok(())
    }
}

/// Currents (mA), voltage and device count for the Micron power equations
/// (HWREF §3.2). Energy per channel is per-device energy x `devices_per_channel`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnergyCfg {
    /// Name printed in every report ("paper", "physical", "dramsim3", or yours).
    pub preset: String,
    /// Supply voltage (V).
    pub vdd: f64,
    /// Activate-precharge current (IDD0, mA).
    pub idd0: f64,
    /// Precharge standby current (IDD2N, mA).
    pub idd2n: f64,
    /// Active standby current (IDD3N, mA).
    pub idd3n: f64,
    /// Burst read current (IDD4R, mA).
    pub idd4r: f64,
    /// Burst write current (IDD4W, mA).
    pub idd4w: f64,
    /// All-bank refresh current (IDD5 / IDD5AB).
    pub idd5: f64,
    /// Read I/O (DQ) power per device while its data is on the bus, mW.
    pub read_io_mw: f64,
    /// Devices whose energy is charged per channel.
    pub devices_per_channel: f64,
}

impl Default for EnergyCfg {
    fn default() -> Self {
        EnergyCfg::paper()
    }
}

impl EnergyCfg {
    /// simtrax's USIMM set (`1Gb_x16_amd2GHz.vi`, HWREF §3.1 A) with simtrax's
    /// `chips_per_rank = 16` applied to every channel, as the paper's group did:
    /// it reproduces the magnitude of DS17 Table 2 (25-39 nJ per 64 B line at the
    /// paper's bandwidths, HWREF §3.4). Read I/O 3.2 mW x 10 per chip (USIMM).
    pub fn paper() -> Self {
        EnergyCfg {
            preset: "paper".into(),
            vdd: 1.5,
            idd0: 120.0,
            idd2n: 70.0,
            idd3n: 67.0,
            idd4r: 250.0,
            idd4w: 250.0,
            idd5: 260.0,
            read_io_mw: 32.0,
            devices_per_channel: 16.0,
        }
    }
    /// The same device currents with the real number of x16 devices on a channel
    /// (2 for 32 bits): about 8x less than `paper` (HWREF §3.4).
    pub fn physical(g: &GeometryCfg) -> Self {
        EnergyCfg {
            preset: "physical".into(),
            devices_per_channel: (g.bus_bits as f64 / 16.0).max(1.0),
            ..EnergyCfg::paper()
        }
    }
    /// DRAMsim3's GDDR5_8Gb_x32.ini currents, one x32 device per 32 bits of bus
    /// (HWREF §3.1); DRAMsim3 does not model I/O power.
    pub fn dramsim3(g: &GeometryCfg) -> Self {
        EnergyCfg {
            preset: "dramsim3".into(),
            vdd: 1.5,
            idd0: 71.0,
            idd2n: 60.0,
            idd3n: 61.0,
            idd4r: 248.0,
            idd4w: 231.0,
            idd5: 286.0,
            read_io_mw: 0.0,
            devices_per_channel: (g.bus_bits as f64 / 32.0).max(1.0),
        }
    }
    pub const PRESETS: &'static [&'static str] = &["paper", "physical", "dramsim3"];
    pub fn by_name(name: &str, g: &GeometryCfg) -> Result<Self, MemError> {
        match name {
            "paper" => Ok(EnergyCfg::paper()),
            "physical" => Ok(EnergyCfg::physical(g)),
            "dramsim3" => Ok(EnergyCfg::dramsim3(g)),
            _ => Err(MemError::Unknown(format!(
                "unknown energy preset '{name}'; available: {}",
                EnergyCfg::PRESETS.join(", ")
            ))),
        }
    }
    pub fn validate(&self) -> Result<(), MemError> {
        let v = [
            ("vdd", self.vdd),
            ("idd0", self.idd0),
            ("idd2n", self.idd2n),
            ("idd3n", self.idd3n),
            ("idd4r", self.idd4r),
            ("idd4w", self.idd4w),
            ("idd5", self.idd5),
            ("read_io_mw", self.read_io_mw),
            ("devices_per_channel", self.devices_per_channel),
        ];
        for (k, x) in v {
            if !x.is_finite() || x < 0.0 {
                return Err(MemError::Config(format!(
                    "mem.energy.{k} = {x} must be a finite, non-negative number"
                )));
            }
        }
        if self.idd4r < self.idd3n || self.idd4w < self.idd3n || self.idd5 < self.idd3n {
            return Err(MemError::Config("mem.energy: IDD4R, IDD4W and IDD5 must be at least IDD3N (they are measured on top of active standby)".into()));
        }
        Ok(())
    }
}

/// The whole memory system.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MemCfg {
    pub geometry: GeometryCfg,
    pub timing: TimingCfg,
    /// Address fields from most to least significant, above the line offset:
    /// `row`, `bank` (bank within its group), `bankgroup`, `channel`, `column`
    /// (line within the row), separated by `:`; every field exactly once.
    ///
    /// Default `row:bank:channel:column:bankgroup`: consecutive 64 B lines rotate
    /// over the four bank groups (so a stream pays tCCD_S, not tCCD_L: with two
    /// BL8 bursts per line, one bank group alone reaches only 2/3 of the bus),
    /// and each channel holds 32 KB contiguous = the same row in one bank of each
    /// group. A 64 KB treelet is 8 whole rows on 2 channels; 8 KB of ray buckets
    /// are row hits in 4 open rows. `row:bank:channel:column` is simtrax's
    /// mapping 1 (one 8 KB row per 8 KB of address, HWREF §5.1).
    pub mapping: String,
    pub ctrl: CtrlCfg,
    pub energy: EnergyCfg,
}

impl Default for MemCfg {
    fn default() -> Self {
        MemCfg {
            geometry: GeometryCfg::default(),
            timing: TimingCfg::default(),
            mapping: "row:bank:channel:column:bankgroup".into(),
            ctrl: CtrlCfg::default(),
            energy: EnergyCfg::paper(),
        }
    }
}

/// Timing and geometry presets (`dualstream dram --preset`).
pub const PRESETS: &[&str] = &["paper", "dramsim3-gddr5"];

/// The DRAM command clock period of the DRAMsim3 preset: tCK = 0.667 ns.
pub const DRAMSIM3_TCK_PS: u64 = 667;

impl MemCfg {
    /// The paper's memory: 16 x 32-bit GDDR5 channels at 8 Gb/s (the default).
    pub fn paper() -> Self {
        MemCfg::default()
    }

    /// Mirrors DRAMsim3's `configs/GDDR5_8Gb_x32.ini` run by DRAMsim3 (HWREF §2.1
    /// B): one 128-bit channel (4 x32 devices), 16384 rows, 128 columns of BL8
    /// (128 B per column command, 16 KB row), mapping `rochrababgco`, and
    /// DRAMsim3's controller (`policy = "dramsim3"`, its default queues:
    /// `trans_queue_size = 32`, `cmd_queue_size = 8`, `PER_BANK`). Use with
    /// `clocks.dram_ps = 667`.
    ///
    /// As DRAMsim3 reads the ini: `bankgroup_enable = false` folds the 4 x 4
    /// banks into one group of 16, and with one group DRAMsim3 applies tCCD_S,
    /// tRRD_S and tWTR_S between all banks, so tCCD_L = tCCD_S = 2 here (the ini's
    /// tCCD_L = 3 is never used); tRTP comes from key `tRTP` (default 5, the
    /// ini's tRTP_L/S are ignored) and tRC = tRAS + tRP.
    pub fn dramsim3_gddr5() -> Self {
        let geometry = GeometryCfg {
            channels: 1,
            bank_groups: 1,
            banks_per_group: 16,
            rows: 16384,
            columns: 128,
            bus_bits: 128,
            burst_length: 8,
            transfers_per_ck: 4,
            line_bytes: 128,
        };
        let energy = EnergyCfg::dramsim3(&geometry);
        MemCfg {
            geometry,
            timing: TimingCfg {
                cl: 24,
                cwl: 7,
                rcd_rd: 24,
                rcd_wr: 20,
                rp: 24,
                ras: 56,
                rc: 80,
                ccd_s: 2,
                ccd_l: 2,
                rrd_s: 10,
                rrd_l: 10,
                faw: 40,
                t32aw: 360,
                wr: 24,
                wtr_s: 10,
                wtr_l: 10,
                rtp: 5,
                ppd: 5,
                rtrs: 1,
                refi: 3800,
                rfc: 74,
            },
            mapping: "row:channel:bank:bankgroup:column".into(),
            ctrl: CtrlCfg {
                policy: CtrlPolicy::Dramsim3,
                read_queue: 32,
                write_queue: 32,
                write_high: 32,
                write_low: 8,
                cmd_queue: 8,
                ..CtrlCfg::default()
            },
            energy,
        }
    }

    /// Returns the preset and its DRAM clock period in ps.
    pub fn preset(name: &str) -> Result<(MemCfg, u64), MemError> {
        match name {
            "paper" => Ok((MemCfg::paper(), 500)),
            "dramsim3-gddr5" => Ok((MemCfg::dramsim3_gddr5(), DRAMSIM3_TCK_PS)),
            _ => Err(MemError::Unknown(format!(
                "unknown memory preset '{name}'; available: {}",
                PRESETS.join(", ")
            ))),
        }
    }

    pub fn validate(&self) -> Result<(), MemError> {
        self.geometry.validate()?;
        self.timing.validate(&self.geometry)?;
        self.ctrl.validate()?;
        self.energy.validate()?;
        super::map::AddrMap::new(&self.geometry, &self.mapping)?;
        if self.ctrl.resp_link.delay > self.timing.cwl {
            return Err(MemError::Config(format!(
                "mem.ctrl.resp_link.delay = {} exceeds CWL = {}; the response register would be loaded before the data ends, so use a delay <= CWL",
                self.ctrl.resp_link.delay, self.timing.cwl
            )));
        }
        if self.ctrl.policy == CtrlPolicy::Dramsim3 && self.geometry.bursts_per_line() != 1 {
            return Err(MemError::Config(format!(
                "mem.ctrl.policy = \"dramsim3\": DRAMsim3 moves one burst per request, but a {} B line is {} bursts of {} B; set mem.geometry.line_bytes = {} or use policy \"frfcfs\"",
                self.geometry.line_bytes,
                self.geometry.bursts_per_line(),
                self.geometry.burst_bytes(),
                self.geometry.burst_bytes()
            )));
        }
        if self.geometry.banks() > 64 {
            return Err(MemError::Config(format!(
                "mem.geometry: {} banks per channel; at most 64 are supported (bank masks)",
                self.geometry.banks()
            )));
        }
        Ok(())
    }
}
