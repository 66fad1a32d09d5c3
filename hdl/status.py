"""Status counters: the counters of a STATUS reply, in block RAM, with an exact snapshot."""

from amaranth.hdl import Module, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from .link.command import StatusSignature
from .counters import CounterBank
from .protocol import COUNTER_BITS, LINK_FIELDS, STATUS_FIELDS


__all__ = ["COUNTED_FIELDS", "LINK_FIELDS", "strobes_layout", "StatusCounters"]


#: The STATUS fields counted here from strobes: all but ``running`` (a level, from the command
#: processor), ``pulses`` (the victim scheduler's pulse index) and ``ivs_used_up`` (a level, from
#: the victim's keyed source), which come first and last.
COUNTED_FIELDS = STATUS_FIELDS[2:-1]
assert STATUS_FIELDS[-1] == "ivs_used_up"


def strobes_layout():
    return data.StructLayout({name: 1 for name in COUNTED_FIELDS})


class StatusCounters(wiring.Component):
    """The STATUS counters of the top level, behind the command processor's status port.

    Each counted field has a strobe; a :class:`~fliss.hdl.counters.CounterBank` counts them
    (saturating at ``2**32 - 1``, zero after reset). A capture on ``port`` takes an exact
    snapshot of all of them and of ``pulses`` in one cycle (the bank's ``captured``), at most
    ``len(COUNTED_FIELDS)`` cycles after it is asked for, with ``pulses`` and ``ivs_used_up``
    of the same cycle; the port reads field ``addr`` of
    :data:`~fliss.hdl.protocol.STATUS_FIELDS` one cycle later (``running`` reads as zero: the
    command processor sends its own).

    Members
    -------
    strobes : In(strobes_layout())
        One strobe per field of :data:`COUNTED_FIELDS`: each cycle it is high counts one.
    pulses : In(32)
        Victim pulses since the start.
    ivs_used_up : In(1)
        The victim's keyed source has used every IV under its key (its ``spent``).
    port : In(StatusSignature)
        To the command processor's ``status``.

    :meth:`count` drives ``strobes`` from the blocks' own ``tally`` strobes.
    """

    strobes: In(strobes_layout())
    pulses:  In(COUNTER_BITS)
    ivs_used_up: In(1)
    port:    In(StatusSignature)

    def count(self, tally, **names):
        """Statements that count each strobe of a block's ``tally`` (a view of one-bit fields)
        in the counter of the same name, or of the name ``names`` gives it (``None``: not
        counted here). A strobe with no counter is refused, so that none is left out unseen,
        and so is a name in ``names`` that the tally does not have."""
        strobes = [name for name, _ in data.Layout.cast(tally.shape())]
        for name in names:
            if name not in strobes:
                raise ValueError(f"No tally strobe {name!r} to count")
        statements = []
        for name in strobes:
            field = names.get(name, name)
            if field is None:
                continue
            if field not in COUNTED_FIELDS:
                raise ValueError(f"No STATUS counter {field!r} for the tally strobe {name!r}")
            statements.append(self.strobes[field].eq(tally[name]))
        return statements

    def elaborate(self, platform):
        m = Module()

        m.submodules.bank = bank = CounterBank(len(COUNTED_FIELDS), width=COUNTER_BITS)
        m.d.comb += [
            bank.inc.eq(self.strobes.as_value()),
            bank.capture.eq(self.port.capture),
            self.port.ready.eq(bank.ready),
        ]

        pulses = Signal(COUNTER_BITS)
        ivs_used_up = Signal()
        with m.If(bank.captured):
            m.d.sync += [pulses.eq(self.pulses), ivs_used_up.eq(self.ivs_used_up)]

        first = STATUS_FIELDS.index(COUNTED_FIELDS[0])
        field = Signal.like(self.port.addr)
        m.d.sync += field.eq(self.port.addr)
        m.d.comb += bank.read_addr.eq(self.port.addr - first)
        with m.Switch(field):
            with m.Case(STATUS_FIELDS.index("pulses")):
                m.d.comb += self.port.data.eq(pulses)
            with m.Case(STATUS_FIELDS.index("ivs_used_up")):
                m.d.comb += self.port.data.eq(ivs_used_up)
            with m.Case(STATUS_FIELDS.index("running")):
                m.d.comb += self.port.data.eq(0)
            with m.Default():
                m.d.comb += self.port.data.eq(bank.read_data)

        return m
