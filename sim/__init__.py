"""Simulation: the bit-exact models, the scene simulator and the boards without hardware.

* :mod:`.models`: reference models of the gateware's blocks, bit for bit;
* :mod:`.scene`: the photon-level Monte Carlo of a LiDAR pixel or pixel array;
* :mod:`.studies`: studies on the scene simulator (detection, interference, the attacker);
* :mod:`.benches`: cocotb testbenches of the generated Verilog;
* :mod:`.boards`: the model board and the virtual board, behind a pseudo-terminal.
"""
