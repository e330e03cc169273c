//! SystemVerilog types of payloads and the package that declares them
//! (`hdl/ds_pkg.sv`): a `typedef struct packed` per payload struct, a
//! `typedef enum` per FSM, and the configured sizes as localparams.
//!
//! `pack` lays a struct's fields LSB first in declaration order; the first
//! member of an SV `struct packed` is its MSB, so members are written in
//! reverse declaration order and each field then sits at the model's bit
//! offset ([`crate::rtl::bits::Payload::fields`]).

use std::fmt::Write;

/// A payload's SystemVerilog type ([`crate::rtl::bits::Payload::sv_type`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SvType {
    /// `logic [W-1:0]`: an integer, a flag or raw bits.
    Logic(u32),
    /// An IEEE-754 single: `logic [31:0]`, noted as a float in the package.
    Float,
    /// An FSM state: `typedef enum`, state k encoded as k.
    Enum {
        /// The Rust type's name (`TpState`).
        name: &'static str,
        names: &'static [&'static str],
    },
    /// A payload struct: `typedef struct packed`; members in declaration
    /// order (the first in the lowest bits).
    Struct {
        /// The Rust type's name (`BoxReq`; `OptHitRec` for an `Option`).
        name: String,
        members: Vec<(&'static str, SvType)>,
    },
}

/// `BoxReq` -> `box_req`, `L1Resp` -> `l1_resp`, `Vec3` -> `vec3`.
pub fn snake(name: &str) -> String {
    let mut s = String::new();
    let mut prev_lower = false;
    for c in name.chars() {
        if c.is_ascii_uppercase() {
            if prev_lower {
                s.push('_');
            }
            s.push(c.to_ascii_lowercase());
            prev_lower = false;
        } else {
            s.push(c);
            prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
        }
    }
    s
}

/// The enum literal of `state` of the FSM type `ty` (`TpState`, `BoxIssue1`
/// -> `TP_STATE_BOX_ISSUE1`): prefixed by the type, as SV enum literals share
/// the package's name space.
pub fn enum_literal(ty: &str, state: &str) -> String {
    format!("{}_{}", snake(ty), snake(state)).to_ascii_uppercase()
}

fn range(w: u32) -> String {
    if w == 1 {
        String::new()
    } else {
        format!(" [{}:0]", w - 1)
    }
}

impl SvType {
    pub fn width(&self) -> u32 {
        match self {
            SvType::Logic(w) => *w,
            SvType::Float => 32,
            SvType::Enum { names, .. } => crate::rtl::bits::clog2_u32(names.len() as u32),
            SvType::Struct { members, .. } => members.iter().map(|(_, t)| t.width()).sum(),
        }
    }

    /// Whether the package declares this type (a struct or an enum).
    pub fn is_named(&self) -> bool {
        matches!(self, SvType::Enum { .. } | SvType::Struct { .. })
    }

    /// The type as a declaration writes it: `box_req_t`, `tp_state_t`,
    /// `logic [31:0]`.
    pub fn sv_name(&self) -> String {
        match self {
            SvType::Logic(w) => format!("logic{}", range(*w)),
            SvType::Float => "logic [31:0]".into(),
            SvType::Enum { name, .. } => format!("{}_t", snake(name)),
            SvType::Struct { name, .. } => format!("{}_t", snake(name)),
        }
    }

    /// The tag naming an `Option` of this type (`OptHitRec`, `OptBits32`).
    pub fn option_name(&self) -> String {
        match self {
            SvType::Logic(w) => format!("OptBits{w}"),
            SvType::Float => "OptF32".into(),
            SvType::Enum { name, .. } => format!("Opt{name}"),
            SvType::Struct { name, .. } => format!("Opt{name}"),
        }
    }

    /// The leaf members, each as (path, offset, width), LSB-first offsets:
    /// what [`crate::rtl::bits::Payload::field_list`] gives for the payload.
    pub fn leaves(&self, prefix: &str, at: u32, out: &mut Vec<(String, u32, u32)>) {
        match self {
            SvType::Struct { members, .. } => {
                let mut at = at;
                for (n, t) in members {
                    t.leaves(&crate::rtl::bits::field_path(prefix, n), at, out);
                    at += t.width();
                }
            }
            t => out.push((prefix.to_string(), at, t.width())),
        }
    }
}

/// The typedefs of a package, each after the types it holds.
#[derive(Clone, Debug, Default)]
pub struct Package {
    types: Vec<SvType>,
}

