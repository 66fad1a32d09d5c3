"""Boards without hardware, behind a pseudo-terminal.

* :mod:`.model`: the model board, the bit-exact models in Python; its data packets are made by
  :mod:`.producers`, one per readout; :mod:`.model_command`, its command line
  (``python -m fliss.sim.boards.model``);
* :mod:`.virtual`: the virtual board, the top level's Verilog in a simulator (a cocotb module);
* :mod:`.fast`: the fast virtual board, the top level Verilated in a C++ harness
  (:mod:`.harness`), driven through ctypes;
* :mod:`.sensor`: the scene's events on the top level's sensor bus, for both engines;
* :mod:`.loopback`, :mod:`.jumper`, :mod:`.fine_loopback`: the self-test's bench: trigger
  outputs looped back to the photon pin (a jumper wire) or to the fine TDC's delay line;
* :mod:`.options`: the options that ``fliss board`` and the model board share;
* :mod:`.pty_server`: the byte side of a board on a pty, with fault injection;
* :mod:`.noisy_line`: a proxy that injects faults into the bytes between host and board.
"""
