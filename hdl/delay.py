from amaranth.hdl import *
from amaranth.lib import enum, stream, wiring
from amaranth.lib.wiring import In, Out

from .lfsr import MAX_LENGTH, POLYNOMIALS, _galois_step, _galois_steps


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
    kind : Out(2)
        Hint for :class:`~fliss.hdl.scheduler.PulseScheduler`: the mode.
    zero : Out(1)
        ``R == 0``, valid unless a transfer was made in the last cycle; low in the cycle after a
        load.
    zero_late : Out(1)
        ``R == 0`` of a transfer made in the cycle after a load, in the next cycle.
    wide : Out(32)
        The m-sequence state ``R + 1`` (zero standing for 1), or zero in another mode.
    narrow : Out(16)
        The masked delay ``R``, or zero in another mode.
    """

    mode:       In(DelayMode)
    length:     In(range(2, MAX_LENGTH + 1))
    mask_width: In(range(1, MAX_MASK_WIDTH + 1))
    seed:       In(MAX_LENGTH)
    load:       In(1)
    delays:     Out(stream.Signature(DELAY_WIDTH))
    kind:       Out(2)
    zero:       Out(1)
    zero_late:  Out(1)
    wide:       Out(DELAY_WIDTH)
    narrow:     Out(MAX_MASK_WIDTH)

    def elaborate(self, platform):
        m = Module()

        # The two registers are those of `Lfsr` (the m-sequence one with a run-time length, the
        # masked one taking `MASKED_STEPS` steps per advance), built here with a shorter path
        # from `load` and `delays.ready` to their state, and with hints for the scheduler.

        # Settings, sampled on load
        mode = Signal(DelayMode)
        mask = Signal(MAX_MASK_WIDTH)
        taps = Signal(MAX_LENGTH, init=POLYNOMIALS[MAX_LENGTH] >> 1)
        mask_in = Signal(MAX_MASK_WIDTH)
        length_mask_in = Signal(MAX_LENGTH)
        taps_in = Signal(MAX_LENGTH)
        with m.Switch(self.mask_width):
            for width in range(1, MAX_MASK_WIDTH + 1):
                with m.Case(width):
                    m.d.comb += mask_in.eq((1 << width) - 1)
            with m.Default():
                m.d.comb += mask_in.eq((1 << MAX_MASK_WIDTH) - 1)
        with m.Switch(self.length):
            for length, poly in POLYNOMIALS.items():
                with m.Case(length):
                    m.d.comb += [
                        length_mask_in.eq((1 << length) - 1),
                        taps_in.eq(poly >> 1),
                    ]
            with m.Default():
                m.d.comb += [
                    length_mask_in.eq((1 << MAX_LENGTH) - 1),
                    taps_in.eq(POLYNOMIALS[MAX_LENGTH] >> 1),
                ]
        with m.If(self.load):
            m.d.sync += [
                mode.eq(self.mode),
                # zero unless masked: `narrow` is zero then (see the scheduler)
                mask.eq(Mux(self.mode == DelayMode.MASKED, mask_in, 0)),
                taps.eq(taps_in),
            ]

        # Which register steps on a transfer
        advance = Signal(DelayMode)
        with m.If(self.delays.ready):
            m.d.comb += advance.eq(mode)

        # `R == 0` for the current delay, from zero flags made a cycle ahead into registers
        # (`zero`): in time for a transfer, as transfers by the scheduler are at least two cycles
        # apart, except in the cycle after a load, where `zero` is low. For a transfer in that
        # cycle, `zero_late` tells in the next cycle whether its delay was zero.
        fresh = Signal()            # loaded in the last cycle
        m.d.sync += fresh.eq(self.load)

        # m-sequence register. It is loaded with the seed's low `L` bits as they are: a zero state
        # stands for 1 (see `Lfsr`) and takes its first step as 1. A step in the cycle after the
        # load cannot know in time that the loaded state is zero: it steps 0 to 0, and the state
        # is set right (`step(1) = taps`) in the next cycle, `fixing`, before any other transfer
        # by the scheduler (the payload is right in that cycle too).
        mseq = Signal(MAX_LENGTH, init=1)
        mseq_raw_zero = Signal()    # `mseq` is zero, standing for 1
        fixing = Signal()
        mseq_seeded = self.seed & length_mask_in
        mseq_loaded_zero = mseq == 0
        mseq_advance = advance == DelayMode.MSEQ
        with m.If(self.load):
            m.d.sync += [
                # zero unless m-sequence: its zero flags are set then (see below)
                mseq.eq(Mux(self.mode == DelayMode.MSEQ, mseq_seeded, 0)),
                mseq_raw_zero.eq(0),
                fixing.eq(0),
            ]
        with m.Else():
            m.d.sync += [
                mseq_raw_zero.eq(Mux(fresh, mseq_loaded_zero, mseq_raw_zero) & ~mseq_advance),
                fixing.eq(fresh & mseq_loaded_zero & mseq_advance),
            ]
            with m.If(fixing):
                m.d.sync += mseq.eq(Mux(mseq_advance, _galois_step(taps, taps), taps))
            with m.Elif(mseq_advance):
                m.d.sync += mseq.eq(_galois_step(mseq | mseq_raw_zero, taps))
        mseq_state = Mux(fixing, taps, Mux(mseq == 0, 1, mseq))

        # Masked register
        masked = Signal(MASKED_LENGTH, init=1)
        masked_seeded = Cat(self.seed[0] | (self.seed[1:] == 0), self.seed[1:])
        masked_next = _galois_steps(masked, POLYNOMIALS[MASKED_LENGTH] >> 1, MASKED_STEPS)
        with m.If(self.load):
            m.d.sync += masked.eq(masked_seeded)
        with m.Elif(advance == DelayMode.MASKED):
            m.d.sync += masked.eq(masked_next)
        masked_delay = masked[:MAX_MASK_WIDTH] & mask

        # The register of the other mode is zero (its mask is zero), so that `R == 0` is when
        # both registers read zero.
        mseq_zero_lo = Signal()
        mseq_zero_hi = Signal()
        masked_zero = Signal()
        zero_late = Signal()
        m.d.sync += [
            mseq_zero_lo.eq((mseq[1:16] == 0) & ~fixing),
            mseq_zero_hi.eq(mseq[16:] == 0),
            masked_zero.eq(masked_delay == 0),
            zero_late.eq((mseq[1:] == 0) & (masked_delay == 0) & fresh & self.delays.ready),
        ]
        zero = mseq_zero_lo & mseq_zero_hi & masked_zero & ~fresh

        # Delay
        m.d.comb += self.delays.valid.eq(1)
        with m.Switch(mode):
            with m.Case(DelayMode.MSEQ):
                m.d.comb += self.delays.payload.eq(mseq_state - 1)
            with m.Case(DelayMode.MASKED):
                m.d.comb += self.delays.payload.eq(masked_delay)

        # Hints for the scheduler
        m.d.comb += [
            self.kind.eq(mode.as_value()),
            self.zero.eq(zero),
            self.zero_late.eq(zero_late),
            self.wide.eq(mseq),
            self.narrow.eq(masked_delay),
        ]

        return m