impl Package {
    /// Declares `ty` and the types it holds; returns how a port or register
    /// of it is written. Two different types under one SV name are an error
    /// (two Rust payloads of one name in different modules).
    pub fn declare(&mut self, ty: &SvType) -> Result<String, String> {
        if let SvType::Struct { members, .. } = ty {
            for (_, m) in members {
                self.declare(m)?;
            }
        }
        let name = ty.sv_name();
        if ty.is_named() {
            match self.types.iter().find(|t| t.sv_name() == name) {
                Some(t) if t != ty => {
                    return Err(format!(
                        "two payload types are named '{name}' in ds_pkg: {t:?} and {ty:?}; rename one"
                    ));
                }
                Some(_) => {}
                None => self.types.push(ty.clone()),
            }
        }
        Ok(name)
    }

    pub fn types(&self) -> &[SvType] {
        &self.types
    }

    /// The package text: a header, `params` as localparams (name, SV type,
    /// value), then the typedefs. Yosys 0.23 (Debian 12) has no `import`,
    /// so under `YOSYS` the same declarations are read into the compilation
    /// unit, where the skeletons (which import `ds_pkg::*` elsewhere) see them.
    pub fn emit(&self, header: &[String], params: &[(String, String, String)]) -> String {
        let mut v = String::new();
        for h in header {
            let _ = writeln!(v, "// {h}");
        }
        let _ = writeln!(v, "`ifndef YOSYS\npackage ds_pkg;\n`endif");
        if !params.is_empty() {
            let _ = writeln!(v);
        }
        for (name, ty, val) in params {
            let _ = writeln!(v, "    localparam {ty} {name} = {val};");
        }
        if !params.is_empty() {
            // Verilator -Wall reports a package's localparams that no module
            // reads; one bit of each feeds the lint sink, as in the skeletons.
            let bits: Vec<String> = params.iter().map(|(n, _, _)| format!("{n}[0]")).collect();
            let _ = writeln!(v, "    localparam [0:0] _unused_cfg_ok = &{{1'b0,");
            for c in bits.chunks(4) {
                let _ = writeln!(v, "        {},", c.join(", "));
            }
            let _ = writeln!(v, "        1'b0}};");
        }
        for t in &self.types {
            let _ = writeln!(v);
            match t {
                SvType::Enum { name, names } => {
                    let w = t.width();
                    let _ = writeln!(v, "    typedef enum logic{} {{", range(w));
                    for (k, s) in names.iter().enumerate() {
                        let sep = if k + 1 == names.len() { "" } else { "," };
                        let _ = writeln!(v, "        {} = {w}'d{k}{sep}", enum_literal(name, s));
                    }
                    let _ = writeln!(v, "    }} {};", t.sv_name());
                }
                SvType::Struct { members, .. } => {
                    let _ = writeln!(
                        v,
                        "    // {} bits; members MSB first (the model packs the last one highest).",
                        t.width()
                    );
                    let _ = writeln!(v, "    typedef struct packed {{");
                    let mut at = t.width();
                    for (n, m) in members.iter().rev() {
                        at -= m.width();
                        let note = if *m == SvType::Float { ", float" } else { "" };
                        let bits = match m.width() {
                            1 => format!("[{at}]"),
                            w => format!("[{}:{at}]", at + w - 1),
                        };
                        let _ = writeln!(v, "        {} {n}; // {bits}{note}", m.sv_name());
                    }
                    let _ = writeln!(v, "    }} {};", t.sv_name());
                }
                _ => {}
            }
        }
        let _ = writeln!(v, "`ifndef YOSYS\nendpackage\n`endif");
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names() {
        assert_eq!(snake("BoxReq"), "box_req");
        assert_eq!(snake("L1Resp"), "l1_resp");
        assert_eq!(snake("Vec3"), "vec3");
        assert_eq!(snake("MemLineReq"), "mem_line_req");
        assert_eq!(enum_literal("TpState", "BoxIssue1"), "TP_STATE_BOX_ISSUE1");
        assert_eq!(enum_literal("DramCmd", "Nop"), "DRAM_CMD_NOP");
    }

    #[test]
    fn a_name_held_by_two_types_is_an_error() {
        let mut p = Package::default();
        let a = SvType::Struct {
            name: "Req".into(),
            members: vec![("a", SvType::Logic(3))],
        };
        let b = SvType::Struct {
            name: "Req".into(),
            members: vec![("a", SvType::Logic(4))],
        };
        assert_eq!(p.declare(&a).unwrap(), "req_t");
        assert_eq!(p.declare(&a).unwrap(), "req_t");
        assert!(p.declare(&b).unwrap_err().contains("'req_t'"));
        assert_eq!(p.types().len(), 1);
    }
}
