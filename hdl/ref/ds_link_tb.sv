// Hand-written testbench (not generated): replays a ds_link's vectors (the
// format of docs/rtl.md, "Vectors": `// ...` header lines, then one row per
// cycle: the cycle, then `valid data ready` for the port `push` (an input of
// the link) and for `pop` (an output)) into ds_link and checks it cycle for
// cycle. Drives push_valid, push_data, pop_ready; checks push_ready,
// pop_valid, and pop_data where pop_valid is 1.
//
//   iverilog -g2012 -P ds_link_tb.WIDTH=32 -P ds_link_tb.DEPTH=2 -P ds_link_tb.DELAY=1 \
//       -o tb hdl/ref/ds_link.sv hdl/ref/ds_link_tb.sv && vvp tb +vectors=link.vec
//
// Prints `PASS <rows>` or one `MISMATCH` line per wrong signal (at most 20),
// then `FAIL <count>`, and ends with $fatal on a mismatch (non-zero exit);
// +verbose shows the header.
module ds_link_tb #(
    parameter integer WIDTH = 32,
    parameter integer DEPTH = 2,
    parameter integer DELAY = 1
);
    reg clk = 1'b0;
    reg rst = 1'b1;
    reg push_valid = 1'b0;
    reg [WIDTH-1:0] push_data = '0;
    reg pop_ready = 1'b0;
    wire push_ready;
    wire pop_valid;
    wire [WIDTH-1:0] pop_data;

    ds_link #(.WIDTH(WIDTH), .DEPTH(DEPTH), .DELAY(DELAY)) dut (
        .clk(clk),
        .rst(rst),
        .push_valid(push_valid),
        .push_ready(push_ready),
        .push_data(push_data),
        .pop_valid(pop_valid),
        .pop_ready(pop_ready),
        .pop_data(pop_data)
    );

    integer fd;
    integer got;
    integer rows;
    integer bad;
    reg [63:0] cycle;
    reg i_valid;
    reg [WIDTH-1:0] i_data;
    reg i_ready;
    reg o_valid;
    reg [WIDTH-1:0] o_data;
    reg o_ready;
    integer c;
    reg [8*200-1:0] line; // a header line
    reg [8*256-1:0] path;

    task automatic mismatch(input [8*16-1:0] what, input [WIDTH-1:0] want, input [WIDTH-1:0] have);
        bad = bad + 1;
        if (bad <= 20) $display("MISMATCH cycle %0d %0s: expected %h, got %h", cycle, what, want, have);
    endtask

    initial begin
        if (!$value$plusargs("vectors=%s", path)) $fatal(1, "give +vectors=<file>");
        fd = $fopen(path, "r");
        if (fd == 0) $fatal(1, "cannot open %0s", path);
        rows = 0;
        bad = 0;
        // Two cycles of reset; row 0 is the first cycle after it (from_reset 1).
        #1 clk = 1'b1;
        #1 clk = 1'b0;
        #1 clk = 1'b1;
        #1 clk = 1'b0;
        rst = 1'b0;
        c = $fgetc(fd);
        while (c != -1) begin
            if (c == "/") begin
                got = $fgets(line, fd); // a header line: shown with +verbose
                if ($test$plusargs("verbose")) $write("/%0s", line);
            end else if (c == "\n" || c == " ") begin
                // between rows
            end else begin
                got = $ungetc(c, fd);
                got = $fscanf(fd, "%h %h %h %h %h %h %h", cycle, i_valid, i_data, i_ready,
                              o_valid, o_data, o_ready);
                if (got != 7) $fatal(1, "bad vector row after cycle %0d", cycle);
                // The environment's side, for the cycle that starts now.
                push_valid = i_valid;
                push_data = i_data;
                pop_ready = o_ready;
                #1;
                // The link's side, sampled at the end of the cycle.
                if (push_ready !== i_ready) mismatch("push_ready", WIDTH'(i_ready), WIDTH'(push_ready));
                if (pop_valid !== o_valid) mismatch("pop_valid", WIDTH'(o_valid), WIDTH'(pop_valid));
                else if (o_valid && pop_data !== o_data) mismatch("pop_data", o_data, pop_data);
                rows = rows + 1;
                clk = 1'b1;
                #1 clk = 1'b0;
            end
            c = $fgetc(fd);
        end
        $fclose(fd);
        if (bad != 0) begin
            $display("FAIL %0d", bad);
            $fatal(1, "%0d mismatches", bad);
        end
        $display("PASS %0d", rows);
        $finish;
    end
endmodule
