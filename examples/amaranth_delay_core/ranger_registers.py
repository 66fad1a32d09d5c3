"""A user's own register block: the settings of the FLISS delay core and of the user's range
window, written over a bus of the user's (no FLISS link, no UART).

Written for this example: a design of yours drives the delay core's ``settings`` from wherever
its settings live (constants, a CPU's bus, a Wishbone or CSR bank).
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay import DelayMode, DelaySettings, delay_problems


__all__ = ["PERIOD_WIDTH", "PULSE_WIDTH_WIDTH", "WINDOW_WIDTH", "REGISTERS", "DELAY_FIELDS",
           "RegisterWrite", "RangerRegisters"]


#: Widths of the delay core's ``period`` and ``pulse_width`` in this design, in bits: periods up
#: to 2**24 - 1 cycles (a PRF down to 3 Hz at 48 MHz), pulses up to 255 cycles. Narrower than
#: the core's widest (32 and 16 bits), for a smaller core.
PERIOD_WIDTH = 24
PULSE_WIDTH_WIDTH = 8

#: Width of the range window's bounds, in TDC cycles (the TDC's width).
WINDOW_WIDTH = 12

#: The registers, by address: (name, width in bits). ``enable`` runs the delay core; the delay
#: core's settings follow, as wide as the fields of ``DelaySettings(period_width=PERIOD_WIDTH,
#: pulse_width_width=PULSE_WIDTH_WIDTH)``; the window is the user's own.
REGISTERS = (
    ("enable",       1),
    ("mode",         2),
    ("length",       6),
    ("mask_width",   5),
    ("seed",         32),
    ("period",       PERIOD_WIDTH),
    ("grid",         1),
    ("pulse_width",  PULSE_WIDTH_WIDTH),
    ("window_start", WINDOW_WIDTH),
    ("window_end",   WINDOW_WIDTH),
)

#: Register names of the delay core's settings.
DELAY_FIELDS = ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width")

assert all(DelaySettings(period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH)[name]
           .width == dict(REGISTERS)[name] for name in DELAY_FIELDS)


class RegisterWrite(data.Struct):
    """One register write: its address and value."""
    address: 4
    data:    32


class RangerRegisters(wiring.Component):
    """Register block: :data:`REGISTERS`, reset to ``reset``, written over ``write``.

    A write to a register sets it at the next clock edge. A write to an address past the table,
    or of a value wider than the register, is refused (nothing changes) and counted in
    ``refused``. A write to a setting of the delay core strobes ``update`` in the next cycle,
    when the register holds the new value, so that a running core takes it from its next frame
    (a stopped core reads its settings in every cycle). The block does not check the settings
    together (the pulse shorter than the period, ...): the software that writes them does, with
    :func:`fliss.hdl.delay.delay_problems`, as the constructor does for ``reset``.

    Parameters
    ----------
    reset : dict
        Value of every register after reset, by name; the delay settings must pass
        :func:`~fliss.hdl.delay.delay_problems` (``ValueError`` with its first message).

    Members
    -------
    write : In(stream.Signature(RegisterWrite, always_ready=True))
        Register writes, one per cycle at most.
    enable : Out(1)
        Run the delay core.
    update : Out(1)
        The delay settings changed in the last cycle (to the core's ``update``).
    settings : Out(DelaySettings(period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH))
        The delay core's settings.
    window_start, window_end : Out(WINDOW_WIDTH)
        The user's range window, in TDC cycles.
    refused : Out(16)
        Writes refused (saturating).
    """

    def __init__(self, reset):
        names = [name for name, _ in REGISTERS]
        unknown = sorted(set(reset) - set(names))
        missing = [name for name in names if name not in reset]
        if unknown or missing:
            raise ValueError(f"Register reset values: unknown {unknown}, missing {missing}")
        problems = delay_problems({name: reset[name] for name in DELAY_FIELDS})
        widths = dict(REGISTERS)
        problems += [f"{name} ({value!r}) does not fit its {widths[name]} bits"
                     for name, value in reset.items()
                     if not isinstance(value, int) or not 0 <= value < 1 << widths[name]]
        if problems:
            raise ValueError(f"Register reset values: {problems[0]}")
        self.reset = dict(reset)
        self.layout = DelaySettings(period_width=PERIOD_WIDTH,
                                    pulse_width_width=PULSE_WIDTH_WIDTH)
        super().__init__({
            "write":        In(stream.Signature(RegisterWrite, always_ready=True)),
            "enable":       Out(1, init=reset["enable"]),
            "update":       Out(1),
            "settings":     Out(self.layout, init={**{name: reset[name] for name in DELAY_FIELDS},
                                               "mode": DelayMode(reset["mode"])}),
            "window_start": Out(WINDOW_WIDTH, init=reset["window_start"]),
            "window_end":   Out(WINDOW_WIDTH, init=reset["window_end"]),
            "refused":      Out(16),
        })

    def elaborate(self, platform):
        m = Module()
        write = self.write

        # Registers, by address: each is its output port, or a field of `settings` (the mode's
        # bits under its enum view)
        targets = [getattr(self, name) if name not in DELAY_FIELDS else
                   self.settings[name].as_value() if name == "mode" else self.settings[name]
                   for name, _ in REGISTERS]

        # Writes
        refused = Signal()
        delay_write = Signal()
        with m.Switch(write.payload.address):
            for address, ((name, width), target) in enumerate(zip(REGISTERS, targets)):
                with m.Case(address):
                    fits = (write.payload.data >> width) == 0
                    with m.If(write.valid & fits):
                        value = write.payload.data[:width]
                        m.d.sync += target.eq(value)
                    m.d.comb += [
                        refused.eq(write.valid & ~fits),
                        delay_write.eq(write.valid & fits & (name in DELAY_FIELDS)),
                    ]
            with m.Default():
                m.d.comb += refused.eq(write.valid)
        m.d.sync += self.update.eq(delay_write)
        with m.If(refused & (self.refused != 0xFFFF)):
            m.d.sync += self.refused.eq(self.refused + 1)

        return m
