//! On-chip and compute energy at 65 nm, per access and per operation, each constant
//! named with its source (`../shared/docs/hardware-reference.md` §4). The paper's
//! figures exclude leakage, so the totals do too; with `energy.leakage = true` the
//! SRAMs' leakage over the render time is reported as a separate figure.
//!
//! What is charged:
//! - compute: every box test (its exact op count, `geom::RAY_BOX_OPS`), every
//!   triangle test (the datapath up to the deferred division for every test; the
//!   three divides and two compares of the hit path only on hits), three reciprocals
//!   per inverse direction (the divider), and the TP instructions by class;
//! - on-chip memory: per access of each SRAM (simtrax's per-access table, as the
//!   paper's group charged it), three register-file accesses and one I-cache access
//!   per TP instruction, one local-store access per TP load or store.

use serde::{Deserialize, Serialize};

use crate::geom::{RAY_BOX_OPS, RAY_TRI_OPS, RAY_TRI_REJECT_OPS};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnergyCfg {
    /// FP add/sub, pJ (simtrax `sim/ReadConfig.cc` default).
    pub fp_add_pj: f64,
    /// FP multiply, pJ (same).
    pub fp_mul_pj: f64,
    /// FP inverse / divide, pJ (same).
    pub fp_div_pj: f64,
    /// FP min/max and compare, pJ (same).
    pub fp_cmp_pj: f64,
    /// Integer add, branch, bitwise, pJ (same).
    pub int_pj: f64,
    /// Integer multiply, pJ (same).
    pub int_mul_pj: f64,
    /// L1, 16 KB, 8 banks, 64 B lines, nJ per access (simtrax `dcacheparams.txt`).
    pub l1_nj: f64,
    /// L2, 512 KB, 32 banks, nJ per access (same table).
    pub l2_nj: f64,
    /// Scene buffer, 4 MB, 64 banks, nJ per access (same table).
    pub scene_buffer_nj: f64,
    /// Ray staging buffer half, 2 KB, 1 bank, nJ per access (same table).
    pub staging_nj: f64,
    /// TP local store (512 B), pJ per access (simtrax `sim/LocalStore.cc`).
    pub local_store_pj: f64,
    /// Register file, pJ per access (simtrax `sim/SimpleRegisterFile.cc`).
    pub rf_pj: f64,
    /// Register-file accesses charged per instruction: 2 reads, 1 write (simtrax `sim/main.cc`).
    pub rf_per_instruction: f64,
    /// I-cache 4 KB, 16 banks (one per 16 threads), pJ per fetch (simtrax `icacheparams.txt`).
    pub icache_pj: f64,
    /// Report the SRAMs' leakage over the render time (cycle mode) as a separate
    /// figure, never in the totals (the paper's figures exclude it). Off by default.
    pub leakage: bool,
    /// Leakage per bank, mW, CACTI 7 at 65 nm, itrs-hp cells at 360 K ("high; treat
    /// with care", hardware-reference §4.2): L1 16 KB as 8-bank RAM.
    pub l1_leak_mw_per_bank: f64,
    /// L2 512 KB, per bank (the 16-bank cache figure, applied to each of `chip.l2.banks`).
    pub l2_leak_mw_per_bank: f64,
    /// Scene buffer 4 MB, per bank (the 64-bank RAM figure, applied to each of `chip.scene_buffer.banks`).
    pub scene_buffer_leak_mw_per_bank: f64,
    /// Ray staging buffer (2 x 2 KB RAM, 2 banks), per bank.
    pub staging_leak_mw_per_bank: f64,
    /// TP scratchpad 512 B, per TP.
    pub scratchpad_leak_mw: f64,
}

