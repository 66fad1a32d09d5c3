"""The pairing of registers that iCE40 synthesis stores inverted (``formal/_inverted.py``): the
undriven bits read from a netlist's ``x`` assignments, and the pair wires added on each side."""

import pytest

from fliss.formal._inverted import alive_pairs, dead_bits, gate_text, gold_script


NETLIST = """module top(a, b);
  wire [5:0] delays__payload;
  wire [2:0] \\source.masked ;
  wire [1:0] \\source.fine ;
  assign \\source.masked [0] = 1'hx;
  assign { \\source.taps [31], \\source.taps [1:0] } = 3'hx;
  assign { delays__payload[3:2], \\source.zero , delays__payload[5] } = { 2'hx, c, 1'hx };
  assign \\source.fine  = 2'b0x;
  assign \\source.lane [2] = d;
endmodule
"""


def test_dead_bits_of_every_x_assignment():
    # (bit by bit: the concatenation's `c` and the constant's `0` are no dead bits)
    assert dead_bits(NETLIST) == [("source.masked", 0), ("source.taps", 0), ("source.taps", 1),
                                  ("source.taps", 31), ("delays__payload", 5),
                                  ("delays__payload", 2), ("delays__payload", 3),
                                  ("source.fine", 0)]


def test_a_term_not_understood_is_refused():
    with pytest.raises(ValueError, match="not a wire or a constant"):
        dead_bits("module top();\n  assign { a, { b, c } } = { 2'hx, d };\nendmodule\n")


def test_other_bits_of_a_dead_wire_paired_as_they_are():
    dead = dead_bits(NETLIST)
    assert alive_pairs(NETLIST, dead) == {
        ("source.masked", 1): ("\\source.masked [1] ", False),
        ("source.masked", 2): ("\\source.masked [2] ", False),
        ("delays__payload", 0): ("\\delays__payload [0] ", False),
        ("delays__payload", 1): ("\\delays__payload [1] ", False),
        ("delays__payload", 4): ("\\delays__payload [4] ", False),
        ("source.fine", 1): ("\\source.fine [1] ", False)}


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
