//! Self-checking SystemVerilog testbenches from a unit's declaration
//! (`dualstream hdl --testbench`, docs/rtl.md "Testbenches"): the testbench
//! instantiates any module with the unit's interface and the skeleton's
//! parameters, replays the environment's side of a vector file (`--capture`,
//! [`crate::rtl::trace::CaptureSpec`]) and checks the unit's side, in the
//! model's order or cycle for cycle. It runs under `verilator --binary` and
//! Icarus 11 (`iverilog -g2012`): flat vectors sliced by the package's field
//! offsets, no queues, no `break`, one file handle per replayed stream.

use std::fmt::Write;

use super::decl::{PortDir, UnitDecl};

/// How the testbench checks the unit's side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TbMode {
    /// Each output port delivers the model's payloads in the model's order
    /// (and all of them, within a timeout); inputs are offered as streams.
    Order,
    /// Every checked token in the model's cycle.
    Cycle,
}

impl TbMode {
    pub fn parse(s: &str) -> Option<TbMode> {
        match s {
            "order" => Some(TbMode::Order),
            "cycle" => Some(TbMode::Cycle),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            TbMode::Order => "order",
            TbMode::Cycle => "cycle",
        }
    }
}

/// What a vector file's header says (docs/rtl.md "Vectors").
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VecHeader {
    pub version: u32,
    pub module: String,
    pub instance: String,
    pub from_reset: bool,
    pub rows: Option<u64>,
    /// (name, dir, width)
    pub ports: Vec<(String, PortDir, u32)>,
    pub params: Vec<(String, u64)>,
}

/// Reads the header of a vector file's text (only its `//` lines).
pub fn parse_header(text: &str) -> Result<VecHeader, String> {
    let mut h = VecHeader {
        version: 0,
        module: String::new(),
        instance: String::new(),
        from_reset: false,
        rows: None,
        ports: Vec::new(),
        params: Vec::new(),
    };
    for l in text.lines() {
        let Some(l) = l.strip_prefix("// ") else {
            break;
        };
        let t: Vec<&str> = l.split_whitespace().collect();
        let num = |s: Option<&&str>| s.and_then(|s| s.parse::<u64>().ok());
        match t.first().copied() {
            Some("dualstream") if t.get(1) == Some(&"vectors") => {
                h.version = num(t.get(2)).unwrap_or(0) as u32
            }
            Some("module") => h.module = t.get(1).unwrap_or(&"").to_string(),
            Some("instance") => h.instance = t.get(1).unwrap_or(&"").to_string(),
            Some("from_reset") => h.from_reset = t.get(1) == Some(&"1"),
            Some("rows") => h.rows = num(t.get(1)),
            Some("param") => h.params.push((
                t.get(1).unwrap_or(&"").to_string(),
                num(t.get(2)).unwrap_or(0),
            )),
            Some("port") => {
                let dir = match t.get(2) {
                    Some(&"in") => PortDir::In,
                    Some(&"out") => PortDir::Out,
                    _ => return Err(format!("bad port line '// {l}'")),
                };
                let w = num(t.get(3)).ok_or_else(|| format!("bad port line '// {l}'"))?;
                h.ports.push((t[1].to_string(), dir, w as u32));
            }
            _ => {}
        }
    }
    if h.version != super::trace::VECTORS_VERSION {
        return Err(format!(
            "not a dualstream vector file of version {} (its first line is not '// dualstream vectors {}')",
            super::trace::VECTORS_VERSION,
            super::trace::VECTORS_VERSION
        ));
    }
    Ok(h)
}

