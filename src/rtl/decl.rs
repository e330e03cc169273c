//! Declarations: what a unit *is* (parameters, ports, registers, memories), separate
//! from what it *does*. One `unit!` declaration produces the Rust fields and this
//! description; the VCD tracer, the Verilog emitter and the state inventory all read
//! the description, so they can never disagree with the struct.

use super::link::LinkId;

/// Direction of a port, seen from the unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortDir {
    /// The unit consumes from a link: `x_valid`, `x_data` in, `x_ready` out.
    In,
    /// The unit produces into a link: `x_valid`, `x_data` out, `x_ready` in.
    Out,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortDecl {
    pub name: &'static str,
    pub dir: PortDir,
    /// Payload width in bits (the `x_data` vector).
    pub width: u32,
    pub link: LinkId,
    /// The payload's SystemVerilog type (`Payload::sv_type`).
    pub ty: super::sv::SvType,
    /// The payload's leaf fields (`Payload::field_list`; empty for a leaf):
    /// what the waveform shows and the package's struct must lay out.
    pub fields: Vec<super::bits::Field>,
}

/// One piece of clocked state as the Verilog skeleton and the trace see it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateDecl {
    pub name: String,
    pub width: u32,
    /// `None` for a register (traced as one VCD signal); `Some(depth)` for a memory
    /// array (`reg [w-1:0] name [0:depth-1]`), which is not traced: a waveform of a
    /// 4 MB buffer helps nobody and costs everything.
    pub depth: Option<u32>,
    /// A memory's depth as an expression of the unit's parameters
    /// ([`super::Ram::sized_by`]; `None`: the literal depth).
    pub depth_expr: Option<&'static str>,
    /// FSM encodings, for the VCD header comment.
    pub enum_names: Option<&'static [&'static str]>,
    /// The value at reset, packed LSB-first (empty: all zeros): what the model
    /// holds before its first edge, so the Verilog's reset agrees with the model
    /// and the waveform (`Declared::decl_at_reset` fills it in for registers).
    pub reset: super::bits::Bits,
    /// A register's payload fields (`Payload::field_list`; empty for a leaf),
    /// which the waveform shows beside the packed value.
    pub fields: Vec<super::bits::Field>,
    /// A register's SystemVerilog type (`Payload::sv_type`; `None`: a plain
    /// vector). The skeleton declares an FSM state register as its enum.
    pub ty: Option<super::sv::SvType>,
}

impl StateDecl {
    pub fn reg(name: impl Into<String>, width: u32) -> Self {
        StateDecl {
            name: name.into(),
            width,
            depth: None,
            depth_expr: None,
            enum_names: None,
            reset: super::bits::Bits::new(),
            fields: Vec::new(),
            ty: None,
        }
    }
    pub fn array(name: impl Into<String>, width: u32, depth: u32) -> Self {
        StateDecl {
            name: name.into(),
            width,
            depth: Some(depth),
            depth_expr: None,
            enum_names: None,
            reset: super::bits::Bits::new(),
            fields: Vec::new(),
            ty: None,
        }
    }
    pub fn bits(&self) -> u64 {
        self.width as u64 * self.depth.unwrap_or(1) as u64
    }
    pub fn traced(&self) -> bool {
        self.depth.is_none()
    }
    /// The reset value as a Verilog literal of the declared width.
    pub fn reset_literal(&self) -> String {
        let w = self.width.max(1);
        if self.reset.words().iter().all(|x| *x == 0) {
            return "'0".into();
        }
        let digits = w.div_ceil(4) as usize;
        let mut hex = String::with_capacity(digits);
        for k in (0..digits).rev() {
            let at = 4 * k as u32;
            let word = self
                .reset
                .words()
                .get((at / 64) as usize)
                .copied()
                .unwrap_or(0);
            let mask = (1u64 << 4.min(w - at)) - 1;
            let nib = (word >> (at % 64)) & mask;
            hex.push(char::from_digit(nib as u32, 16).expect("a nibble"));
        }
        format!("{w}'h{hex}")
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamDecl {
    /// Verilog name (upper case by convention).
    pub name: &'static str,
    pub value: u64,
}

/// The full declaration of one unit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitDecl {
    /// Verilog module name, also the default instance name.
    pub module: &'static str,
    /// Rust source file that holds the declaration (named in the Verilog comment).
    pub source: &'static str,
    /// First line of the unit's doc comment.
    pub doc: &'static str,
    pub params: Vec<ParamDecl>,
    pub ports: Vec<PortDecl>,
    pub state: Vec<StateDecl>,
}

/// A signal as it appears in a unit's VCD scope and as a Verilog port/reg.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SignalDecl {
    pub name: String,
    pub width: u32,
    pub enum_names: Option<&'static [&'static str]>,
}

