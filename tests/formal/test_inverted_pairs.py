"""The pairing of registers that iCE40 synthesis stores inverted (``formal/_inverted.py``): the
undriven bits read from a netlist's ``x`` assignments, and the pair wires added on each side."""

from fliss.formal._inverted import dead_bits, gate_text, gold_script


NETLIST = """module top(a, b);
  assign \\source.masked [0] = 1'hx;
  assign { \\source.taps [31], \\source.taps [1:0] } = 3'hx;
  assign { delays__payload[3:2], \\source.zero } = { 2'hx, c };
  assign \\source.fine [2] = d;
endmodule
"""


def test_dead_bits_of_every_x_assignment():
    assert dead_bits(NETLIST) == [("source.masked", 0), ("source.taps", 31), ("source.taps", 0),
                                  ("source.taps", 1), ("delays__payload", 2),
                                  ("delays__payload", 3), ("source.zero", None)]


def test_pair_wires_on_each_side():
    pairs = {("source.masked", 0): ("\\source.q_SB [0] ", True),
             ("source.zero", None): ("q2 ", False)}
    assert gold_script(pairs) == ["add -wire fliss_pair_0 1",
                                  "connect -set fliss_pair_0 source.masked[0]",
                                  "add -wire fliss_pair_1 1",
                                  "connect -set fliss_pair_1 source.zero"]
    text = gate_text(NETLIST, pairs)
    assert text.endswith("  (* keep *) wire fliss_pair_0;\n  assign fliss_pair_0 = ~(\\source.q_SB [0] );\n"
                         "  (* keep *) wire fliss_pair_1;\n  assign fliss_pair_1 = (q2 );\nendmodule\n")
