"""cocotb testbenches of the generated Verilog, and what they need.

* :mod:`.runner`: pytest to cocotb (Verilog from a component, built once per folder);
* :mod:`.uart_bfm`: UART driver and monitor;
* :mod:`.link_top`, :mod:`.histogram_link_top`: tops of parts of the link for fuzzing, and
  :mod:`.wire`, the player and recorder of frame bytes in the first;
* one bench per block or top: :mod:`.delay_source`, :mod:`.delay_core`, :mod:`.depth`,
  :mod:`.link`, :mod:`.packetizer`, :mod:`.top`, :mod:`.top_depth`, :mod:`.scene`;
* :mod:`.netlist_top`: the benches a board build's netlist runs, through the board's pins.
"""