/// Checks that vectors with header `h` are of unit `d` as configured: the
/// same module, ports (names, directions, widths, in order) and parameters.
pub fn check_header(d: &UnitDecl, h: &VecHeader) -> Result<(), String> {
    if h.module != d.module {
        return Err(format!(
            "the vectors are of module '{}' ({}), not '{}'; give --testbench {}",
            h.module, h.instance, d.module, h.module
        ));
    }
    let want: Vec<(String, PortDir, u32)> = d
        .ports
        .iter()
        .map(|p| (p.name.to_string(), p.dir, p.width))
        .collect();
    if want != h.ports {
        let show = |v: &[(String, PortDir, u32)]| {
            v.iter()
                .map(|(n, d, w)| {
                    format!("{n} {} {w}", if *d == PortDir::In { "in" } else { "out" })
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        return Err(format!(
            "the vectors' ports ({}) are not {}'s as configured ({}); give the --config the vectors were captured with",
            show(&h.ports),
            d.module,
            show(&want)
        ));
    }
    // Parameters by name only: their values are the run's (some, such as
    // HITS_BASE, are set per frame by the host), and the testbench
    // instantiates the unit with the vectors' values.
    let names: Vec<&str> = d.params.iter().map(|p| p.name).collect();
    let theirs: Vec<&str> = h.params.iter().map(|(n, _)| n.as_str()).collect();
    if names != theirs {
        return Err(format!(
            "the vectors' parameters ({theirs:?}) are not {}'s ({names:?}); capture them again with this build",
            d.module
        ));
    }
    if !h.from_reset {
        return Err(format!(
            "the vectors of {} do not start at reset (from_reset 0): the RTL's state at their first cycle is unknown; capture from cycle 0 (--capture-window 0..N)",
            h.instance
        ));
    }
    Ok(())
}

/// Options of a generated testbench.
#[derive(Clone, Debug)]
pub struct TbGen {
    pub mode: TbMode,
    /// The vector file the testbench reads unless `+vectors=FILE` says.
    pub vectors: String,
    /// Stop after this many mismatches (`+max_mismatches=N`).
    pub max_mismatches: u32,
    /// Order mode: cycles after the vectors' end to wait for the outputs
    /// still owed (`+timeout=N`).
    pub timeout: u32,
    /// Order mode: the transfers of each port in the vectors
    /// ([`count_fires`]), which size the testbench's stream memory.
    pub fires: Vec<u64>,
    /// The unit's parameters as the vectors' run had them (name, value).
    pub params: Vec<(String, u64)>,
}

/// Transfers (valid and ready in one row) per port of a vector file's rows,
/// for `nports` ports.
pub fn count_fires(r: impl std::io::BufRead, nports: usize) -> std::io::Result<Vec<u64>> {
    let mut n = vec![0u64; nports];
    for l in r.lines() {
        let l = l?;
        if l.starts_with("//") {
            continue;
        }
        let t: Vec<&str> = l.split(' ').collect();
        for (k, c) in n.iter_mut().enumerate() {
            let (v, r) = (t.get(1 + 3 * k), t.get(3 + 3 * k));
            *c += (v == Some(&"1") && r == Some(&"1")) as u64;
        }
    }
    Ok(n)
}

fn range(w: u32) -> String {
    format!("[{}:0]", w.max(1) - 1)
}

/// The testbench module `tb_<module>` for `d`.
pub fn emit_testbench(d: &UnitDecl, g: &TbGen) -> String {
    let mut v = String::new();
    let w = &mut v;
    let m = d.module;
    let np = d.ports.len();
    let maxw = d.ports.iter().map(|p| p.width.max(1)).max().unwrap_or(1);
    let _ = writeln!(
        w,
        "// Generated by dualstream from {} (`dualstream hdl --testbench {m}`); do not edit.",
        d.source
    );
    let _ = writeln!(
        w,
        "// A self-checking testbench of module {m}, {} mode: it replays the environment's side of",
        g.mode.name()
    );
    let _ = writeln!(
        w,
        "// a vector file (+vectors=FILE, default below) and checks the unit's side (docs/rtl.md)."
    );
    let _ = writeln!(
        w,
        "// Any module named {m} with this interface: the skeleton hdl/{m}.v or an implementation."
    );
    let _ = writeln!(w, "module tb_{m};");
    let _ = writeln!(w, "    localparam integer NP = {np};");
    let _ = writeln!(w, "    localparam integer MAXW = {maxw};");
    let _ = writeln!(w, "    logic clk = 1'b0;");
    let _ = writeln!(w, "    logic rst = 1'b1;");
    let _ = writeln!(w, "    always #5 clk <= ~clk;");
    for p in &d.ports {
        let _ = writeln!(
            w,
            "    logic {n}_valid;\n    logic {n}_ready;\n    logic {r} {n}_data;",
            n = p.name,
            r = range(p.width)
        );
    }
    let params: Vec<String> = g.params.iter().map(|(n, v)| format!(".{n}({v})")).collect();
    let ps = if params.is_empty() {
        String::new()
    } else {
        format!(" #({})", params.join(", "))
    };
    let _ = writeln!(w, "    {m}{ps} dut (");
    let mut conns = vec![
        "        .clk(clk)".to_string(),
        "        .rst(rst)".to_string(),
    ];
    for p in &d.ports {
        for s in ["valid", "ready"] {
            conns.push(format!("        .{n}_{s}({n}_{s})", n = p.name));
        }
        if p.width > 0 {
            conns.push(format!("        .{n}_data({n}_data)", n = p.name));
        }
    }
    let _ = writeln!(w, "{}\n    );", conns.join(",\n"));
    let _ = writeln!(
        w,
        r#"
    // The row read: cycle, then per port valid, data, ready.
    integer fd;
    logic rd_ok;
    logic [63:0] rd_c;
    logic rd_v [0:NP-1];
    logic rd_r [0:NP-1];
    logic [MAXW-1:0] rd_d [0:NP-1];
    logic [63:0] tc;
    logic tv;
    logic tr;
    logic [MAXW-1:0] td;
    logic [8*1024-1:0] path;
    logic [8*1024-1:0] wave;
    logic [8*1024-1:0] line;
    integer max_mismatches;
    integer timeout;
    integer mismatches;
    integer checked;
    integer transfers;
    integer got;
    integer ch;
    logic [63:0] cyc;

    task automatic open_vectors;
        fd = $fopen(path, "r");
        if (fd == 0) $fatal(1, "cannot open the vector file %0s; give +vectors=FILE", path);
        ch = $fgetc(fd);
        while (ch == "/") begin
            got = $fgets(line, fd);
            ch = $fgetc(fd);
        end
        got = $ungetc(ch, fd);
    endtask

    task automatic read_row;
        // Icarus scans into plain variables only: through tc, tv, td, tr.
        got = $fscanf(fd, "%h", tc);
        rd_c = tc;
        rd_ok = (got == 1);
        if (rd_ok) begin
            for (int k = 0; k < NP; k++) begin
                got = $fscanf(fd, "%h %h %h", tv, td, tr);
                if (got != 3) $fatal(1, "the vector file %0s is cut short at cycle %0d", path, tc);
                rd_v[k] = tv;
                rd_d[k] = td;
                rd_r[k] = tr;
            end
        end
    endtask

    task automatic mismatch;
        mismatches = mismatches + 1;
    endtask

    task automatic summary;
        $display("tb_{m}: {mode} mode: %0d vectors checked, %0d transfers, %0d mismatches", checked, transfers, mismatches);
        if (mismatches >= max_mismatches) $display("tb_{m}: stopped after %0d mismatches (+max_mismatches=N)", mismatches);
        if (mismatches != 0) $fatal(1, "tb_{m}: FAIL");
        $display("tb_{m}: PASS");
        $finish;
    endtask"#,
        mode = g.mode.name()
    );
    // Field-by-field reports, one task per port.
    for p in &d.ports {
        let mut leaves = Vec::new();
        p.ty.leaves("", 0, &mut leaves);
        let r = range(p.width);
        let _ = writeln!(
            w,
            "\n    task automatic diff_{n}(input logic {r} e, input logic {r} a);",
            n = p.name
        );
        for (path, off, width) in leaves {
            if width == 0 {
                continue;
            }
            let field = if path.is_empty() {
                String::new()
            } else {
                format!(".{path}")
            };
            let sl = format!("[{}:{off}]", off + width - 1);
            let _ = writeln!(
                w,
                "        if (e{sl} !== a{sl}) $display(\"cycle %0d port {n}: expected {field}=%h got %h\", cyc, e{sl}, a{sl});",
                n = p.name
            );
        }
        let _ = writeln!(w, "    endtask");
    }
    let idx = |k: usize| format!("{k}");
    let data = |k: usize, width: u32| format!("rd_d[{k}][{}:0]", width.max(1) - 1);
    let sdata = |k: usize, width: u32| format!("sd[base[{k}] + pos[{k}]][{}:0]", width.max(1) - 1);
    let _ = writeln!(w);
    match g.mode {
        TbMode::Cycle => {
            let _ = writeln!(w, "    initial begin");
            emit_init(w, g, d);
            let _ = writeln!(w, "        read_row();");
            let _ = writeln!(
                w,
                "        while (rd_ok && mismatches < max_mismatches) begin\n            cyc = rd_c;"
            );
            for (k, p) in d.ports.iter().enumerate() {
                let n = p.name;
                match p.dir {
                    PortDir::In => {
                        let _ = writeln!(w, "            {n}_valid = rd_v[{}];", idx(k));
                        let _ = writeln!(w, "            {n}_data = {};", data(k, p.width));
                    }
                    PortDir::Out => {
                        let _ = writeln!(w, "            {n}_ready = rd_r[{}];", idx(k));
                    }
                }
            }
            let _ = writeln!(w, "            #3;");
            for (k, p) in d.ports.iter().enumerate() {
                let n = p.name;
                match p.dir {
                    PortDir::In => {
                        let _ = writeln!(
                            w,
                            "            if ({n}_ready !== rd_r[{k}]) begin\n                $display(\"cycle %0d port {n}: expected ready=%0d got %b\", cyc, rd_r[{k}], {n}_ready);\n                mismatch();\n            end"
                        );
                    }
                    PortDir::Out => {
                        let _ = writeln!(
                            w,
                            "            if ({n}_valid !== rd_v[{k}]) begin\n                $display(\"cycle %0d port {n}: expected valid=%0d got %b\", cyc, rd_v[{k}], {n}_valid);\n                mismatch();\n            end else if (rd_v[{k}] && {n}_data !== {e}) begin\n                diff_{n}({e}, {n}_data);\n                mismatch();\n            end\n            if (rd_v[{k}] && rd_r[{k}]) transfers = transfers + 1;",
                            e = data(k, p.width)
                        );
                    }
                }
            }
            let _ = writeln!(
                w,
                "            checked = checked + 1;\n            @(posedge clk);\n            #1;\n            read_row();\n        end\n        summary();\n    end"
            );
        }
        TbMode::Order => {
            // Each port's transfers, read in a first pass over the vectors.
            let caps: Vec<u64> = (0..np)
                .map(|k| g.fires.get(k).copied().unwrap_or(0))
                .collect();
            let total: u64 = caps.iter().sum::<u64>().max(1);
            let _ = writeln!(
                w,
                "    // Per port: its transfers in the model's order (sd from base[k], cnt[k] of\n    // them, the next at pos[k]); an input's payload offered and not yet taken.\n    logic [MAXW-1:0] sd [0:{}];\n    integer base [0:NP-1];\n    integer cap [0:NP-1];\n    integer cnt [0:NP-1];\n    integer pos [0:NP-1];\n    logic held [0:NP-1];\n    integer owed;\n    integer drain;\n\n    initial begin",
                total - 1
            );
            let mut at = 0;
            for (k, c) in caps.iter().enumerate() {
                let _ = writeln!(w, "        base[{k}] = {at};\n        cap[{k}] = {c};");
                at += c;
            }
            emit_init(w, g, d);
            let _ = writeln!(
                w,
                "        for (int k = 0; k < NP; k++) begin\n            cnt[k] = 0;\n            pos[k] = 0;\n            held[k] = 1'b0;\n        end\n        read_row();\n        while (rd_ok) begin\n            for (int k = 0; k < NP; k++) begin\n                if (rd_v[k] && rd_r[k]) begin\n                    if (cnt[k] == cap[k]) $fatal(1, \"the vectors %0s hold more transfers than the testbench was generated for; generate it for them (dualstream hdl --testbench ... --vectors)\", path);\n                    sd[base[k] + cnt[k]] = rd_d[k];\n                    cnt[k] = cnt[k] + 1;\n                end\n            end\n            read_row();\n        end\n        $fclose(fd);\n        open_vectors();\n        read_row();\n        drain = 0;\n        owed = 1;\n        while ((rd_ok || (owed != 0 && drain < timeout)) && mismatches < max_mismatches) begin\n            cyc = rd_ok ? rd_c : cyc + 1;"
            );
            for (k, p) in d.ports.iter().enumerate() {
                let n = p.name;
                match p.dir {
                    PortDir::In => {
                        let _ = writeln!(
                            w,
                            "            {n}_valid = pos[{k}] < cnt[{k}] && (held[{k}] || !rd_ok || rd_v[{k}]);\n            {n}_data = {};",
                            sdata(k, p.width)
                        );
                    }
                    PortDir::Out => {
                        let _ = writeln!(w, "            {n}_ready = rd_ok ? rd_r[{k}] : 1'b1;");
                    }
                }
            }
            let _ = writeln!(w, "            #3;");
            for (k, p) in d.ports.iter().enumerate() {
                let n = p.name;
                match p.dir {
                    PortDir::In => {
                        let _ = writeln!(
                            w,
                            "            if ({n}_valid && {n}_ready === 1'b1) begin\n                held[{k}] = 1'b0;\n                pos[{k}] = pos[{k}] + 1;\n            end else held[{k}] = {n}_valid;"
                        );
                    }
                    PortDir::Out => {
                        let _ = writeln!(
                            w,
                            "            if ({n}_valid === 1'b1 && {n}_ready) begin\n                if (pos[{k}] == cnt[{k}]) begin\n                    $display(\"cycle %0d port {n}: a transfer the model did not make\", cyc);\n                    mismatch();\n                end else begin\n                    if ({n}_data !== {e}) begin\n                        diff_{n}({e}, {n}_data);\n                        mismatch();\n                    end\n                    transfers = transfers + 1;\n                    pos[{k}] = pos[{k}] + 1;\n                end\n            end",
                            e = sdata(k, p.width)
                        );
                    }
                }
            }
            let outs: Vec<String> = d
                .ports
                .iter()
                .enumerate()
                .filter(|(_, p)| p.dir == PortDir::Out)
                .map(|(k, _)| format!("pos[{k}] < cnt[{k}]"))
                .collect();
            let owed = if outs.is_empty() {
                "1'b0".to_string()
            } else {
                outs.join(" || ")
            };
            let _ = writeln!(
                w,
                "            owed = ({owed}) ? 1 : 0;\n            if (rd_ok) checked = checked + 1;\n            else drain = drain + 1;\n            @(posedge clk);\n            #1;\n            if (rd_ok) read_row();\n        end"
            );
            for (k, p) in d.ports.iter().enumerate() {
                if p.dir == PortDir::Out {
                    let _ = writeln!(
                        w,
                        "        if (pos[{k}] < cnt[{k}] && mismatches < max_mismatches) begin\n            $display(\"cycle %0d port {n}: %0d of the model's %0d transfers not delivered within %0d cycles after the vectors (+timeout=N)\", cyc, cnt[{k}] - pos[{k}], cnt[{k}], timeout);\n            mismatch();\n        end",
                        n = p.name
                    );
                }
            }
            let _ = writeln!(w, "        summary();\n    end");
        }
    }
    // Verilator's unused check: the bits of the rows a mode does not read.
    let _ = writeln!(
        w,
        "    wire _unused_ok = &{{1'b0, ^line, ^timeout, ^wave, 1'b0}};\nendmodule"
    );
    v
}

fn emit_init(w: &mut String, g: &TbGen, d: &UnitDecl) {
    let _ = writeln!(
        w,
        "        if (!$value$plusargs(\"vectors=%s\", path)) path = \"{}\";",
        g.vectors.replace('\\', "\\\\").replace('"', "\\\"")
    );
    let _ = writeln!(
        w,
        "        if (!$value$plusargs(\"max_mismatches=%d\", max_mismatches)) max_mismatches = {};",
        g.max_mismatches.max(1)
    );
    let _ = writeln!(
        w,
        "        if (!$value$plusargs(\"timeout=%d\", timeout)) timeout = {};",
        g.timeout
    );
    // A waveform of the unit under test (+wave=FILE; Verilator needs
    // --trace or --trace-fst): vector cycle n is the clock period from
    // time 10n + 25 (three reset periods first).
    let _ = writeln!(
        w,
        "        if ($value$plusargs(\"wave=%s\", wave)) begin\n            $dumpfile(wave);\n            $dumpvars(0, dut);\n        end"
    );
    let _ = writeln!(
        w,
        "        mismatches = 0;\n        checked = 0;\n        transfers = 0;\n        cyc = 0;"
    );
    let _ = writeln!(w, "        open_vectors();");
    for p in &d.ports {
        match p.dir {
            PortDir::In => {
                let _ = writeln!(
                    w,
                    "        {n}_valid = 1'b0;\n        {n}_data = '0;",
                    n = p.name
                );
            }
            PortDir::Out => {
                let _ = writeln!(w, "        {}_ready = 1'b0;", p.name);
            }
        }
    }
    let _ = writeln!(
        w,
        "        // Reset: three edges with rst high, released after the last; cycle 0 follows.\n        repeat (3) @(posedge clk);\n        #1;\n        rst = 1'b0;"
    );
}
