//! The L2's configuration: size, ways, banks, MSHRs, latencies and memory lanes.

use serde::{Deserialize, Serialize};

use crate::units::stream_scheduler::MAX_STREAM_LANES;

/// The L2 cache (`units/l2.rs`): everything that is not a stream goes through it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct L2Cfg {
    /// `false`: the hit record updater and the TMs' global-memory ports go
    /// straight to memory ports (to measure the L2's effect).
    pub enabled: bool,
    /// 512 KB [DS17 Table 1].
    pub bytes: u32,
    /// 32 banks [DS17 Table 1], one access per bank per cycle.
    pub banks: u32,
    /// 64 B, the DRAM line of the data contract.
    pub line_bytes: u32,
    /// Assumption: 8 ways (a common L2 associativity; 32 sets per bank at the
    /// defaults). The hit records and path states are large arrays whose lines are
    /// touched once per pass each, so associativity matters little; 8 keeps the
    /// tag compare small.
    pub ways: u32,
    /// Cycles from acceptance to the answer visible at the client (response link
    /// included). Assumption: 10 (a 512 KB banked SRAM at 1 GHz plus the crossbar).
    pub hit_latency: u32,
    /// Miss registers. Assumption: 64.
    pub mshrs: u32,
    /// Accesses merged into one miss register. Assumption: 8.
    pub targets: u32,
    /// Writeback buffer entries (plus one reserved per MSHR). Assumption: 16.
    pub writebacks: u32,
    /// Requests per client accepted and not yet answered. Assumption: 64.
    pub port_queue: u32,
    /// Lines per cycle between the L2 and the memory (fills and writebacks, the
    /// end-of-run flush too): one memory port (lane) each, a line always on lane
    /// `line index mod lanes` (docs/chip.md "L2"). 4 (256 GB/s at 1 GHz): half
    /// the 8 lines per cycle of the paper's 512 GB/s GDDR5 (§5.1), the other half
    /// left to the two streams; one lane (64 GB/s) bounded the shading pass and
    /// made every end-of-run flush write back one line per cycle. 1 to 16.
    pub mem_lines_per_cycle: u32,
    /// Bank index = XOR of the line index's bank-wide bit fields (true) or the
    /// line index modulo the banks (false). Assumption: hashed, as banked GPU L2s
    /// do, so strided line sequences spread over the banks (docs/chip.md, "L2").
    pub bank_hash: bool,
    /// A bank serving a read of a line serves other clients' reads of the same
    /// line in that cycle too (one array read, the data multicast). Assumption:
    /// on; shading's clients read the same triangles and materials, so many
    /// bank conflicts are same-line reads (docs/chip.md, "L2").
    pub combine_reads: bool,
}

impl Default for L2Cfg {
    fn default() -> Self {
        L2Cfg {
            enabled: true,
            bytes: 512 << 10,
            banks: 32,
            line_bytes: 64,
            ways: 8,
            hit_latency: 10,
            mshrs: 64,
            targets: 8,
            writebacks: 16,
            port_queue: 64,
            mem_lines_per_cycle: 4,
            bank_hash: true,
            combine_reads: true,
        }
    }
}

impl L2Cfg {
    /// Checks the cache's geometry and sizes; `link_delay` is part of `hit_latency`.
    pub fn validate(&self, link_delay: u32) -> Result<(), crate::units::UnitError> {
        if self.line_bytes != 64 {
            return Err(crate::units::UnitError::Invalid(format!(
                "chip.l2.line_bytes = {}: the data contract's DRAM line is 64 B; give 64",
                self.line_bytes
            )));
        }
        if self.banks == 0 || self.ways == 0 {
            return Err(crate::units::UnitError::Invalid(
                "chip.l2.banks and chip.l2.ways must be at least 1".into(),
            ));
        }
        let unit = self.banks as u64 * self.ways as u64 * self.line_bytes as u64;
        if self.bytes == 0 || !(self.bytes as u64).is_multiple_of(unit) {
            return Err(crate::units::UnitError::Invalid(format!(
                "chip.l2.bytes = {} is not a positive multiple of banks x ways x line_bytes = {} x {} x {} = {unit}; every bank needs whole sets",
                self.bytes, self.banks, self.ways, self.line_bytes
            )));
        }
        if self.hit_latency <= link_delay {
            return Err(crate::units::UnitError::Invalid(format!(
                "chip.l2.hit_latency = {} must exceed the response link delay ({link_delay}, chip.links.delay), which is part of it",
                self.hit_latency
            )));
        }
        for (name, v) in [
            ("mshrs", self.mshrs),
            ("targets", self.targets),
            ("writebacks", self.writebacks),
            ("port_queue", self.port_queue),
        ] {
            if v == 0 {
                return Err(crate::units::UnitError::Invalid(format!(
                    "chip.l2.{name} = 0: give at least 1"
                )));
            }
        }
        if self.mem_lines_per_cycle == 0 || self.mem_lines_per_cycle > MAX_STREAM_LANES {
            return Err(crate::units::UnitError::Invalid(format!(
                "chip.l2.mem_lines_per_cycle = {}: give 1 to {MAX_STREAM_LANES} lines per cycle (one memory port each; 8 lines per cycle is already the 512 GB/s GDDR5 peak)",
                self.mem_lines_per_cycle
            )));
        }
        Ok(())
    }
}
