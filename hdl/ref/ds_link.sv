// Hand-written reference RTL (not generated; `dualstream hdl` leaves hdl/ref/ alone).
//
// ds_link: the model's registered link (src/rtl/link.rs) as a FIFO of DEPTH
// entries between two units on one clock.
//   - push side (an input port of the link): push_ready is "the FIFO has room as
//     the producer sees it this cycle": DEPTH minus the entries held at the start
//     of the cycle, visible or not. A pop is seen by the producer the next cycle
//     (the credit is registered); a push of this cycle counts from the next one.
//   - a payload pushed in cycle t (push_valid & push_ready) is visible on the pop
//     side from cycle t + DELAY on (DELAY >= 1: no combinational path).
//   - pop side (an output port): pop_valid while the oldest entry is visible,
//     pop_data is that entry, a pop is pop_valid & pop_ready.
//   - at most one push and one pop per cycle; full throughput needs
//     DEPTH >= DELAY + 1.
// Storage is not reset (yosys infers a memory); the counters and the delay line
// are.
module ds_link #(
    parameter integer WIDTH = 1,
    parameter integer DEPTH = 2,
    parameter integer DELAY = 1
) (
    input  wire clk,
    input  wire rst,
    input  wire push_valid,
    output wire push_ready,
    input  wire [WIDTH-1:0] push_data,
    output wire pop_valid,
    input  wire pop_ready,
    output wire [WIDTH-1:0] pop_data
);
    localparam integer CW = $clog2(DEPTH + 1);
    localparam integer AW = (DEPTH > 1) ? $clog2(DEPTH) : 1;
    localparam [AW-1:0] LAST = AW'(DEPTH - 1);
    localparam [CW-1:0] FULL = CW'(DEPTH);

    reg [WIDTH-1:0] mem [0:DEPTH-1];
    reg [AW-1:0] wr_ptr;
    reg [AW-1:0] rd_ptr;
    // Entries held (the producer's view) and entries visible (the consumer's).
    reg [CW-1:0] held;
    reg [CW-1:0] shown;

    wire push = push_valid && push_ready;
    wire pop = pop_valid && pop_ready;
    // A push that becomes visible at the next edge: this cycle's (DELAY 1) or
    // the one of DELAY-1 cycles ago.
    wire arrive;

    generate
        if (DELAY == 1) begin : g_now
            assign arrive = push;
        end else if (DELAY == 2) begin : g_one
            reg pushed;
            always_ff @(posedge clk) begin
                if (rst) pushed <= 1'b0;
                else pushed <= push;
            end
            assign arrive = pushed;
        end else begin : g_line
            // in_flight[k]: whether there was a push k+1 cycles ago.
            reg [DELAY-2:0] in_flight;
            always_ff @(posedge clk) begin
                if (rst) in_flight <= '0;
                else in_flight <= {in_flight[DELAY-3:0], push};
            end
            assign arrive = in_flight[DELAY-2];
        end
    endgenerate

    assign push_ready = held != FULL;
    assign pop_valid = shown != '0;
    assign pop_data = mem[rd_ptr];

    always_ff @(posedge clk) begin
        if (push) mem[wr_ptr] <= push_data;
    end

    always_ff @(posedge clk) begin
        if (rst) begin
            wr_ptr <= '0;
            rd_ptr <= '0;
            held <= '0;
            shown <= '0;
        end else begin
            if (push) wr_ptr <= (wr_ptr == LAST) ? '0 : wr_ptr + 1'b1;
            if (pop) rd_ptr <= (rd_ptr == LAST) ? '0 : rd_ptr + 1'b1;
            held <= held + CW'(push) - CW'(pop);
            shown <= shown + CW'(arrive) - CW'(pop);
        end
    end
endmodule
