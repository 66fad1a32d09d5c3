"""cocotb testbenches of the generated Verilog, and what they need.

* :mod:`.runner`: pytest to cocotb (Verilog from a component, built once per folder);
* :mod:`.uart_bfm`: UART driver and monitor;
* :mod:`.link_top`, :mod:`.histogram_link_top`: tops of parts of the link for fuzzing, and
  :mod:`.wire`, the player and recorder of frame bytes in the first;
* one bench per block or top: :mod:`.delay_source`, :mod:`.delay_core`, :mod:`.depth`,
  :mod:`.link`, :mod:`.packetizer`, :mod:`.top`, :mod:`.top_depth`, :mod:`.scene`;
* :mod:`.netlist_top`: the benches a board build's netlist runs, through the board's pins.

The benches' clocks run in the simulator's interface (``Clock(..., impl="gpi")``), not as a
cocotb task: a clock in Python took a fifth of a run's time on Icarus. The netlists' power-up
bench keeps the clock in Python: the GPI's first edge comes at time 0, ahead of its reset.
"""