impl Default for EnergyCfg {
    fn default() -> Self {
        EnergyCfg {
            fp_add_pj: 7.4,
            fp_mul_pj: 14.2,
            fp_div_pj: 156.3,
            fp_cmp_pj: 0.536,
            int_pj: 0.572,
            int_mul_pj: 17.7,
            l1_nj: 0.2042,
            l2_nj: 0.6830,
            scene_buffer_nj: 1.656,
            staging_nj: 0.0626,
            local_store_pj: 6.93,
            rf_pj: 7.90,
            rf_per_instruction: 3.0,
            icache_pj: 13.5,
            leakage: false,
            l1_leak_mw_per_bank: 10.2,
            l2_leak_mw_per_bank: 68.0,
            scene_buffer_leak_mw_per_bank: 150.0,
            staging_leak_mw_per_bank: 4.0,
            scratchpad_leak_mw: 0.8,
        }
    }
}

/// An `energy.*` constant that is negative or not a number.
#[derive(Debug)]
pub struct EnergyError {
    pub key: &'static str,
    pub value: f64,
}

impl std::fmt::Display for EnergyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (k, v) = (self.key, self.value);
        write!(f, "energy.{k} = {v} must be a non-negative number")
    }
}

impl std::error::Error for EnergyError {}

impl EnergyCfg {
    pub fn validate(&self) -> Result<(), EnergyError> {
        let all = [
            ("fp_add_pj", self.fp_add_pj),
            ("fp_mul_pj", self.fp_mul_pj),
            ("fp_div_pj", self.fp_div_pj),
            ("fp_cmp_pj", self.fp_cmp_pj),
            ("int_pj", self.int_pj),
            ("int_mul_pj", self.int_mul_pj),
            ("l1_nj", self.l1_nj),
            ("l2_nj", self.l2_nj),
            ("scene_buffer_nj", self.scene_buffer_nj),
            ("staging_nj", self.staging_nj),
            ("local_store_pj", self.local_store_pj),
            ("rf_pj", self.rf_pj),
            ("rf_per_instruction", self.rf_per_instruction),
            ("icache_pj", self.icache_pj),
            ("l1_leak_mw_per_bank", self.l1_leak_mw_per_bank),
            ("l2_leak_mw_per_bank", self.l2_leak_mw_per_bank),
            (
                "scene_buffer_leak_mw_per_bank",
                self.scene_buffer_leak_mw_per_bank,
            ),
            ("staging_leak_mw_per_bank", self.staging_leak_mw_per_bank),
            ("scratchpad_leak_mw", self.scratchpad_leak_mw),
        ];
        for (k, v) in all {
            if !(v.is_finite() && v >= 0.0) {
                return Err(EnergyError { key: k, value: v });
            }
        }
        Ok(())
    }

    fn ops_pj(&self, o: crate::geom::OpCount) -> f64 {
        o.add as f64 * self.fp_add_pj
            + o.mul as f64 * self.fp_mul_pj
            + (o.cmp + o.minmax) as f64 * self.fp_cmp_pj
            + o.div as f64 * self.fp_div_pj
    }
}

/// TP instructions by functional-unit class (the TP cost table's classes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Instructions {
    pub int: u64,
    pub int_mul: u64,
    pub fp_add: u64,
    pub fp_mul: u64,
    pub fp_cmp: u64,
    pub branch: u64,
    pub load: u64,
    pub store: u64,
}

impl Instructions {
    /// Adds `n` runs of a TP state's instruction mix.
    pub fn add_state(&mut self, c: &crate::units::tm::StateCost, n: u64) {
        self.int += c.int as u64 * n;
        self.int_mul += c.int_mul as u64 * n;
        self.fp_add += c.fp_add as u64 * n;
        self.fp_mul += c.fp_mul as u64 * n;
        self.fp_cmp += c.fp_cmp as u64 * n;
        self.branch += c.branch as u64 * n;
        self.load += c.load as u64 * n;
        self.store += c.store as u64 * n;
    }
    pub fn total(&self) -> u64 {
        self.int
            + self.int_mul
            + self.fp_add
            + self.fp_mul
            + self.fp_cmp
            + self.branch
            + self.load
            + self.store
    }
}

