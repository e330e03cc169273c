//! Hardware units, one per file. Each is declared once with `unit!`.
pub mod box_pipe;
pub mod divider;
pub mod mem_ctrl;
pub mod tri_pipe;

/// Identifies the requester (thread processor and slot) so a shared unit's result
/// can be routed back. 16 bits cover 16 TPs with room for per-TP sub-ids.
pub type Tag = u16;

use crate::config::Config;
use crate::rtl::link::LinkId;
use crate::rtl::{Declared, In, Out, UnitDecl};

/// The declaration of every hardware unit, built with `cfg` (for `dualstream hdl`
/// and the declaration tests). Link ids are placeholders: only the interface matters.
pub fn catalog(cfg: &Config) -> Vec<UnitDecl> {
    let d = cfg.links.tm.delay;
    let (i, o) = (LinkId(0), LinkId(1));
    vec![
        box_pipe::BoxPipe::new(&cfg.box_pipe, d, In::new(i), Out::new(o)).decl(),
        tri_pipe::TriPipe::new(&cfg.tri_pipe, d, In::new(i), Out::new(o)).decl(),
        divider::Divider::new(&cfg.divider, d, In::new(i), Out::new(o)).decl(),
        mem_ctrl::MemCtrl::new(&cfg.mem, cfg.clocks.dram_ps, 0, In::new(i), Out::new(o)).decl(),
    ]
}

/// Writes one `<module>.v` per unit into `dir` (created if missing); returns the paths.
pub fn write_hdl(cfg: &Config, dir: &std::path::Path) -> Result<Vec<std::path::PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| {
        format!(
            "cannot create the HDL directory '{}': {e}; choose a writable --out",
            dir.display()
        )
    })?;
    let mut out = Vec::new();
    for d in catalog(cfg) {
        let p = dir.join(format!("{}.v", d.module));
        std::fs::write(&p, crate::rtl::verilog::emit_module(&d)).map_err(|e| {
            format!(
                "cannot write '{}': {e}; choose a writable --out",
                p.display()
            )
        })?;
        out.push(p);
    }
    Ok(out)
}
