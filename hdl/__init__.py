"""FLISS gateware (Amaranth 0.5).

One block per module; the larger blocks are subpackages of several:

* :mod:`.delay`: the delay core: pseudorandom delay sources (``off``, ``mseq``, ``masked``,
  ``keyed``), the pulse scheduler (``interval`` and ``grid`` modes), the laser trigger and TDC
  start, and an aggressor's independent trigger;
* :mod:`.tdc`: the sensor's timestamp interface and a built-in coarse TDC;
* :mod:`.finetdc`: a fine TDC in the FPGA fabric (a tapped delay line) and its calibration table;
* :mod:`.histogram`: the two-bank histogram engine and its readout;
* :mod:`.depth`: the depth engine, a depth record per pixel of each frame of the readout;
* :mod:`.rawfifo`: the raw event FIFO that counts what it drops;
* :mod:`.packets`: the data packetizers, one per kind of data packet (EVENTS, HISTOGRAM and
  HISTOGRAM_COMPACT, DEPTH);
* :mod:`.link`: the UART, the framing (CRC, COBS), the command processor and the arbiter that
  merges the packetizers' packets onto the link;
* :mod:`.regfile`: register file (settings, their checks, groups as structs);
* :mod:`.counters`, :mod:`.status`: event counters and the STATUS reply's counters;
* :mod:`.block_ram`, :mod:`.spram`: block RAM and single-port RAM, the FPGA's or generic;
* :mod:`.divider`: a serial divider;
* :mod:`.top`: :class:`~.top.FlissTop`, everything behind a UART; :mod:`.ports`, what each of
  its ports means (the ports table of ``fliss generate`` and ``docs/ports.md``).

Definitions shared by gateware, models and host: :mod:`.clock` (the default clock and PRF,
and what the parameters come to in clock cycles), :mod:`.event` (the photon event layout),
:mod:`.protocol` (packets), :mod:`.registers` (the register map: rows, :mod:`.register_rows`;
the checks across registers, :mod:`.register_checks`),
:mod:`.codes` (a timestamp code's width for each event source), :mod:`.delay.settings` (the
delay core's limits). :mod:`.verilog` writes Verilog that every simulator reads the same way;
:mod:`.testbench` holds the Verilog testbench ``fliss generate`` writes beside it.
:mod:`.lazy` gives a package its public names imported when first asked for (as
:mod:`.delay`, :mod:`.histogram` and :mod:`.link` offer their blocks).

Here: :func:`lookup`, a constant table read at a signal's value, as LUTs or a ROM.
"""

from amaranth.hdl import Array, Cat, Const, Value


def lookup(values, index, width=None, *, fill=0, rom=False):
    """The constant table ``values`` read at ``index`` (an Amaranth value), ``width`` bits wide
    (by default, as wide as the largest value); entries past the end read as ``fill``.

    Each bit of the result is a function of ``index`` alone: a LUT or two for a narrow index,
    where the shifts, sums and comparisons that give the values would be carry chains or
    shifters. By default the table is a slice of one wide constant at a variable offset; with
    ``rom``, a case over ``index`` (an :class:`~amaranth.hdl.Array` of constants), which Yosys
    writes as a ROM. Both are the same logic; Verilator reads the ROM as one array access but
    the slice as a shift of many words every cycle, and on the ECP5 either may take fewer LUTs
    (the frame sequencer's and the register file's tables are smaller as ROMs, the depth
    engine's and the packetizers' as slices).
    """
    index = Value.cast(index)
    values = list(values)
    values += [fill] * ((1 << len(index)) - len(values))
    if width is None:
        width = max(values).bit_length()
    if rom:
        return Array(Const(value, width) for value in values)[index]
    return Cat(Const(value, width) for value in values).word_select(index, width)
