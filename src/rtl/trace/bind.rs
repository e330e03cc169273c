//! Binding a tracer to the simulator: which units it traces, and the header
//! that declares their signals. Per unit instance a scope holds, per port,
//! `valid`, `ready`, `data` (the packed vector) and `fire` (valid and ready),
//! the payload's fields in a struct scope named after the port, then every
//! register. The first scope holds one clock per domain and the reset.

use super::super::decl::{PortDir, SignalDecl};
use super::super::link::LinkDyn;
use super::super::sim::{Clock, Time};
use super::super::unit::Unit;
use super::sink::{ScopeKind, VarDef, VarKind};
use super::{ClockSig, Derive, Derived, NONE, Sig, TraceError, TracedUnit, Tracer};
use crate::rtl::bits::FieldKind;

impl Tracer {
    /// Selects the units to trace and writes the header.
    pub(crate) fn bind(
        &mut self,
        units: &[(&str, &dyn Unit, &Clock)],
        links: &[Box<dyn LinkDyn>],
        clocks: &[Clock],
    ) -> Result<(), TraceError> {
        let mut chosen = Vec::new();
        for (i, (path, u, clk)) in units.iter().enumerate() {
            if self.spec.matches(path) {
                chosen.push((i, *path, *u, *clk));
            }
        }
        if chosen.is_empty() {
            return Err(TraceError::NoUnit {
                filter: self.spec.filter.clone(),
                units: units.iter().map(|u| u.0.to_string()).collect(),
            });
        }
        self.traced_of = vec![NONE; units.len()];
        for (k, c) in chosen.iter().enumerate() {
            self.traced_of[c.0] = k as u32;
        }
        let of = |u: Option<crate::rtl::UnitId>| u.map_or(NONE, |u| self.traced_of[u.0 as usize]);
        self.link_ends = links
            .iter()
            .map(|l| {
                let (p, c) = l.ends();
                [of(p), NONE, of(c), NONE]
            })
            .collect();
        let root = chosen[0].1.split('.').next().unwrap_or("top");
        self.sink.begin_scope(root, ScopeKind::Module);
        let mut open: Vec<&str> = vec![root];
        self.declare_clocks(root, clocks);
        for (index, path, u, clk) in chosen {
            let scopes: Vec<&str> = path.split('.').collect();
            let common = open.iter().zip(&scopes).take_while(|(a, b)| a == b).count();
            for _ in common..open.len() {
                self.sink.end_scope();
            }
            open.truncate(common);
            for s in &scopes[common..] {
                self.sink.begin_scope(s, ScopeKind::Module);
                open.push(s);
            }
            let unit = self.declare_unit(index, path, u, clk, links);
            // Every unit is sampled at its first edge in the window.
            self.active.push(self.units.len() as u32);
            self.units.push(unit);
        }
        for _ in 0..open.len() {
            self.sink.end_scope();
        }
        for (ui, u) in self.units.iter().enumerate() {
            for (k, &(l, dir)) in u.ports.iter().enumerate() {
                let e = &mut self.link_ends[l.0 as usize];
                let end = if dir == PortDir::Out { 0 } else { 2 };
                if e[end] == ui as u32 {
                    e[end + 1] = k as u32;
                }
            }
        }
        let format = self.format;
        self.header_bytes = self
            .sink
            .end_header()
            .map_err(|source| TraceError::Header { format, source })?;
        Ok(())
    }

    /// `clk_<domain>` per clock domain and `rst`, on the trace's picosecond
    /// time base.
    fn declare_clocks(&mut self, root: &str, clocks: &[Clock]) {
        self.sink.comment(
            "clk_<domain>: rises at the start of each cycle (cycle n at n x period ps), \
             when the registers take the values shown for that cycle; rst: the model \
             leaves reset before time 0",
        );
        for c in clocks {
            let name = format!("clk_{}", c.name);
            let h = self.sink.var(&VarDef {
                name: &name,
                kind: VarKind::Wire,
                width: 1,
                enum_names: None,
            });
            self.view
                .sig(format_args!("{root}.{name}"), 1, false, None, "");
            self.clocks.push(ClockSig {
                h,
                period: c.period_ps,
                level: false,
                next: 0,
            });
        }
        self.rst = Some(self.sink.var(&VarDef {
            name: "rst",
            kind: VarKind::Wire,
            width: 1,
            enum_names: None,
        }));
        self.view
            .sig(format_args!("{root}.rst"), 1, false, None, "");
    }

