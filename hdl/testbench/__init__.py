"""The Verilog testbench that ``fliss generate`` writes beside the top level
(``fliss_top_tb.v``, package data; :mod:`fliss.host.ip`)."""
