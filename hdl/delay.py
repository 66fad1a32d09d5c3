from amaranth.hdl import *
from amaranth.lib import enum, stream, wiring
from amaranth.lib.wiring import In, Out

from .lfsr import Lfsr, MAX_LENGTH


__all__ = ["DelayMode", "MAX_MASK_WIDTH", "MASKED_LENGTH", "MASKED_STEPS", "DELAY_WIDTH",
           "DelaySource"]


#: Widest bit-mask of the ``masked`` source, in bits.
MAX_MASK_WIDTH = 16

#: Length of the register behind the ``masked`` source, in bits.
MASKED_LENGTH = 32

#: Register steps per pulse of the ``masked`` source. With at least ``MAX_MASK_WIDTH`` steps,
#: consecutive delays are taken from fresh register bits rather than from shifted copies of the
#: previous delay; 16 is coprime with ``2**32 - 1``, so the sequence still has the full period.
MASKED_STEPS = 16

#: Width of a delay, in bits.
DELAY_WIDTH = MAX_LENGTH


class DelayMode(enum.Enum, shape=2):
    """Source of the pseudorandom delay ``T_rnd``, in clock cycles."""
    #: No delay: the laser fires on the nominal schedule.
    OFF    = 0
    #: Complete m-sequence of an ``L``-bit register, one state per pulse; delay ``R = state - 1``,
    #: so ``R`` runs over ``0 … 2**L - 2`` once per period (equation 9 and Table 2 of the paper).
    MSEQ   = 1
    #: The ``Wm`` least significant bits of a 32-bit register that takes ``MASKED_STEPS`` steps per
    #: pulse; delay from ``0`` to ``2**Wm - 1``.
    MASKED = 2


class DelaySource(wiring.Component):
    """Pseudorandom delay source.

    Produces one delay per transfer on ``delays``. The mode, register length, mask width and seed
    are run-time settings, sampled on ``load``; ``load`` also restarts the sequence from the seed.

    Members
    -------
    mode : In(DelayMode)
        Delay source, sampled on ``load``.
    length : In(range(2, 33))
        Register length ``L`` of the ``MSEQ`` source, sampled on ``load``.
    mask_width : In(range(1, 17))
        Mask width ``Wm`` of the ``MASKED`` source, sampled on ``load``; a value out of range acts
        as 16.
    seed : In(32)
        Seed; the register never holds zero (see :class:`Lfsr`).
    load : In(1)
        Sample the settings and restart the sequence. The delay of the restarted sequence is on
        ``delays.payload`` in the next cycle.
    delays : Out(stream.Signature(32))
        Delays in clock cycles. ``valid`` is always high; each transfer moves to the next delay.
    """

    mode:       In(DelayMode)
    length:     In(range(2, MAX_LENGTH + 1))
    mask_width: In(range(1, MAX_MASK_WIDTH + 1))
    seed:       In(MAX_LENGTH)
    load:       In(1)
    delays:     Out(stream.Signature(DELAY_WIDTH))

    def elaborate(self, platform):
        m = Module()

        m.submodules.mseq = mseq = Lfsr()
        m.submodules.masked = masked = Lfsr(length=MASKED_LENGTH, steps=MASKED_STEPS)

        # Settings, sampled on load
        mode = Signal(DelayMode)
        mask = Signal(MAX_MASK_WIDTH)
        with m.If(self.load):
            m.d.sync += mode.eq(self.mode)
            with m.Switch(self.mask_width):
                for width in range(1, MAX_MASK_WIDTH + 1):
                    with m.Case(width):
                        m.d.sync += mask.eq((1 << width) - 1)
                with m.Default():
                    m.d.sync += mask.eq((1 << MAX_MASK_WIDTH) - 1)

        # Registers
        m.d.comb += [
            mseq.length.eq(self.length),
            mseq.seed.eq(self.seed),
            mseq.load.eq(self.load),
            masked.seed.eq(self.seed),
            masked.load.eq(self.load),
        ]
        with m.If(self.delays.ready):
            with m.Switch(mode):
                with m.Case(DelayMode.MSEQ):
                    m.d.comb += mseq.advance.eq(1)
                with m.Case(DelayMode.MASKED):
                    m.d.comb += masked.advance.eq(1)

        # Delay
        m.d.comb += self.delays.valid.eq(1)
        with m.Switch(mode):
            with m.Case(DelayMode.MSEQ):
                m.d.comb += self.delays.payload.eq(mseq.state - 1)
            with m.Case(DelayMode.MASKED):
                m.d.comb += self.delays.payload.eq(masked.state & mask)

        return m