impl UnitDecl {
    /// The value of a parameter expression: integers and parameter names
    /// joined by `+`, `*` and `/`, products before sums, left to right
    /// (`"2 * HALF_RAYS"`, `"BYTES / LINE_BYTES"`); an error names what it
    /// cannot read.
    pub fn eval_param_expr(&self, expr: &str) -> Result<u64, String> {
        let atom = |t: &str| -> Result<u64, String> {
            let t = t.trim();
            t.parse::<u64>().or_else(|_| {
                self.params
                    .iter()
                    .find(|p| p.name == t)
                    .map(|p| p.value)
                    .ok_or_else(|| format!("'{t}' is no parameter of {}", self.module))
            })
        };
        let mut sum = 0u64;
        for term in expr.split('+') {
            let mut v: Option<u64> = None;
            let mut op = '*';
            let mut rest = term;
            loop {
                let at = rest.find(['*', '/']);
                let (a, tail) = match at {
                    Some(i) => (
                        &rest[..i],
                        Some((rest.as_bytes()[i] as char, &rest[i + 1..])),
                    ),
                    None => (rest, None),
                };
                let x = atom(a)?;
                v = Some(match (v, op) {
                    (None, _) => x,
                    (Some(v), '*') => v * x,
                    (Some(_), _) if x == 0 => return Err(format!("'{expr}' divides by zero")),
                    (Some(v), _) => v / x,
                });
                match tail {
                    Some((o, t)) => {
                        op = o;
                        rest = t;
                    }
                    None => break,
                }
            }
            sum += v.unwrap_or(0);
        }
        Ok(sum)
    }

    /// Each memory sized by a parameter expression whose value is not its
    /// depth, as a message (empty: all agree).
    pub fn depth_mismatches(&self) -> Vec<String> {
        self.state
            .iter()
            .filter_map(|s| {
                let (e, d) = (s.depth_expr?, s.depth?);
                match self.eval_param_expr(e) {
                    Ok(v) if v == d as u64 => None,
                    Ok(v) => Some(format!(
                        "{}.{}: depth {d}, but its bound '{e}' is {v}",
                        self.module, s.name
                    )),
                    Err(m) => Some(format!("{}.{}: bound '{e}': {m}", self.module, s.name)),
                }
            })
            .collect()
    }

    /// Bits of clocked state (registers and memories), excluding link FIFOs, which
    /// belong to the interconnect.
    pub fn state_bits(&self) -> u64 {
        self.state.iter().map(StateDecl::bits).sum()
    }

    /// The traced signals in order: for each port `valid`, `ready`, `data`; then each
    /// register. This is the contract between the VCD scope and the Verilog module.
    pub fn signals(&self) -> Vec<SignalDecl> {
        let mut v = Vec::new();
        for p in &self.ports {
            for (suffix, w) in [("valid", 1), ("ready", 1), ("data", p.width)] {
                v.push(SignalDecl {
                    name: format!("{}_{}", p.name, suffix),
                    width: w,
                    enum_names: None,
                });
            }
        }
        for s in self.state.iter().filter(|s| s.traced()) {
            v.push(SignalDecl {
                name: s.name.clone(),
                width: s.width,
                enum_names: s.enum_names,
            });
        }
        v
    }
}

/// Collects state declarations; each state primitive adds its own entries.
#[derive(Default)]
pub struct StateList {
    pub items: Vec<StateDecl>,
}

/// Reused buffer of sampled signal values (one `Bits` per traced signal, in order).
#[derive(Default)]
pub struct Samples {
    pub vals: Vec<super::bits::Bits>,
    pub n: usize,
}

impl Samples {
    pub fn begin(&mut self) {
        self.n = 0;
    }
    /// The next slot, cleared, to pack one signal's value into.
    pub fn slot(&mut self) -> &mut super::bits::Bits {
        if self.n == self.vals.len() {
            self.vals.push(super::bits::Bits::new());
        }
        let b = &mut self.vals[self.n];
        b.clear();
        self.n += 1;
        b
    }
}

/// The name of element `k` of a port array (`tp_req_3`), interned so a port name
/// stays a `&'static str` like a declared one.
pub fn array_port_name(base: &str, k: usize) -> &'static str {
    use std::collections::HashSet;
    use std::sync::{Mutex, OnceLock};
    static NAMES: OnceLock<Mutex<HashSet<&'static str>>> = OnceLock::new();
    let name = format!("{base}_{k}");
    let mut set = NAMES
        .get_or_init(|| Mutex::new(HashSet::new()))
        .lock()
        .expect("name table lock");
    if let Some(s) = set.get(name.as_str()) {
        return s;
    }
    let s: &'static str = Box::leak(name.into_boxed_str());
    set.insert(s);
    s
}
