//! A reader of the generated SystemVerilog: the package `ds_pkg.sv` (its
//! structs, enums and localparams, read from the text, not from the code
//! that wrote it) and the port and register declarations of a module.

use std::collections::BTreeMap;

/// One typedef of the package.
#[derive(Clone, Debug, PartialEq)]
pub enum Def {
    /// Width and literals (name, value).
    Enum(u32, Vec<(String, u64)>),
    /// Members as written, MSB first: (type, name).
    Struct(Vec<(String, String)>),
}

/// The package's typedefs and localparams by name.
#[derive(Clone, Debug, Default)]
pub struct Pkg {
    pub types: BTreeMap<String, Def>,
    pub params: BTreeMap<String, String>,
}

/// `[H:L]` -> H - L + 1.
fn range_width(r: &str) -> u32 {
    let (h, l) = r
        .trim_start_matches('[')
        .trim_end_matches(']')
        .split_once(':')
        .unwrap_or_else(|| panic!("a range: {r}"));
    h.trim().parse::<u32>().unwrap() - l.trim().parse::<u32>().unwrap() + 1
}

impl Pkg {
    pub fn parse(text: &str) -> Pkg {
        let mut p = Pkg::default();
        let mut open: Option<Def> = None;
        for line in text.lines() {
            let l = line.split("//").next().unwrap().trim();
            if let Some(r) = l.strip_prefix("typedef enum logic") {
                let w = match r.trim().trim_end_matches('{').trim() {
                    "" => 1,
                    r => range_width(r),
                };
                open = Some(Def::Enum(w, Vec::new()));
            } else if l.starts_with("typedef struct packed") {
                open = Some(Def::Struct(Vec::new()));
            } else if let Some(name) = l.strip_prefix("} ") {
                let name = name.trim_end_matches(';').to_string();
                p.types.insert(name, open.take().expect("a typedef open"));
            } else if let Some(Def::Enum(_, lits)) = &mut open {
                if let Some((n, v)) = l.trim_end_matches(',').split_once(" = ") {
                    let v = v.split_once("'d").expect("W'dK").1.parse().unwrap();
                    lits.push((n.to_string(), v));
                }
            } else if let Some(Def::Struct(ms)) = &mut open {
                if let Some(m) = l.strip_suffix(';') {
                    let (ty, name) = m.rsplit_once(' ').unwrap();
                    ms.push((ty.to_string(), name.to_string()));
                }
            } else if let Some(r) = l.strip_prefix("localparam ") {
                let (lhs, v) = r.split_once(" = ").unwrap();
                let name = lhs.rsplit(' ').next().unwrap();
                p.params
                    .insert(name.to_string(), v.trim_end_matches(';').to_string());
            }
        }
        p
    }

    /// The width of a type as a declaration writes it.
    pub fn width(&self, ty: &str) -> u32 {
        if ty == "logic" {
            return 1;
        }
        if let Some(r) = ty.strip_prefix("logic ") {
            return range_width(r);
        }
        match self.types.get(ty) {
            Some(Def::Enum(w, _)) => *w,
            Some(Def::Struct(ms)) => ms.iter().map(|(t, _)| self.width(t)).sum(),
            None => panic!("type {ty} is not in the package"),
        }
    }

    /// The leaves of a struct type: (path, LSB offset, width), in the order
    /// of their offsets (the last member written is the lowest).
    pub fn leaves(&self, ty: &str, prefix: &str, at: u32, out: &mut Vec<(String, u32, u32)>) {
        match self.types.get(ty) {
            Some(Def::Struct(ms)) => {
                let mut at = at;
                for (t, n) in ms.iter().rev() {
                    let path = if prefix.is_empty() {
                        n.clone()
                    } else {
                        format!("{prefix}.{n}")
                    };
                    self.leaves(t, &path, at, out);
                    at += self.width(t);
                }
            }
            _ => out.push((prefix.to_string(), at, self.width(ty))),
        }
    }

    /// A port or register of a module line: (name, type as written, kind),
    /// kind `wire` for a port, `reg` for a register; `None` for anything else
    /// (a memory array, `clk`, an assignment).
    pub fn decl(&self, line: &str) -> Option<(String, String, &'static str)> {
        let l = line.trim().trim_end_matches([',', ';']);
        let typed = |r: &str| -> Option<(String, String)> {
            let (ty, name) = r.rsplit_once(' ')?;
            let ty = match ty.strip_prefix("wire") {
                Some("") => "logic".to_string(),
                Some(rng) => format!("logic {}", rng.trim()),
                None if ty == "reg" => "logic".to_string(),
                None => match ty.strip_prefix("reg ") {
                    Some(rng) => format!("logic {rng}"),
                    None if self.types.contains_key(ty) => ty.to_string(),
                    None => return None,
                },
            };
            Some((name.to_string(), ty))
        };
        if let Some(r) = l
            .strip_prefix("input  ")
            .or_else(|| l.strip_prefix("output "))
        {
            return typed(r).map(|(n, t)| (n, t, "wire"));
        }
        if l.contains(" [0:") || l.contains(" = ") || l.contains("<=") || l.starts_with("wire ") {
            return None;
        }
        typed(l).map(|(n, t)| (n, t, "reg"))
    }
}