    fn declare(
        &mut self,
        name: &str,
        kind: VarKind,
        width: u32,
        e: Option<&'static [&'static str]>,
    ) -> u32 {
        self.sink.var(&VarDef {
            name,
            kind,
            width,
            enum_names: e,
        })
    }

    fn declare_unit(
        &mut self,
        index: usize,
        path: &str,
        u: &dyn Unit,
        clk: &Clock,
        links: &[Box<dyn LinkDyn>],
    ) -> TracedUnit {
        let decl = u.decl();
        self.sink.comment(&format!(
            "{path}: module {} ({}), clock {} period {} ps",
            decl.module, decl.source, clk.name, clk.period_ps
        ));
        let signals = decl.signals();
        let (mut sigs, mut derived, mut port_derived) = (Vec::new(), Vec::new(), Vec::new());
        let mut reg_derived = Vec::new();
        self.view.begin_unit(path);
        // Ports' valid, ready and data come first (`UnitDecl::signals`):
        // wires. A register is never taken for a port because its name starts
        // with one (`ray_index` beside port `ray`).
        for (k, p) in decl.ports.iter().enumerate() {
            // Every port signal is sampled (fire and the fields come from
            // them); `show` picks what the file holds. The view lists valid,
            // ready, fire, then the data and its fields.
            let show = self.spec.show;
            let first = derived.len();
            for (j, s) in signals[3 * k..3 * k + 3].iter().enumerate() {
                let kind = if j < 2 { show.handshakes } else { show.data };
                if j == 2 && show.keeps(show.handshakes, 1) {
                    let fire = format!("{}_fire", p.name);
                    let h = self.declare(&fire, VarKind::Wire, 1, None);
                    self.view
                        .sig(format_args!("{path}.{fire}"), 1, false, None, "");
                    derived.push(Derived {
                        sig: Sig::new(h, 1),
                        how: Derive::Fire { port: k },
                    });
                }
                sigs.push(if show.keeps(kind, s.width) {
                    let h = self.declare(&s.name, VarKind::Wire, s.width, None);
                    self.view
                        .sig(format_args!("{path}.{}", s.name), s.width, false, None, "");
                    Sig::new(h, s.width)
                } else {
                    Sig::hidden(s.width)
                });
            }
            let fields_start = derived.len();
            let fields: Vec<_> = links[p.link.0 as usize]
                .fields()
                .into_iter()
                .filter(|f| show.keeps(show.fields, f.width))
                .collect();
            if fields.is_empty() {
                port_derived.push((first, fields_start, derived.len()));
                continue;
            }
            let port = (path, p.name, 3 * k + 2, decl.module);
            self.declare_fields(port, fields, &mut derived);
            port_derived.push((first, fields_start, derived.len()));
        }
        let traced_state = decl.state.iter().filter(|s| s.traced());
        for (
            SignalDecl {
                name,
                width,
                enum_names,
            },
            state,
        ) in signals
            .into_iter()
            .skip(3 * decl.ports.len())
            .zip(traced_state)
        {
            if let Some(names) = enum_names {
                let enc: Vec<String> = names
                    .iter()
                    .enumerate()
                    .map(|(i, n)| format!("{i}={n}"))
                    .collect();
                self.sink
                    .comment(&format!("{path}.{name} states: {}", enc.join(" ")));
            }
            let show = self.spec.show;
            let kind = if enum_names.is_some() {
                show.fsm
            } else {
                show.regs
            };
            if !show.keeps(kind, width) {
                sigs.push(Sig::hidden(width));
                continue;
            }
            let h = self.declare(&name, VarKind::Reg, width, enum_names);
            let fsm_name = enum_names.map_or(String::new(), |_| format!("{}_{name}", decl.module));
            self.view.sig(
                format_args!("{path}.{name}"),
                width,
                false,
                enum_names,
                &fsm_name,
            );
            sigs.push(Sig::new(h, width));
            // A struct register's fields, as a port's (Verilator's
            // --trace-structs): from the packed value, sampled at `of`.
            let of = sigs.len() - 1;
            let fields: Vec<_> = state
                .fields
                .iter()
                .filter(|f| show.keeps(show.fields, f.width))
                .cloned()
                .collect();
            if !fields.is_empty() {
                let start = derived.len();
                self.declare_fields((path, &name, of, decl.module), fields, &mut derived);
                reg_derived.push((of, start, derived.len()));
            }
        }
        self.view.end_unit();
        let ports = decl.ports.iter().map(|p| (p.link, p.dir)).collect();
        self.full_bytes_per_ps += sigs
            .iter()
            .chain(derived.iter().map(|d| &d.sig))
            .filter(|s| s.shown)
            .map(|s| (s.width + self.sink.id_len(s.h) as u32 + 3) as f64)
            .sum::<f64>()
            / clk.period_ps as f64;
        if !self.periods.contains(&clk.period_ps) {
            self.periods.push(clk.period_ps);
        }
        let spans = derived
            .iter()
            .map(|d| match d.how {
                Derive::Field { offset, .. } => (offset, d.sig.width),
                Derive::Fire { .. } => (0, 0),
            })
            .collect();
        TracedUnit {
            index,
            period: clk.period_ps,
            busy_until: Time::MAX,
            moving: true,
            queued: true,
            fresh: true,
            port_busy: vec![Time::MAX; decl.ports.len()],
            port_wake: vec![Time::MAX; decl.ports.len()],
            ran_at: Time::MAX,
            regs_at: Time::MAX,
            ports,
            sigs,
            derived,
            wide: Vec::new(),
            spans,
            port_derived,
            reg_derived,
        }
    }

    /// A port's payload fields: a struct scope named after the port (nested
    /// as the payload nests), one variable per leaf field, derived from the
    /// packed data (sampled signal `of`).
    fn declare_fields(
        &mut self,
        (path, port, of, module): (&str, &str, usize, &str),
        fields: Vec<crate::rtl::bits::Field>,
        derived: &mut Vec<Derived>,
    ) {
        self.view.begin(&format!("{port} fields"), false);
        self.sink.begin_scope(port, ScopeKind::Struct);
        let mut open: Vec<String> = Vec::new();
        for f in fields {
            let parts: Vec<&str> = f.name.split('.').collect();
            let (leaf, scopes) = parts.split_last().expect("a field has a name");
            let common = open.iter().zip(scopes).take_while(|(a, b)| a == *b).count();
            // Nested structs are scopes in the trace and groups in the view
            // (GTKWave shows a signal's last name only: origin.x and dir.x
            // would both read `x`).
            for _ in common..open.len() {
                self.sink.end_scope();
                self.view.end();
            }
            open.truncate(common);
            for s in &scopes[common..] {
                self.sink.begin_scope(s, ScopeKind::Struct);
                self.view.begin(s, false);
                open.push(s.to_string());
            }
            let (kind, e) = match f.kind {
                FieldKind::Float => (VarKind::Real, None),
                FieldKind::Enum(names) => (VarKind::Wire, Some(names)),
                FieldKind::Bits => (VarKind::Wire, None),
            };
            let h = self.declare(leaf, kind, f.width, e);
            let fsm_name = e.map_or(String::new(), |_| format!("{module}_{leaf}"));
            self.view.sig(
                format_args!("{path}.{port}.{}", f.name),
                f.width,
                kind == VarKind::Real,
                e,
                &fsm_name,
            );
            derived.push(Derived {
                sig: Sig::new(h, f.width),
                how: Derive::Field {
                    of,
                    offset: f.offset,
                    float: f.kind == FieldKind::Float,
                },
            });
        }
        for _ in 0..open.len() {
            self.sink.end_scope();
            self.view.end();
        }
        self.sink.end_scope();
        self.view.end();
    }
}
