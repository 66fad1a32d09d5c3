// FLISS: a testbench of the top level as `fliss generate` writes it, for any Verilog simulator.
//
// It drives the top level as a host does: it sends the bytes of COMMANDS (one hex byte a line,
// frames of the FLISS link that set a delay source and start: `fliss generate` writes them)
// on uart_rx at BAUD, then watches the laser trigger. The delay of pulse k is the time from
// pulse k-1's rising edge to its own, in clock cycles, less PERIOD (the interval scheduler fires
// T + R apart); pulses 1 to PULSES-1 are checked against EXPECTED (one hex delay a line, as
// `fliss sequence` prints them; pulse 0's delay counts from the START and is not checked), and
// tdc_start must be high in the cycle of every rising edge of the laser.
//
// It prints one line, PASS or FAIL, and a FAIL ends with $fatal. The top level's name is the
// macro FLISS_TOP (fliss_top by default); define FLISS_PADS for a build with the fine TDC,
// whose pads read back are then tied to the outputs.

`timescale 1ns/1ps

`ifndef FLISS_TOP
`define FLISS_TOP fliss_top
`endif

module fliss_top_tb;
  parameter integer CLOCK_HZ = 80000000;   // the clock the top level was generated for
  parameter integer BAUD = 3000000;        // its baud rate
  parameter integer PERIOD = 80;           // the victim's period after reset, in cycles
  parameter integer MAX_DELAY = 63;        // the largest delay of the delay source, in cycles
  parameter integer PULSES = 32;           // delays in EXPECTED
  parameter integer COMMAND_BYTES = 1;     // bytes in COMMANDS
  parameter integer TIMESTAMP_BITS = 13;   // widths of the sensor bus
  parameter integer ADDRESS_BITS = 6;
  parameter COMMANDS = "commands.hex";
  parameter EXPECTED = "expected_delays.hex";

  localparam real CLOCK_NS = 1.0e9 / CLOCK_HZ;
  localparam real BIT_NS = 1.0e9 / BAUD;
  // Cycles with no rising edge of the laser, once the commands are sent, before it gives up
  localparam integer PATIENCE = 2 * (PERIOD + MAX_DELAY) + 2000;

  reg clk = 1'b0;
  reg rst = 1'b1;
  reg uart_rx = 1'b1;
  wire uart_tx, laser, tdc_start, aggressor_laser, running;

  always #(CLOCK_NS / 2) clk = ~clk;

  `FLISS_TOP dut (
    .clk(clk), .rst(rst),
    .uart_rx(uart_rx), .uart_tx(uart_tx),
    .laser(laser), .tdc_start(tdc_start), .aggressor_laser(aggressor_laser),
    .sensor_valid(1'b0), .sensor_timestamp({TIMESTAMP_BITS{1'b0}}),
    .sensor_address({ADDRESS_BITS{1'b0}}), .sensor_collision(1'b0),
    .photon_hit(1'b0), .running(running)
`ifdef FLISS_PADS
    , .laser_pad(laser), .aggressor_laser_pad(aggressor_laser)
`endif
  );

  reg [7:0] commands [0:COMMAND_BYTES - 1];
  reg [31:0] expected [0:PULSES - 1];

  // The host: reset, then the commands, 8N1, a pause after each frame's delimiter (0x00)
  reg sent = 1'b0;
  integer i, bit_index;

  task send_byte(input [7:0] value);
    begin
      uart_rx = 1'b0;
      #(BIT_NS);
      for (bit_index = 0; bit_index < 8; bit_index = bit_index + 1) begin
        uart_rx = value[bit_index];
        #(BIT_NS);
      end
      uart_rx = 1'b1;
      #(BIT_NS);
    end
  endtask

  initial begin
    $readmemh(COMMANDS, commands);
    $readmemh(EXPECTED, expected);
    repeat (4) @(posedge clk);
    rst <= 1'b0;
    repeat (16) @(posedge clk);
    for (i = 0; i < COMMAND_BYTES; i = i + 1) begin
      send_byte(commands[i]);
      if (commands[i] == 8'h00)
        #(20 * BIT_NS);
    end
    sent = 1'b1;
  end

  // The laser: each rising edge's cycle, the delays against EXPECTED
  integer cycle = 0;
  integer last_edge = 0;
  integer quiet = 0;
  integer edges = 0;
  integer checked = 0;
  integer wrong = 0;
  integer no_start = 0;
  integer delay;
  reg laser_before = 1'b0;

  always @(posedge clk) begin
    cycle = cycle + 1;
    if (laser === 1'b1 && laser_before !== 1'b1) begin
      if (tdc_start !== 1'b1)
        no_start = no_start + 1;
      if (edges > 0) begin
        delay = cycle - last_edge - PERIOD;
        checked = checked + 1;
        if (delay !== expected[edges]) begin
          wrong = wrong + 1;
          if (wrong <= 8)
            $display("pulse %0d: delay %0d cycles, expected %0d", edges, delay,
                     expected[edges]);
        end
      end
      last_edge = cycle;
      edges = edges + 1;
      quiet = 0;
      if (edges == PULSES)
        finish;
    end else if (sent) begin
      quiet = quiet + 1;
      if (quiet > PATIENCE) begin
        $display("FAIL: %0d of %0d laser pulses, then none for %0d cycles", edges, PULSES,
                 quiet);
        $fatal(1, "fliss_top_tb: no laser pulse");
      end
    end
    laser_before = laser;
  end

  task finish;
    begin
      if (wrong == 0 && no_start == 0) begin
        $display("PASS: the delays of pulses 1 to %0d match %0s (%0d checked), tdc_start with each",
                 PULSES - 1, EXPECTED, checked);
        $finish;
      end else begin
        $display("FAIL: %0d of %0d delays differ from %0s; %0d laser edges without tdc_start",
                 wrong, checked, EXPECTED, no_start);
        $fatal(1, "fliss_top_tb: delays differ");
      end
    end
  endtask
endmodule