/// What happened on the chip, in events.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Activity {
    pub box_tests: u64,
    pub tri_tests: u64,
    pub tri_hits: u64,
    pub inverse_dirs: u64,
    pub instructions: Instructions,
    pub l1_accesses: u64,
    pub l2_accesses: u64,
    pub scene_buffer_accesses: u64,
    pub staging_accesses: u64,
    pub local_store_accesses: u64,
}

/// Actions of the TPs' shading states, each named as its cost in `tm.costs`
/// (`WaveCycles::shade_uses`), for the energy model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ShadeUses {
    pub shade_load: u64,
    pub shade: u64,
    pub shade_emit: u64,
    pub shade_store: u64,
}

impl ShadeUses {
    /// Each state's actions from `uses_of(its name in tm.costs)`.
    pub fn of(uses_of: impl Fn(&str) -> u64) -> ShadeUses {
        ShadeUses {
            shade_load: uses_of("shade_load"),
            shade: uses_of("shade"),
            shade_emit: uses_of("shade_emit"),
            shade_store: uses_of("shade_store"),
        }
    }

    /// The actions between two snapshots (`self` the later).
    pub fn since(&self, b: &ShadeUses) -> ShadeUses {
        ShadeUses {
            shade_load: self.shade_load - b.shade_load,
            shade: self.shade - b.shade,
            shade_emit: self.shade_emit - b.shade_emit,
            shade_store: self.shade_store - b.shade_store,
        }
    }
}

/// The TP instructions of the shading pass on the chip: each shading state's
/// instruction mix (`tm.costs`) times its actions.
pub fn shading_instructions(costs: &crate::units::tm::TpCosts, uses: ShadeUses) -> Instructions {
    let mut i = Instructions::default();
    let states = [
        (&costs.shade_load, uses.shade_load),
        (&costs.shade, uses.shade),
        (&costs.shade_emit, uses.shade_emit),
        (&costs.shade_store, uses.shade_store),
    ];
    for (c, n) in states {
        i.add_state(c, n);
    }
    i
}

impl std::ops::AddAssign for Instructions {
    fn add_assign(&mut self, o: Instructions) {
        self.int += o.int;
        self.int_mul += o.int_mul;
        self.fp_add += o.fp_add;
        self.fp_mul += o.fp_mul;
        self.fp_cmp += o.fp_cmp;
        self.branch += o.branch;
        self.load += o.load;
        self.store += o.store;
    }
}

/// Energy in joules by component.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Energy {
    pub compute_j: f64,
    pub onchip_j: f64,
    /// Each component's joules, in the JSON an object keyed by its name in
    /// snake case with the unit (`"box_tests_j": ...`).
    #[serde(serialize_with = "parts_by_name")]
    pub parts: Vec<(&'static str, f64)>,
    /// SRAM leakage over the render time (`energy.leakage`, cycle mode), not
    /// part of `compute_j` or `onchip_j`.
    pub leakage_j: Option<f64>,
}

/// `[("box tests", 1e-4), ..]` as `{"box_tests_j": 1e-4, ..}`, in order.
fn parts_by_name<S: serde::Serializer>(
    parts: &[(&'static str, f64)],
    s: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(parts.len()))?;
    for (name, j) in parts {
        m.serialize_entry(&format!("{}_j", part_key(name)), j)?;
    }
    m.end()
}

/// A component's name as a JSON key: `"TP arithmetic"` is `tp_arithmetic`.
pub fn part_key(name: &str) -> String {
    name.to_ascii_lowercase()
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|w| !w.is_empty())
        .collect::<Vec<_>>()
        .join("_")
}

