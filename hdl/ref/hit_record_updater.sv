// Hand-written reference RTL of the hit record updater; not generated (the
// generated skeleton is hdl/hit_record_updater.v). It behaves as the model,
// src/units/hit_record_updater.rs, cycle for cycle: checked against vectors
// captured from the model (docs/rtl.md, "Reference RTL: the hit record updater").
//
// Per cycle, in the model's order, all combinational on the registers at the
// start of the cycle and this cycle's inputs:
//   1. a memory answer (always taken): a written record retires its index;
//      a read record is compared with the in-flight update, which becomes a
//      decided write if strictly closer (t, then triangle id), else retires;
//   2. one memory request while the request link has room: the oldest decided
//      write (bypassing the write queue when it is empty), else, with fewer
//      than IN_FLIGHT read-compare-writes, a read of the oldest queued update
//      whose index is not in flight (it leaves the queue);
//   3. one update accepted over the TMS hit ports, round-robin from
//      cycle mod TMS: it merges into the queued update of its index (the
//      closer wins) or, with room, joins the queue's tail; with the queue full
//      only ports whose index is queued are eligible.
// Storage (the queue, the in-flight table, the write queue) is not reset word
// by word: counts and valid bits are.
//
// Planted faults for the checker's own tests: `HRU_WRONG_MERGE` keeps the
// farther hit on a merge; `HRU_WRONG_LATENCY` gives the memory request one
// cycle more latency.
module hit_record_updater
`ifndef YOSYS
    import ds_pkg::*;
`endif
#(
    parameter integer TMS = 128,
    parameter integer HITS_BASE = 1122304,
    parameter integer QUEUE = 64,
    parameter integer IN_FLIGHT = 32
) (
    input  wire clk,
    input  wire rst,
    input  wire mem_resp_valid,
    output wire mem_resp_ready,
    input  mem_line_resp_t mem_resp_data,
    output wire mem_req_valid,
    input  wire mem_req_ready,
    output mem_line_req_t mem_req_data,
    input  wire hit_0_valid,
    output wire hit_0_ready,
    input  hit_update_t hit_0_data,
    input  wire hit_1_valid,
    output wire hit_1_ready,
    input  hit_update_t hit_1_data,
    input  wire hit_2_valid,
    output wire hit_2_ready,
    input  hit_update_t hit_2_data,
    input  wire hit_3_valid,
    output wire hit_3_ready,
    input  hit_update_t hit_3_data,
    input  wire hit_4_valid,
    output wire hit_4_ready,
    input  hit_update_t hit_4_data,
    input  wire hit_5_valid,
    output wire hit_5_ready,
    input  hit_update_t hit_5_data,
    input  wire hit_6_valid,
    output wire hit_6_ready,
    input  hit_update_t hit_6_data,
    input  wire hit_7_valid,
    output wire hit_7_ready,
    input  hit_update_t hit_7_data,
    input  wire hit_8_valid,
    output wire hit_8_ready,
    input  hit_update_t hit_8_data,
    input  wire hit_9_valid,
    output wire hit_9_ready,
    input  hit_update_t hit_9_data,
    input  wire hit_10_valid,
    output wire hit_10_ready,
    input  hit_update_t hit_10_data,
    input  wire hit_11_valid,
    output wire hit_11_ready,
    input  hit_update_t hit_11_data,
    input  wire hit_12_valid,
    output wire hit_12_ready,
    input  hit_update_t hit_12_data,
    input  wire hit_13_valid,
    output wire hit_13_ready,
    input  hit_update_t hit_13_data,
    input  wire hit_14_valid,
    output wire hit_14_ready,
    input  hit_update_t hit_14_data,
    input  wire hit_15_valid,
    output wire hit_15_ready,
    input  hit_update_t hit_15_data,
    input  wire hit_16_valid,
    output wire hit_16_ready,
    input  hit_update_t hit_16_data,
    input  wire hit_17_valid,
    output wire hit_17_ready,
    input  hit_update_t hit_17_data,
    input  wire hit_18_valid,
    output wire hit_18_ready,
    input  hit_update_t hit_18_data,
    input  wire hit_19_valid,
    output wire hit_19_ready,
    input  hit_update_t hit_19_data,
    input  wire hit_20_valid,
    output wire hit_20_ready,
    input  hit_update_t hit_20_data,
    input  wire hit_21_valid,
    output wire hit_21_ready,
    input  hit_update_t hit_21_data,
    input  wire hit_22_valid,
    output wire hit_22_ready,
    input  hit_update_t hit_22_data,
    input  wire hit_23_valid,
    output wire hit_23_ready,
    input  hit_update_t hit_23_data,
    input  wire hit_24_valid,
    output wire hit_24_ready,
    input  hit_update_t hit_24_data,
    input  wire hit_25_valid,
    output wire hit_25_ready,
    input  hit_update_t hit_25_data,
    input  wire hit_26_valid,
    output wire hit_26_ready,
    input  hit_update_t hit_26_data,
    input  wire hit_27_valid,
    output wire hit_27_ready,
    input  hit_update_t hit_27_data,
    input  wire hit_28_valid,
    output wire hit_28_ready,
    input  hit_update_t hit_28_data,
    input  wire hit_29_valid,
    output wire hit_29_ready,
    input  hit_update_t hit_29_data,
    input  wire hit_30_valid,
    output wire hit_30_ready,
    input  hit_update_t hit_30_data,
    input  wire hit_31_valid,
    output wire hit_31_ready,
    input  hit_update_t hit_31_data,
    input  wire hit_32_valid,
    output wire hit_32_ready,
    input  hit_update_t hit_32_data,
    input  wire hit_33_valid,
    output wire hit_33_ready,
    input  hit_update_t hit_33_data,
    input  wire hit_34_valid,
    output wire hit_34_ready,
    input  hit_update_t hit_34_data,
    input  wire hit_35_valid,
    output wire hit_35_ready,
    input  hit_update_t hit_35_data,
    input  wire hit_36_valid,
    output wire hit_36_ready,
    input  hit_update_t hit_36_data,
    input  wire hit_37_valid,
    output wire hit_37_ready,
    input  hit_update_t hit_37_data,
    input  wire hit_38_valid,
    output wire hit_38_ready,
    input  hit_update_t hit_38_data,
    input  wire hit_39_valid,
    output wire hit_39_ready,
    input  hit_update_t hit_39_data,
    input  wire hit_40_valid,
    output wire hit_40_ready,
    input  hit_update_t hit_40_data,
    input  wire hit_41_valid,
    output wire hit_41_ready,
    input  hit_update_t hit_41_data,
    input  wire hit_42_valid,
    output wire hit_42_ready,
    input  hit_update_t hit_42_data,
    input  wire hit_43_valid,
    output wire hit_43_ready,
    input  hit_update_t hit_43_data,
    input  wire hit_44_valid,
    output wire hit_44_ready,
    input  hit_update_t hit_44_data,
    input  wire hit_45_valid,
    output wire hit_45_ready,
    input  hit_update_t hit_45_data,
    input  wire hit_46_valid,
    output wire hit_46_ready,
    input  hit_update_t hit_46_data,
    input  wire hit_47_valid,
    output wire hit_47_ready,
    input  hit_update_t hit_47_data,
    input  wire hit_48_valid,
    output wire hit_48_ready,
    input  hit_update_t hit_48_data,
    input  wire hit_49_valid,
    output wire hit_49_ready,
    input  hit_update_t hit_49_data,
    input  wire hit_50_valid,
    output wire hit_50_ready,
    input  hit_update_t hit_50_data,
    input  wire hit_51_valid,
    output wire hit_51_ready,
    input  hit_update_t hit_51_data,
    input  wire hit_52_valid,
    output wire hit_52_ready,
    input  hit_update_t hit_52_data,
    input  wire hit_53_valid,
    output wire hit_53_ready,
    input  hit_update_t hit_53_data,
    input  wire hit_54_valid,
    output wire hit_54_ready,
    input  hit_update_t hit_54_data,
    input  wire hit_55_valid,
    output wire hit_55_ready,
    input  hit_update_t hit_55_data,
    input  wire hit_56_valid,
    output wire hit_56_ready,
    input  hit_update_t hit_56_data,
    input  wire hit_57_valid,
    output wire hit_57_ready,
    input  hit_update_t hit_57_data,
    input  wire hit_58_valid,
    output wire hit_58_ready,
    input  hit_update_t hit_58_data,
    input  wire hit_59_valid,
    output wire hit_59_ready,
    input  hit_update_t hit_59_data,
    input  wire hit_60_valid,
    output wire hit_60_ready,
    input  hit_update_t hit_60_data,
    input  wire hit_61_valid,
    output wire hit_61_ready,
    input  hit_update_t hit_61_data,
    input  wire hit_62_valid,
    output wire hit_62_ready,
    input  hit_update_t hit_62_data,
    input  wire hit_63_valid,
    output wire hit_63_ready,
    input  hit_update_t hit_63_data,
    input  wire hit_64_valid,
    output wire hit_64_ready,
    input  hit_update_t hit_64_data,
    input  wire hit_65_valid,
    output wire hit_65_ready,
    input  hit_update_t hit_65_data,
    input  wire hit_66_valid,
    output wire hit_66_ready,
    input  hit_update_t hit_66_data,
    input  wire hit_67_valid,
    output wire hit_67_ready,
    input  hit_update_t hit_67_data,
    input  wire hit_68_valid,
    output wire hit_68_ready,
    input  hit_update_t hit_68_data,
    input  wire hit_69_valid,
    output wire hit_69_ready,
    input  hit_update_t hit_69_data,
    input  wire hit_70_valid,
    output wire hit_70_ready,
    input  hit_update_t hit_70_data,
    input  wire hit_71_valid,
    output wire hit_71_ready,
    input  hit_update_t hit_71_data,
    input  wire hit_72_valid,
    output wire hit_72_ready,
    input  hit_update_t hit_72_data,
    input  wire hit_73_valid,
    output wire hit_73_ready,
    input  hit_update_t hit_73_data,
    input  wire hit_74_valid,
    output wire hit_74_ready,
    input  hit_update_t hit_74_data,
    input  wire hit_75_valid,
    output wire hit_75_ready,
    input  hit_update_t hit_75_data,
    input  wire hit_76_valid,
    output wire hit_76_ready,
    input  hit_update_t hit_76_data,
    input  wire hit_77_valid,
    output wire hit_77_ready,
    input  hit_update_t hit_77_data,
    input  wire hit_78_valid,
    output wire hit_78_ready,
    input  hit_update_t hit_78_data,
    input  wire hit_79_valid,
    output wire hit_79_ready,
    input  hit_update_t hit_79_data,
    input  wire hit_80_valid,
    output wire hit_80_ready,
    input  hit_update_t hit_80_data,
    input  wire hit_81_valid,
    output wire hit_81_ready,
    input  hit_update_t hit_81_data,
    input  wire hit_82_valid,
    output wire hit_82_ready,
    input  hit_update_t hit_82_data,
    input  wire hit_83_valid,
    output wire hit_83_ready,
    input  hit_update_t hit_83_data,
    input  wire hit_84_valid,
    output wire hit_84_ready,
    input  hit_update_t hit_84_data,
    input  wire hit_85_valid,
    output wire hit_85_ready,
    input  hit_update_t hit_85_data,
    input  wire hit_86_valid,
    output wire hit_86_ready,
    input  hit_update_t hit_86_data,
    input  wire hit_87_valid,
    output wire hit_87_ready,
    input  hit_update_t hit_87_data,
    input  wire hit_88_valid,
    output wire hit_88_ready,
    input  hit_update_t hit_88_data,
    input  wire hit_89_valid,
    output wire hit_89_ready,
    input  hit_update_t hit_89_data,
    input  wire hit_90_valid,
    output wire hit_90_ready,
    input  hit_update_t hit_90_data,
    input  wire hit_91_valid,
    output wire hit_91_ready,
    input  hit_update_t hit_91_data,
    input  wire hit_92_valid,
    output wire hit_92_ready,
    input  hit_update_t hit_92_data,
    input  wire hit_93_valid,
    output wire hit_93_ready,
    input  hit_update_t hit_93_data,
    input  wire hit_94_valid,
    output wire hit_94_ready,
    input  hit_update_t hit_94_data,
    input  wire hit_95_valid,
    output wire hit_95_ready,
    input  hit_update_t hit_95_data,
    input  wire hit_96_valid,
    output wire hit_96_ready,
    input  hit_update_t hit_96_data,
    input  wire hit_97_valid,
    output wire hit_97_ready,
    input  hit_update_t hit_97_data,
    input  wire hit_98_valid,
    output wire hit_98_ready,
    input  hit_update_t hit_98_data,
    input  wire hit_99_valid,
    output wire hit_99_ready,
    input  hit_update_t hit_99_data,
    input  wire hit_100_valid,
    output wire hit_100_ready,
    input  hit_update_t hit_100_data,
    input  wire hit_101_valid,
    output wire hit_101_ready,
    input  hit_update_t hit_101_data,
    input  wire hit_102_valid,
    output wire hit_102_ready,
    input  hit_update_t hit_102_data,
    input  wire hit_103_valid,
    output wire hit_103_ready,
    input  hit_update_t hit_103_data,
    input  wire hit_104_valid,
    output wire hit_104_ready,
    input  hit_update_t hit_104_data,
    input  wire hit_105_valid,
    output wire hit_105_ready,
    input  hit_update_t hit_105_data,
    input  wire hit_106_valid,
    output wire hit_106_ready,
    input  hit_update_t hit_106_data,
    input  wire hit_107_valid,
    output wire hit_107_ready,
    input  hit_update_t hit_107_data,
    input  wire hit_108_valid,
    output wire hit_108_ready,
    input  hit_update_t hit_108_data,
    input  wire hit_109_valid,
    output wire hit_109_ready,
    input  hit_update_t hit_109_data,
    input  wire hit_110_valid,
    output wire hit_110_ready,
    input  hit_update_t hit_110_data,
    input  wire hit_111_valid,
    output wire hit_111_ready,
    input  hit_update_t hit_111_data,
    input  wire hit_112_valid,
    output wire hit_112_ready,
    input  hit_update_t hit_112_data,
    input  wire hit_113_valid,
    output wire hit_113_ready,
    input  hit_update_t hit_113_data,
    input  wire hit_114_valid,
    output wire hit_114_ready,
    input  hit_update_t hit_114_data,
    input  wire hit_115_valid,
    output wire hit_115_ready,
    input  hit_update_t hit_115_data,
    input  wire hit_116_valid,
    output wire hit_116_ready,
    input  hit_update_t hit_116_data,
    input  wire hit_117_valid,
    output wire hit_117_ready,
    input  hit_update_t hit_117_data,
    input  wire hit_118_valid,
    output wire hit_118_ready,
    input  hit_update_t hit_118_data,
    input  wire hit_119_valid,
    output wire hit_119_ready,
    input  hit_update_t hit_119_data,
    input  wire hit_120_valid,
    output wire hit_120_ready,
    input  hit_update_t hit_120_data,
    input  wire hit_121_valid,
    output wire hit_121_ready,
    input  hit_update_t hit_121_data,
    input  wire hit_122_valid,
    output wire hit_122_ready,
    input  hit_update_t hit_122_data,
    input  wire hit_123_valid,
    output wire hit_123_ready,
    input  hit_update_t hit_123_data,
    input  wire hit_124_valid,
    output wire hit_124_ready,
    input  hit_update_t hit_124_data,
    input  wire hit_125_valid,
    output wire hit_125_ready,
    input  hit_update_t hit_125_data,
    input  wire hit_126_valid,
    output wire hit_126_ready,
    input  hit_update_t hit_126_data,
    input  wire hit_127_valid,
    output wire hit_127_ready,
    input  hit_update_t hit_127_data
);

    // The interface's hit ports (the skeleton's); TMS of them take part.
    localparam integer PORTS = 128;
    localparam integer RRW = (TMS > 1) ? $clog2(TMS) : 1;
    localparam integer WPW = (IN_FLIGHT > 1) ? $clog2(IN_FLIGHT) : 1;
    localparam logic [63:0] BASE = 64'(HITS_BASE);
    localparam logic [15:0] IN_FLIGHT_N = IN_FLIGHT[15:0];
    localparam logic [WPW-1:0] W_LAST = WPW'(IN_FLIGHT - 1);

    // ---- The declared registers (the model's `queued`, `in_flight`) ----
    reg [15:0] queued;
    reg [15:0] in_flight;

    // ---- Storage ----
    // Pending updates in arrival order, positions 0 .. queued-1 (a
    // collapsing queue); q_blk: the entry's index is in flight.
    logic [31:0] q_idx [0:QUEUE-1];
    logic [127:0] q_hit [0:QUEUE-1];
    logic [QUEUE-1:0] q_blk;
    // Read-compare-writes in flight, unordered slots.
    logic [IN_FLIGHT-1:0] f_val;
    logic [31:0] f_idx [0:IN_FLIGHT-1];
    logic [127:0] f_hit [0:IN_FLIGHT-1];
    // Decided writes waiting for the memory port (a ring).
    logic [63:0] w_addr [0:IN_FLIGHT-1];
    logic [31:0] w_idx [0:IN_FLIGHT-1];
    logic [127:0] w_hit [0:IN_FLIGHT-1];
    logic [WPW-1:0] w_head, w_tail;
    logic [15:0] w_cnt;
    // Round-robin start: cycle mod TMS.
    logic [RRW-1:0] rr;

    // ---- The hit ports as arrays ----
    logic [PORTS-1:0] hv;
    logic [PORTS-1:0] hr;
    logic [159:0] hd [0:PORTS-1];
    logic [31:0] hidx [0:PORTS-1];     // each port's record index
    assign hv[0] = hit_0_valid; assign hd[0] = hit_0_data; assign hidx[0] = hit_0_data.index; assign hit_0_ready = hr[0];
    assign hv[1] = hit_1_valid; assign hd[1] = hit_1_data; assign hidx[1] = hit_1_data.index; assign hit_1_ready = hr[1];
    assign hv[2] = hit_2_valid; assign hd[2] = hit_2_data; assign hidx[2] = hit_2_data.index; assign hit_2_ready = hr[2];
    assign hv[3] = hit_3_valid; assign hd[3] = hit_3_data; assign hidx[3] = hit_3_data.index; assign hit_3_ready = hr[3];
    assign hv[4] = hit_4_valid; assign hd[4] = hit_4_data; assign hidx[4] = hit_4_data.index; assign hit_4_ready = hr[4];
    assign hv[5] = hit_5_valid; assign hd[5] = hit_5_data; assign hidx[5] = hit_5_data.index; assign hit_5_ready = hr[5];
    assign hv[6] = hit_6_valid; assign hd[6] = hit_6_data; assign hidx[6] = hit_6_data.index; assign hit_6_ready = hr[6];
    assign hv[7] = hit_7_valid; assign hd[7] = hit_7_data; assign hidx[7] = hit_7_data.index; assign hit_7_ready = hr[7];
    assign hv[8] = hit_8_valid; assign hd[8] = hit_8_data; assign hidx[8] = hit_8_data.index; assign hit_8_ready = hr[8];
    assign hv[9] = hit_9_valid; assign hd[9] = hit_9_data; assign hidx[9] = hit_9_data.index; assign hit_9_ready = hr[9];
    assign hv[10] = hit_10_valid; assign hd[10] = hit_10_data; assign hidx[10] = hit_10_data.index; assign hit_10_ready = hr[10];
    assign hv[11] = hit_11_valid; assign hd[11] = hit_11_data; assign hidx[11] = hit_11_data.index; assign hit_11_ready = hr[11];
    assign hv[12] = hit_12_valid; assign hd[12] = hit_12_data; assign hidx[12] = hit_12_data.index; assign hit_12_ready = hr[12];
    assign hv[13] = hit_13_valid; assign hd[13] = hit_13_data; assign hidx[13] = hit_13_data.index; assign hit_13_ready = hr[13];
    assign hv[14] = hit_14_valid; assign hd[14] = hit_14_data; assign hidx[14] = hit_14_data.index; assign hit_14_ready = hr[14];
    assign hv[15] = hit_15_valid; assign hd[15] = hit_15_data; assign hidx[15] = hit_15_data.index; assign hit_15_ready = hr[15];
    assign hv[16] = hit_16_valid; assign hd[16] = hit_16_data; assign hidx[16] = hit_16_data.index; assign hit_16_ready = hr[16];
    assign hv[17] = hit_17_valid; assign hd[17] = hit_17_data; assign hidx[17] = hit_17_data.index; assign hit_17_ready = hr[17];
    assign hv[18] = hit_18_valid; assign hd[18] = hit_18_data; assign hidx[18] = hit_18_data.index; assign hit_18_ready = hr[18];
    assign hv[19] = hit_19_valid; assign hd[19] = hit_19_data; assign hidx[19] = hit_19_data.index; assign hit_19_ready = hr[19];
    assign hv[20] = hit_20_valid; assign hd[20] = hit_20_data; assign hidx[20] = hit_20_data.index; assign hit_20_ready = hr[20];
    assign hv[21] = hit_21_valid; assign hd[21] = hit_21_data; assign hidx[21] = hit_21_data.index; assign hit_21_ready = hr[21];
    assign hv[22] = hit_22_valid; assign hd[22] = hit_22_data; assign hidx[22] = hit_22_data.index; assign hit_22_ready = hr[22];
    assign hv[23] = hit_23_valid; assign hd[23] = hit_23_data; assign hidx[23] = hit_23_data.index; assign hit_23_ready = hr[23];
    assign hv[24] = hit_24_valid; assign hd[24] = hit_24_data; assign hidx[24] = hit_24_data.index; assign hit_24_ready = hr[24];
    assign hv[25] = hit_25_valid; assign hd[25] = hit_25_data; assign hidx[25] = hit_25_data.index; assign hit_25_ready = hr[25];
    assign hv[26] = hit_26_valid; assign hd[26] = hit_26_data; assign hidx[26] = hit_26_data.index; assign hit_26_ready = hr[26];
    assign hv[27] = hit_27_valid; assign hd[27] = hit_27_data; assign hidx[27] = hit_27_data.index; assign hit_27_ready = hr[27];
    assign hv[28] = hit_28_valid; assign hd[28] = hit_28_data; assign hidx[28] = hit_28_data.index; assign hit_28_ready = hr[28];
    assign hv[29] = hit_29_valid; assign hd[29] = hit_29_data; assign hidx[29] = hit_29_data.index; assign hit_29_ready = hr[29];
    assign hv[30] = hit_30_valid; assign hd[30] = hit_30_data; assign hidx[30] = hit_30_data.index; assign hit_30_ready = hr[30];
    assign hv[31] = hit_31_valid; assign hd[31] = hit_31_data; assign hidx[31] = hit_31_data.index; assign hit_31_ready = hr[31];
    assign hv[32] = hit_32_valid; assign hd[32] = hit_32_data; assign hidx[32] = hit_32_data.index; assign hit_32_ready = hr[32];
    assign hv[33] = hit_33_valid; assign hd[33] = hit_33_data; assign hidx[33] = hit_33_data.index; assign hit_33_ready = hr[33];
    assign hv[34] = hit_34_valid; assign hd[34] = hit_34_data; assign hidx[34] = hit_34_data.index; assign hit_34_ready = hr[34];
    assign hv[35] = hit_35_valid; assign hd[35] = hit_35_data; assign hidx[35] = hit_35_data.index; assign hit_35_ready = hr[35];
    assign hv[36] = hit_36_valid; assign hd[36] = hit_36_data; assign hidx[36] = hit_36_data.index; assign hit_36_ready = hr[36];
    assign hv[37] = hit_37_valid; assign hd[37] = hit_37_data; assign hidx[37] = hit_37_data.index; assign hit_37_ready = hr[37];
    assign hv[38] = hit_38_valid; assign hd[38] = hit_38_data; assign hidx[38] = hit_38_data.index; assign hit_38_ready = hr[38];
    assign hv[39] = hit_39_valid; assign hd[39] = hit_39_data; assign hidx[39] = hit_39_data.index; assign hit_39_ready = hr[39];
    assign hv[40] = hit_40_valid; assign hd[40] = hit_40_data; assign hidx[40] = hit_40_data.index; assign hit_40_ready = hr[40];
    assign hv[41] = hit_41_valid; assign hd[41] = hit_41_data; assign hidx[41] = hit_41_data.index; assign hit_41_ready = hr[41];
    assign hv[42] = hit_42_valid; assign hd[42] = hit_42_data; assign hidx[42] = hit_42_data.index; assign hit_42_ready = hr[42];
    assign hv[43] = hit_43_valid; assign hd[43] = hit_43_data; assign hidx[43] = hit_43_data.index; assign hit_43_ready = hr[43];
    assign hv[44] = hit_44_valid; assign hd[44] = hit_44_data; assign hidx[44] = hit_44_data.index; assign hit_44_ready = hr[44];
    assign hv[45] = hit_45_valid; assign hd[45] = hit_45_data; assign hidx[45] = hit_45_data.index; assign hit_45_ready = hr[45];
    assign hv[46] = hit_46_valid; assign hd[46] = hit_46_data; assign hidx[46] = hit_46_data.index; assign hit_46_ready = hr[46];
    assign hv[47] = hit_47_valid; assign hd[47] = hit_47_data; assign hidx[47] = hit_47_data.index; assign hit_47_ready = hr[47];
    assign hv[48] = hit_48_valid; assign hd[48] = hit_48_data; assign hidx[48] = hit_48_data.index; assign hit_48_ready = hr[48];
    assign hv[49] = hit_49_valid; assign hd[49] = hit_49_data; assign hidx[49] = hit_49_data.index; assign hit_49_ready = hr[49];
    assign hv[50] = hit_50_valid; assign hd[50] = hit_50_data; assign hidx[50] = hit_50_data.index; assign hit_50_ready = hr[50];
    assign hv[51] = hit_51_valid; assign hd[51] = hit_51_data; assign hidx[51] = hit_51_data.index; assign hit_51_ready = hr[51];
    assign hv[52] = hit_52_valid; assign hd[52] = hit_52_data; assign hidx[52] = hit_52_data.index; assign hit_52_ready = hr[52];
    assign hv[53] = hit_53_valid; assign hd[53] = hit_53_data; assign hidx[53] = hit_53_data.index; assign hit_53_ready = hr[53];
    assign hv[54] = hit_54_valid; assign hd[54] = hit_54_data; assign hidx[54] = hit_54_data.index; assign hit_54_ready = hr[54];
    assign hv[55] = hit_55_valid; assign hd[55] = hit_55_data; assign hidx[55] = hit_55_data.index; assign hit_55_ready = hr[55];
    assign hv[56] = hit_56_valid; assign hd[56] = hit_56_data; assign hidx[56] = hit_56_data.index; assign hit_56_ready = hr[56];
    assign hv[57] = hit_57_valid; assign hd[57] = hit_57_data; assign hidx[57] = hit_57_data.index; assign hit_57_ready = hr[57];
    assign hv[58] = hit_58_valid; assign hd[58] = hit_58_data; assign hidx[58] = hit_58_data.index; assign hit_58_ready = hr[58];
    assign hv[59] = hit_59_valid; assign hd[59] = hit_59_data; assign hidx[59] = hit_59_data.index; assign hit_59_ready = hr[59];
    assign hv[60] = hit_60_valid; assign hd[60] = hit_60_data; assign hidx[60] = hit_60_data.index; assign hit_60_ready = hr[60];
    assign hv[61] = hit_61_valid; assign hd[61] = hit_61_data; assign hidx[61] = hit_61_data.index; assign hit_61_ready = hr[61];
    assign hv[62] = hit_62_valid; assign hd[62] = hit_62_data; assign hidx[62] = hit_62_data.index; assign hit_62_ready = hr[62];
    assign hv[63] = hit_63_valid; assign hd[63] = hit_63_data; assign hidx[63] = hit_63_data.index; assign hit_63_ready = hr[63];
    assign hv[64] = hit_64_valid; assign hd[64] = hit_64_data; assign hidx[64] = hit_64_data.index; assign hit_64_ready = hr[64];
    assign hv[65] = hit_65_valid; assign hd[65] = hit_65_data; assign hidx[65] = hit_65_data.index; assign hit_65_ready = hr[65];
    assign hv[66] = hit_66_valid; assign hd[66] = hit_66_data; assign hidx[66] = hit_66_data.index; assign hit_66_ready = hr[66];
    assign hv[67] = hit_67_valid; assign hd[67] = hit_67_data; assign hidx[67] = hit_67_data.index; assign hit_67_ready = hr[67];
    assign hv[68] = hit_68_valid; assign hd[68] = hit_68_data; assign hidx[68] = hit_68_data.index; assign hit_68_ready = hr[68];
    assign hv[69] = hit_69_valid; assign hd[69] = hit_69_data; assign hidx[69] = hit_69_data.index; assign hit_69_ready = hr[69];
    assign hv[70] = hit_70_valid; assign hd[70] = hit_70_data; assign hidx[70] = hit_70_data.index; assign hit_70_ready = hr[70];
    assign hv[71] = hit_71_valid; assign hd[71] = hit_71_data; assign hidx[71] = hit_71_data.index; assign hit_71_ready = hr[71];
    assign hv[72] = hit_72_valid; assign hd[72] = hit_72_data; assign hidx[72] = hit_72_data.index; assign hit_72_ready = hr[72];
    assign hv[73] = hit_73_valid; assign hd[73] = hit_73_data; assign hidx[73] = hit_73_data.index; assign hit_73_ready = hr[73];
    assign hv[74] = hit_74_valid; assign hd[74] = hit_74_data; assign hidx[74] = hit_74_data.index; assign hit_74_ready = hr[74];
    assign hv[75] = hit_75_valid; assign hd[75] = hit_75_data; assign hidx[75] = hit_75_data.index; assign hit_75_ready = hr[75];
    assign hv[76] = hit_76_valid; assign hd[76] = hit_76_data; assign hidx[76] = hit_76_data.index; assign hit_76_ready = hr[76];
    assign hv[77] = hit_77_valid; assign hd[77] = hit_77_data; assign hidx[77] = hit_77_data.index; assign hit_77_ready = hr[77];
    assign hv[78] = hit_78_valid; assign hd[78] = hit_78_data; assign hidx[78] = hit_78_data.index; assign hit_78_ready = hr[78];
    assign hv[79] = hit_79_valid; assign hd[79] = hit_79_data; assign hidx[79] = hit_79_data.index; assign hit_79_ready = hr[79];
    assign hv[80] = hit_80_valid; assign hd[80] = hit_80_data; assign hidx[80] = hit_80_data.index; assign hit_80_ready = hr[80];
    assign hv[81] = hit_81_valid; assign hd[81] = hit_81_data; assign hidx[81] = hit_81_data.index; assign hit_81_ready = hr[81];
    assign hv[82] = hit_82_valid; assign hd[82] = hit_82_data; assign hidx[82] = hit_82_data.index; assign hit_82_ready = hr[82];
    assign hv[83] = hit_83_valid; assign hd[83] = hit_83_data; assign hidx[83] = hit_83_data.index; assign hit_83_ready = hr[83];
    assign hv[84] = hit_84_valid; assign hd[84] = hit_84_data; assign hidx[84] = hit_84_data.index; assign hit_84_ready = hr[84];
    assign hv[85] = hit_85_valid; assign hd[85] = hit_85_data; assign hidx[85] = hit_85_data.index; assign hit_85_ready = hr[85];
    assign hv[86] = hit_86_valid; assign hd[86] = hit_86_data; assign hidx[86] = hit_86_data.index; assign hit_86_ready = hr[86];
    assign hv[87] = hit_87_valid; assign hd[87] = hit_87_data; assign hidx[87] = hit_87_data.index; assign hit_87_ready = hr[87];
    assign hv[88] = hit_88_valid; assign hd[88] = hit_88_data; assign hidx[88] = hit_88_data.index; assign hit_88_ready = hr[88];
    assign hv[89] = hit_89_valid; assign hd[89] = hit_89_data; assign hidx[89] = hit_89_data.index; assign hit_89_ready = hr[89];
    assign hv[90] = hit_90_valid; assign hd[90] = hit_90_data; assign hidx[90] = hit_90_data.index; assign hit_90_ready = hr[90];
    assign hv[91] = hit_91_valid; assign hd[91] = hit_91_data; assign hidx[91] = hit_91_data.index; assign hit_91_ready = hr[91];
    assign hv[92] = hit_92_valid; assign hd[92] = hit_92_data; assign hidx[92] = hit_92_data.index; assign hit_92_ready = hr[92];
    assign hv[93] = hit_93_valid; assign hd[93] = hit_93_data; assign hidx[93] = hit_93_data.index; assign hit_93_ready = hr[93];
    assign hv[94] = hit_94_valid; assign hd[94] = hit_94_data; assign hidx[94] = hit_94_data.index; assign hit_94_ready = hr[94];
    assign hv[95] = hit_95_valid; assign hd[95] = hit_95_data; assign hidx[95] = hit_95_data.index; assign hit_95_ready = hr[95];
    assign hv[96] = hit_96_valid; assign hd[96] = hit_96_data; assign hidx[96] = hit_96_data.index; assign hit_96_ready = hr[96];
    assign hv[97] = hit_97_valid; assign hd[97] = hit_97_data; assign hidx[97] = hit_97_data.index; assign hit_97_ready = hr[97];
    assign hv[98] = hit_98_valid; assign hd[98] = hit_98_data; assign hidx[98] = hit_98_data.index; assign hit_98_ready = hr[98];
    assign hv[99] = hit_99_valid; assign hd[99] = hit_99_data; assign hidx[99] = hit_99_data.index; assign hit_99_ready = hr[99];
    assign hv[100] = hit_100_valid; assign hd[100] = hit_100_data; assign hidx[100] = hit_100_data.index; assign hit_100_ready = hr[100];
    assign hv[101] = hit_101_valid; assign hd[101] = hit_101_data; assign hidx[101] = hit_101_data.index; assign hit_101_ready = hr[101];
    assign hv[102] = hit_102_valid; assign hd[102] = hit_102_data; assign hidx[102] = hit_102_data.index; assign hit_102_ready = hr[102];
    assign hv[103] = hit_103_valid; assign hd[103] = hit_103_data; assign hidx[103] = hit_103_data.index; assign hit_103_ready = hr[103];
    assign hv[104] = hit_104_valid; assign hd[104] = hit_104_data; assign hidx[104] = hit_104_data.index; assign hit_104_ready = hr[104];
    assign hv[105] = hit_105_valid; assign hd[105] = hit_105_data; assign hidx[105] = hit_105_data.index; assign hit_105_ready = hr[105];
    assign hv[106] = hit_106_valid; assign hd[106] = hit_106_data; assign hidx[106] = hit_106_data.index; assign hit_106_ready = hr[106];
    assign hv[107] = hit_107_valid; assign hd[107] = hit_107_data; assign hidx[107] = hit_107_data.index; assign hit_107_ready = hr[107];
    assign hv[108] = hit_108_valid; assign hd[108] = hit_108_data; assign hidx[108] = hit_108_data.index; assign hit_108_ready = hr[108];
    assign hv[109] = hit_109_valid; assign hd[109] = hit_109_data; assign hidx[109] = hit_109_data.index; assign hit_109_ready = hr[109];
    assign hv[110] = hit_110_valid; assign hd[110] = hit_110_data; assign hidx[110] = hit_110_data.index; assign hit_110_ready = hr[110];
    assign hv[111] = hit_111_valid; assign hd[111] = hit_111_data; assign hidx[111] = hit_111_data.index; assign hit_111_ready = hr[111];
    assign hv[112] = hit_112_valid; assign hd[112] = hit_112_data; assign hidx[112] = hit_112_data.index; assign hit_112_ready = hr[112];
    assign hv[113] = hit_113_valid; assign hd[113] = hit_113_data; assign hidx[113] = hit_113_data.index; assign hit_113_ready = hr[113];
    assign hv[114] = hit_114_valid; assign hd[114] = hit_114_data; assign hidx[114] = hit_114_data.index; assign hit_114_ready = hr[114];
    assign hv[115] = hit_115_valid; assign hd[115] = hit_115_data; assign hidx[115] = hit_115_data.index; assign hit_115_ready = hr[115];
    assign hv[116] = hit_116_valid; assign hd[116] = hit_116_data; assign hidx[116] = hit_116_data.index; assign hit_116_ready = hr[116];
    assign hv[117] = hit_117_valid; assign hd[117] = hit_117_data; assign hidx[117] = hit_117_data.index; assign hit_117_ready = hr[117];
    assign hv[118] = hit_118_valid; assign hd[118] = hit_118_data; assign hidx[118] = hit_118_data.index; assign hit_118_ready = hr[118];
    assign hv[119] = hit_119_valid; assign hd[119] = hit_119_data; assign hidx[119] = hit_119_data.index; assign hit_119_ready = hr[119];
    assign hv[120] = hit_120_valid; assign hd[120] = hit_120_data; assign hidx[120] = hit_120_data.index; assign hit_120_ready = hr[120];
    assign hv[121] = hit_121_valid; assign hd[121] = hit_121_data; assign hidx[121] = hit_121_data.index; assign hit_121_ready = hr[121];
    assign hv[122] = hit_122_valid; assign hd[122] = hit_122_data; assign hidx[122] = hit_122_data.index; assign hit_122_ready = hr[122];
    assign hv[123] = hit_123_valid; assign hd[123] = hit_123_data; assign hidx[123] = hit_123_data.index; assign hit_123_ready = hr[123];
    assign hv[124] = hit_124_valid; assign hd[124] = hit_124_data; assign hidx[124] = hit_124_data.index; assign hit_124_ready = hr[124];
    assign hv[125] = hit_125_valid; assign hd[125] = hit_125_data; assign hidx[125] = hit_125_data.index; assign hit_125_ready = hr[125];
    assign hv[126] = hit_126_valid; assign hd[126] = hit_126_data; assign hidx[126] = hit_126_data.index; assign hit_126_ready = hr[126];
    assign hv[127] = hit_127_valid; assign hd[127] = hit_127_data; assign hidx[127] = hit_127_data.index; assign hit_127_ready = hr[127];

    // ---- Closest hit on (t, triangle id), as f32 compares ----
    function automatic logic f_nan(input logic [30:0] a);
        f_nan = a[30:23] == 8'hff && a[22:0] != 23'd0;
    endfunction
    function automatic logic f_lt(input logic [31:0] a, input logic [31:0] b);
        if (f_nan(a[30:0]) || f_nan(b[30:0]) || (a[30:0] == 31'd0 && b[30:0] == 31'd0))
            f_lt = 1'b0;
        else if (a[31] != b[31])
            f_lt = a[31];
        else if (a[31])
            f_lt = a[30:0] > b[30:0];
        else
            f_lt = a[30:0] < b[30:0];
    endfunction
    function automatic logic f_eq(input logic [31:0] a, input logic [31:0] b);
        f_eq = !f_nan(a[30:0]) && !f_nan(b[30:0])
            && (a == b || (a[30:0] == 31'd0 && b[30:0] == 31'd0));
    endfunction
    // On the key {tri_id, t}: hit_rec_t's low 64 bits (t [31:0], tri_id
    // [63:32]; u, v above do not take part).
    function automatic logic key_closer(input logic [63:0] a, input logic [63:0] b);
        key_closer = f_lt(a[31:0], b[31:0])
            || (f_eq(a[31:0], b[31:0]) && a[63:32] < b[63:32]);
    endfunction
    // The record's byte offset in its line, and its line's address.
    function automatic logic [5:0] rec_off(input logic [1:0] idx_low);
        rec_off = BASE[5:0] + {idx_low, 4'b0000};
    endfunction
    function automatic logic [63:0] rec_line(input logic [31:0] idx);
        rec_line = (BASE + {28'd0, idx, 4'b0000}) & ~64'd63;
    endfunction

    // ---- 1. The memory answer ----
    logic rsp_write;
    logic [31:0] rsp_id;
    logic [63:0] rsp_addr;
    logic [511:0] rsp_line;
    logic [63:0] rsp_cur;        // the record as read: its key {tri_id, t}
    logic [127:0] rsp_upd;       // the in-flight update of that index
    int rs;                      // its slot
    logic decided;               // a read answer whose update is closer: a write
    logic retire;                // the index leaves the in-flight table
    assign rsp_write = mem_resp_data.write;
    assign rsp_id = mem_resp_data.id;
    assign rsp_addr = mem_resp_data.addr;
    assign rsp_line = mem_resp_data.data >> {rec_off(mem_resp_data.id[1:0]), 3'b000};
    assign rsp_cur = rsp_line[63:0];
    // Each combinational block computes in locals and writes its outputs
    // once: no intermediate values for an event-driven simulator to chase.
    always_comb begin : p_rsp
        int r;
        logic [127:0] u;
        r = 0;
        u = '0;
        for (int s = 0; s < IN_FLIGHT; s++)
            if (f_val[s] && f_idx[s] == rsp_id) begin
                r = s;
                u = f_hit[s];
            end
        rs = r;
        rsp_upd = u;
    end
    assign decided = mem_resp_valid && !rsp_write && key_closer(rsp_upd[63:0], rsp_cur);
    assign retire = mem_resp_valid && !decided;
    assign mem_resp_ready = mem_resp_valid || in_flight != 16'd0;

    // ---- 2. The memory request ----
    logic [QUEUE-1:0] blk;       // q_blk after this cycle's retirement
    int nq;                      // queued, as an int
    int kp;                      // the oldest queued entry not in flight
    logic cand;
    logic wr_now;                // a write goes out
    logic wr_bypass;             // ... the one decided this cycle
    logic rd_now;                // a read goes out
    logic [63:0] wr_addr;
    logic [31:0] wr_idx;
    logic [127:0] wr_hit;
    logic [15:0] in_flight_left; // after the retirement
    assign nq = {16'd0, queued};
    assign in_flight_left = in_flight - {15'd0, retire};
    always_comb begin : p_pick
        logic [QUEUE-1:0] b;
        int k;
        logic c;
        k = 0;
        c = 1'b0;
        for (int m = QUEUE - 1; m >= 0; m--) begin
            b[m] = q_blk[m] && !(retire && q_idx[m] == rsp_id);
            if (m < nq && !b[m]) begin
                k = m;
                c = 1'b1;
            end
        end
        blk = b;
        kp = k;
        cand = c;
    end
    assign wr_now = mem_req_ready && (w_cnt != 16'd0 || decided);
    assign wr_bypass = w_cnt == 16'd0;
    assign rd_now = mem_req_ready && !wr_now && in_flight_left < IN_FLIGHT_N && cand;
    assign wr_addr = wr_bypass ? rsp_addr : w_addr[w_head];
    assign wr_idx = wr_bypass ? rsp_id : w_idx[w_head];
    assign wr_hit = wr_bypass ? rsp_upd : w_hit[w_head];

    logic req_valid;
    mem_line_req_t req;
    logic [31:0] rd_idx;
    assign rd_idx = q_idx[kp];
    assign req_valid = wr_now || rd_now;
    assign req = wr_now
        ? {{384'd0, wr_hit} << {rec_off(wr_idx[1:0]), 3'b000},
           64'hFFFF << rec_off(wr_idx[1:0]), wr_idx, STREAM_TAG_HIT, 1'b1, wr_addr}
        : {512'd0, 64'd0, rd_idx, STREAM_TAG_HIT, 1'b0, rec_line(rd_idx)};
`ifdef HRU_WRONG_LATENCY
    logic late_valid;
    mem_line_req_t late;
    always_ff @(posedge clk) begin
        if (rst) late_valid <= 1'b0;
        else late_valid <= req_valid;
        late <= req;
    end
    assign mem_req_valid = late_valid;
    assign mem_req_data = late;
`else
    assign mem_req_valid = req_valid;
    assign mem_req_data = req;
`endif

    // ---- 3. One update accepted ----
    logic [QUEUE-1:0] live;      // queue entries after the read's removal
    logic full;                  // no room after the removal
    logic [PORTS-1:0] elig;
    int g;                       // the granted port
    logic granted;
    logic [31:0] u_idx;
    logic [127:0] u_hit;
    int mp;                      // the entry it merges into (old position)
    logic merge;
    logic append;
    logic u_blk;                 // the appended index is in flight
    logic [127:0] merged;
    int nl;                      // entries left after the removal
    int rr_i;
    assign rr_i = {{(32 - RRW) {1'b0}}, rr};
    assign nl = nq - (rd_now ? 1 : 0);
    assign full = nl >= QUEUE;
    always_comb begin : p_live
        logic [QUEUE-1:0] l;
        for (int m = 0; m < QUEUE; m++)
            l[m] = m < nq && !(rd_now && m == kp);
        live = l;
    end
    always_comb begin : p_elig
        logic [PORTS-1:0] e;
        for (int j = 0; j < PORTS; j++) begin
            e[j] = 1'b0;
            if (j < TMS && hv[j]) begin
                e[j] = !full;
                // The index match matters only with the queue full (and
                // skipping it then keeps event-driven simulators fast).
                if (full)
                    for (int m = 0; m < QUEUE; m++)
                        if (live[m] && q_idx[m] == hidx[j]) e[j] = 1'b1;
            end
        end
        elig = e;
    end
    // Round-robin: the first eligible port at or after rr, else the first.
    always_comb begin : p_grant
        int k;
        k = 0;
        for (int j = PORTS - 1; j >= 0; j--)
            if (elig[j]) k = j;
        for (int j = PORTS - 1; j >= 0; j--)
            if (elig[j] && j >= rr_i) k = j;
        g = k;
        granted = elig != '0;
    end
    assign u_idx = hd[g][31:0];
    assign u_hit = hd[g][159:32];
    always_comb begin : p_merge
        int k;
        logic f;
        k = 0;
        f = 1'b0;
        for (int m = 0; m < QUEUE; m++)
            if (granted && live[m] && q_idx[m] == u_idx) begin
                k = m;
                f = 1'b1;
            end
        mp = k;
        merge = f;
    end
    assign append = granted && !merge;
`ifdef HRU_WRONG_MERGE
    assign merged = key_closer(u_hit[63:0], q_hit[mp][63:0]) ? q_hit[mp] : u_hit;
`else
    assign merged = key_closer(u_hit[63:0], q_hit[mp][63:0]) ? u_hit : q_hit[mp];
`endif
    always_comb begin : p_ublk
        logic b;
        b = rd_now && rd_idx == u_idx;
        for (int s = 0; s < IN_FLIGHT; s++)
            if (f_val[s] && f_idx[s] == u_idx && !(retire && s == rs)) b = 1'b1;
        u_blk = b;
    end
    always_comb begin : p_ready
        logic [PORTS-1:0] r;
        for (int j = 0; j < PORTS; j++) r[j] = !hv[j] || (granted && g == j);
        hr = r;
    end

    // A free in-flight slot for the read (the retired one counts as free).
    logic [WPW-1:0] fs;
    always_comb begin : p_free
        logic [WPW-1:0] f;
        f = '0;
        for (int s = IN_FLIGHT - 1; s >= 0; s--)
            if (!f_val[s] || (retire && s == rs)) f = WPW'(s);
        fs = f;
    end

    // ---- The clock edge ----
    // The entry behind queue position j (itself at the tail).
    function automatic int up(input int j);
        up = (j + 1 < QUEUE) ? j + 1 : j;
    endfunction
    always_ff @(posedge clk) begin
        if (rst) begin
            queued <= '0;
            in_flight <= '0;
            f_val <= '0;
            w_head <= '0;
            w_tail <= '0;
            w_cnt <= '0;
            rr <= '0;
        end else begin
            rr <= (rr == RRW'(TMS - 1)) ? '0 : rr + 1'b1;
            queued <= queued - {15'd0, rd_now} + {15'd0, append};
            in_flight <= in_flight_left + {15'd0, rd_now};
            if (retire) f_val[rs] <= 1'b0;
            if (rd_now) f_val[fs] <= 1'b1;
            w_cnt <= w_cnt + {15'd0, decided && !(wr_now && wr_bypass)}
                - {15'd0, wr_now && !wr_bypass};
            if (wr_now && !wr_bypass) w_head <= (w_head == W_LAST) ? '0 : w_head + 1'b1;
            if (decided && !(wr_now && wr_bypass))
                w_tail <= (w_tail == W_LAST) ? '0 : w_tail + 1'b1;
        end
        // Storage: written where needed, never reset.
        if (rd_now) begin
            f_idx[fs] <= rd_idx;
            f_hit[fs] <= q_hit[kp];
        end
        if (decided && !(wr_now && wr_bypass)) begin
            w_addr[w_tail] <= rsp_addr;
            w_idx[w_tail] <= rsp_id;
            w_hit[w_tail] <= rsp_upd;
        end
        for (int j = 0; j < QUEUE; j++) begin
            // Entry j takes old entry j, or j + 1 behind the removed read.
            if (rd_now && j >= kp && j + 1 < QUEUE) begin
                q_idx[j] <= q_idx[up(j)];
                q_hit[j] <= (merge && mp == up(j)) ? merged : q_hit[up(j)];
                q_blk[j] <= blk[up(j)];
            end else begin
                q_hit[j] <= (merge && mp == j) ? merged : q_hit[j];
                q_blk[j] <= blk[j];
            end
            if (append && j == nl) begin
                q_idx[j] <= u_idx;
                q_hit[j] <= u_hit;
                q_blk[j] <= u_blk;
            end
        end
    end

    wire _unused_ok = &{1'b0, mem_resp_data.tag, rsp_line[511:64], 1'b0};
endmodule
