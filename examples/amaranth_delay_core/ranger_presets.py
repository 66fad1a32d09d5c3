"""A user's own settings sequencer: on a strobe (a button press), it writes the next of a few sets
of delay settings into the user's registers.

Written for this example: it stands for whatever writes your registers (a CPU, a host link).
"""

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay import delay_problems

from ranger_registers import DELAY_FIELDS, REGISTERS, RegisterWrite


__all__ = ["PresetWriter"]


class PresetWriter(wiring.Component):
    """Writes preset delay settings into :class:`~ranger_registers.RangerRegisters`.

    Preset 0 is the one in the registers after reset. Each ``step`` strobe writes the next
    preset (after the last, preset 0 again), one register per cycle: ``enable`` 0 (the delay
    core stops, so that no frame runs with half of the new settings), the delay settings in the
    order of :data:`~ranger_registers.DELAY_FIELDS`, then ``enable`` 1. A ``step`` while it
    writes is ignored.

    Parameters
    ----------
    presets : list of dict
        Delay settings by field name, each passing :func:`fliss.hdl.delay.delay_problems`
        (``ValueError`` with the first message otherwise); at least two.

    Members
    -------
    step : In(1)
        Write the next preset.
    write : Out(stream.Signature(RegisterWrite, always_ready=True))
        To the registers' ``write``.
    preset : Out(range(len(presets)))
        The preset written last (0 after reset).
    """

    def __init__(self, presets):
        presets = [dict(preset) for preset in presets]
        if len(presets) < 2:
            raise ValueError(f"A preset writer needs at least two presets, not {len(presets)}")
        for number, preset in enumerate(presets):
            problems = delay_problems(preset)
            if problems:
                raise ValueError(f"Preset {number}: {problems[0]}")
        address = {name: index for index, (name, _) in enumerate(REGISTERS)}
        self.writes = [[(address["enable"], 0)] +
                       [(address[name], int(preset[name])) for name in DELAY_FIELDS] +
                       [(address["enable"], 1)] for preset in presets]
        super().__init__({
            "step":   In(1),
            "write":  Out(stream.Signature(RegisterWrite, always_ready=True)),
            "preset": Out(range(len(presets))),
        })

    def elaborate(self, platform):
        m = Module()
        per_preset = len(self.writes[0])
        table = Array(Cat(Const(address, 4), Const(data, 32))
                      for writes in self.writes for address, data in writes)

        # The write in hand: its index in the table, and how many follow it
        busy = Signal()
        index = Signal(range(len(table)))
        left = Signal(range(per_preset))
        last = len(self.writes) - 1
        with m.If(self.step & ~busy):
            following = Signal.like(self.preset)
            m.d.comb += following.eq(Mux(self.preset == last, 0, self.preset + 1))
            m.d.sync += [
                busy.eq(1),
                self.preset.eq(following),
                index.eq(following * per_preset),
                left.eq(per_preset - 1),
            ]
        with m.Elif(busy):
            m.d.sync += [
                index.eq(index + 1),
                left.eq(left - 1),
                busy.eq(left != 0),
            ]

        entry = table[index]
        m.d.comb += [
            self.write.valid.eq(busy),
            self.write.payload.address.eq(entry[:4]),
            self.write.payload.data.eq(entry[4:]),
        ]

        return m