/// Charges `a` with the per-event energies of `c`.
pub fn energy(c: &EnergyCfg, a: &Activity) -> Energy {
    let pj = 1e-12;
    let i = &a.instructions;
    let hit_extra = c.ops_pj(RAY_TRI_OPS) - c.ops_pj(RAY_TRI_REJECT_OPS);
    let compute = [
        ("box tests", a.box_tests as f64 * c.ops_pj(RAY_BOX_OPS) * pj),
        (
            "triangle tests",
            (a.tri_tests as f64 * c.ops_pj(RAY_TRI_REJECT_OPS) + a.tri_hits as f64 * hit_extra)
                * pj,
        ),
        ("divider", a.inverse_dirs as f64 * 3.0 * c.fp_div_pj * pj),
        (
            "TP arithmetic",
            (i.int as f64 * c.int_pj
                + i.int_mul as f64 * c.int_mul_pj
                + i.fp_add as f64 * c.fp_add_pj
                + i.fp_mul as f64 * c.fp_mul_pj
                + (i.fp_cmp + i.branch) as f64 * c.fp_cmp_pj.max(c.int_pj))
                * pj,
        ),
    ];
    let n = i.total() as f64;
    let onchip = [
        ("L1", a.l1_accesses as f64 * c.l1_nj * 1e-9),
        ("L2", a.l2_accesses as f64 * c.l2_nj * 1e-9),
        (
            "scene buffer",
            a.scene_buffer_accesses as f64 * c.scene_buffer_nj * 1e-9,
        ),
        (
            "staging buffer",
            a.staging_accesses as f64 * c.staging_nj * 1e-9,
        ),
        ("register file", n * c.rf_per_instruction * c.rf_pj * pj),
        ("instruction fetch", n * c.icache_pj * pj),
        (
            "local store",
            a.local_store_accesses as f64 * c.local_store_pj * pj,
        ),
    ];
    Energy {
        compute_j: compute.iter().map(|p| p.1).sum(),
        onchip_j: onchip.iter().map(|p| p.1).sum(),
        parts: compute.into_iter().chain(onchip).collect(),
        leakage_j: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_event_is_charged_its_listed_energy() {
        let c = EnergyCfg::default();
        // One box test: 6 adds, 7 muls, 1 compare, 6 min/max.
        let e = energy(
            &c,
            &Activity {
                box_tests: 1,
                ..Activity::default()
            },
        );
        let want = (6.0 * 7.4 + 7.0 * 14.2 + 7.0 * 0.536) * 1e-12;
        assert!(
            (e.compute_j - want).abs() < 1e-18,
            "{} vs {want}",
            e.compute_j
        );
        assert_eq!(e.onchip_j, 0.0);
        // A hit costs the three divides and two compares more than a miss.
        let miss = energy(
            &c,
            &Activity {
                tri_tests: 1,
                ..Activity::default()
            },
        )
        .compute_j;
        let hit = energy(
            &c,
            &Activity {
                tri_tests: 1,
                tri_hits: 1,
                ..Activity::default()
            },
        )
        .compute_j;
        assert!(((hit - miss) - (3.0 * 156.3 + 2.0 * 0.536) * 1e-12).abs() < 1e-18);
        // An instruction: 3 RF accesses and one fetch, plus a local-store access for a load.
        let a = Activity {
            instructions: Instructions {
                load: 1,
                ..Instructions::default()
            },
            local_store_accesses: 1,
            ..Activity::default()
        };
        let e = energy(&c, &a);
        assert!((e.onchip_j - (3.0 * 7.9 + 13.5 + 6.93) * 1e-12).abs() < 1e-18);
        // SRAM accesses.
        let e = energy(
            &c,
            &Activity {
                l1_accesses: 1000,
                scene_buffer_accesses: 10,
                ..Activity::default()
            },
        );
        assert!((e.onchip_j - (1000.0 * 0.2042 + 10.0 * 1.656) * 1e-9).abs() < 1e-15);
    }

    #[test]
    fn bad_constants_are_named() {
        let c = EnergyCfg {
            l1_nj: -1.0,
            ..EnergyCfg::default()
        };
        let e = c.validate().unwrap_err();
        assert_eq!((e.key, e.value), ("l1_nj", -1.0));
        assert!(e.to_string().contains("energy.l1_nj"));
    }
}
