"""Gateware for Verilog users: the folder ``fliss generate`` writes.

* :mod:`.folder`: :func:`~.folder.write_folder`, the top level's Verilog and beside it the
  black boxes of its vendor cells, the ports table, a constraints template per board, the
  testbench and a FuseSoC core file that names them all;
* :mod:`.core_file`: the FuseSoC core file (CAPI2) with its targets ``lint`` and ``sim``;
* :mod:`.ports_table`: the ports table, from the top level's signature;
* :mod:`.stimulus`: what the testbench sends over the UART and the delays it expects, from the
  reference model (as ``fliss sequence`` prints them).
"""

from .folder import VARIANTS, Generated, check_build, make_top, victim_period, write_folder
from .stimulus import TB_MODES, DelayCheck


__all__ = ["VARIANTS", "Generated", "check_build", "make_top", "victim_period", "write_folder", "TB_MODES",
           "DelayCheck"]
