"""Boards without hardware, behind a pseudo-terminal.

* :mod:`.model`: the model board, the bit-exact models in Python; its data packets are made by
  :mod:`.producers`, one per readout;
* :mod:`.virtual`: the virtual board, the top level's Verilog in a simulator (a cocotb module);
* :mod:`.pty_server`: the byte side of a board on a pty, with fault injection;
* :mod:`.noisy_line`: a proxy that injects faults into the bytes between host and board.
"""
