from amaranth.hdl import Cat, Module, Mux, Shape, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from .keyed import Keying, KeyedStream
from .lfsr import POLYNOMIALS, _galois_step, _galois_steps
from ..registers import DelaySettings
from .modes import DelayMode
from .settings import (IV_BITS, MAX_LENGTH, MAX_MASK_WIDTH, DELAY_WIDTH, MASKED_LENGTH,
                       MASKED_STEPS)


__all__ = ["DelayMode", "MAX_MASK_WIDTH", "MASKED_LENGTH", "MASKED_STEPS", "DELAY_WIDTH",
           "Delay", "DelaySource"]


class Delay(data.Struct):
    """A delay of :class:`DelaySource`, with hints that time its pulse in the scheduler
    (:class:`~fliss.hdl.delay.scheduler.PulseScheduler`).

    ``value`` stays put until a transfer; ``zero`` and ``zero_late`` are timed as described
    below, so they may change while the delay waits.
    """
    #: The delay ``R`` in clock cycles.
    value:     DELAY_WIDTH
    #: The mode (a :class:`DelayMode` value).
    kind:      Shape.cast(DelayMode).width
    #: ``R == 0``, valid unless a transfer was made in the last cycle; low in the cycle after a
    #: load.
    zero:      1
    #: ``R == 0`` of a transfer made in the cycle after a load, in the next cycle.
    zero_late: 1
    #: The m-sequence state ``R + 1`` (zero standing for 1), or zero in another mode.
    wide:      DELAY_WIDTH
    #: The masked or keyed delay ``R``, or zero in another mode.
    narrow:    MAX_MASK_WIDTH


class DelaySource(wiring.Component):
    """Pseudorandom delay source.

    Produces one delay per transfer on ``delays``. The mode, register length, mask width and seed
    are run-time settings, sampled on ``load``; ``load`` also restarts the sequence from the seed.

    Parameters
    ----------
    layout : DelaySettings
        Layout of ``settings`` (that of the delay core around the source).
    keyed : bool
        Build the ``KEYED`` source (:class:`~fliss.hdl.delay.keyed.KeyedStream`). Without it, a
        ``KEYED`` mode gives zero delays (the register file refuses it).

    Members
    -------
    settings : In(layout)
        Of the delay core's settings, the source uses ``mode`` (the delay source),
        ``length`` (register length ``L`` of the ``MSEQ`` source), ``mask_width`` (mask width
        ``Wm`` of the ``MASKED`` source; a value out of range acts as 16) and ``seed`` (the
        register never holds zero, see :class:`~.lfsr.Lfsr`), all sampled on ``load``.
    load : In(1)
        Sample the settings and restart the sequence. The delay of the restarted sequence is on
        ``delays.payload`` in the next cycle.
    delays : Out(stream.Signature(Delay, always_valid=True))
        Delays in clock cycles, with hints for the scheduler (:class:`Delay`); each transfer
        moves to the next delay.
    keying : In(Keying)
        Key and IV of the ``KEYED`` source (only if ``keyed``).
    rekey : In(1)
        The key or the IV was written (only if ``keyed``).
    busy : Out(1)
        In ``KEYED`` mode, no delay is in hand: the scheduler must not run (it stops, and
        starts again once ``busy`` falls). A load in ``KEYED`` mode after a key or IV write, or
        after delays were taken, initialises Trivium again: ``busy`` from the cycle after it
        until :data:`~fliss.hdl.delay.settings.KEYED_START_CYCLES` cycles after it (a transfer while
        ``busy`` is ignored). It stays high while the source is ``spent``. From registers only.
        Low if not ``keyed``.
    iv : Out(80)
        The IV of the ``KEYED`` source in use (only if ``keyed``).
    spent : Out(1)
        The ``KEYED`` source has used every IV under its key and gives no delay until a key is
        written (only if ``keyed``; :class:`~fliss.hdl.delay.keyed.KeyedStream` ``spent``).
    """

    def __init__(self, *, layout=None, keyed=True):
        if not isinstance(keyed, bool):
            raise TypeError(f"keyed must be True or False, not {keyed!r}")
        self.layout = DelaySettings() if layout is None else layout
        self.keyed = keyed
        ports = {
            "settings": In(self.layout),
            "load":     In(1),
            "delays":   Out(stream.Signature(Delay, always_valid=True)),
            "busy":     Out(1),
        }
        if keyed:
            ports.update(keying=In(Keying), rekey=In(1), iv=Out(IV_BITS), spent=Out(1))
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()
        settings = self.settings

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
        with m.Switch(settings.mask_width):
            for width in range(1, MAX_MASK_WIDTH + 1):
                with m.Case(width):
                    m.d.comb += mask_in.eq((1 << width) - 1)
            with m.Default():
                m.d.comb += mask_in.eq((1 << MAX_MASK_WIDTH) - 1)
        with m.Switch(settings.length):
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
        keyed_mask = Signal(MAX_MASK_WIDTH)
        keyed_width = Signal(range(MAX_MASK_WIDTH + 1))     # (sampled by the keyed stream)
        m.d.comb += keyed_width.eq(Mux((settings.mask_width >= 1) &
                                       (settings.mask_width <= MAX_MASK_WIDTH),
                                       settings.mask_width, MAX_MASK_WIDTH))
        with m.If(self.load):
            m.d.sync += [
                mode.eq(settings.mode),
                # zero unless masked (keyed): `narrow` is zero then (see the scheduler)
                mask.eq(Mux(settings.mode == DelayMode.MASKED, mask_in, 0)),
                keyed_mask.eq(Mux(settings.mode == DelayMode.KEYED, mask_in, 0)),
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
        mseq_seeded = settings.seed & length_mask_in
        mseq_loaded_zero = mseq == 0
        mseq_advance = advance == DelayMode.MSEQ
        with m.If(self.load):
            m.d.sync += [
                # zero unless m-sequence: its zero flags are set then (see below)
                mseq.eq(Mux(settings.mode == DelayMode.MSEQ, mseq_seeded, 0)),
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
        masked_seeded = Cat(settings.seed[0] | (settings.seed[1:] == 0), settings.seed[1:])
        masked_next = _galois_steps(masked, POLYNOMIALS[MASKED_LENGTH] >> 1, MASKED_STEPS)
        with m.If(self.load):
            m.d.sync += masked.eq(masked_seeded)
        with m.Elif(advance == DelayMode.MASKED):
            m.d.sync += masked.eq(masked_next)
        masked_delay = masked[:MAX_MASK_WIDTH] & mask

        # Keyed source: `keyed_width` keystream bits per delay
        keyed_delay = Signal(MAX_MASK_WIDTH)
        if self.keyed:
            m.submodules.keyed = keyed = KeyedStream()
            m.d.comb += [
                keyed.keying.eq(self.keying),
                keyed.rekey.eq(self.rekey),
                keyed.load.eq(self.load),
                keyed.keyed.eq(settings.mode == DelayMode.KEYED),
                keyed.take.eq(advance == DelayMode.KEYED),
                keyed.width.eq(keyed_width),
                keyed_delay.eq(keyed.bits & keyed_mask),
                self.iv.eq(keyed.iv),
                self.spent.eq(keyed.spent),
                self.busy.eq(keyed.busy & (mode == DelayMode.KEYED)),
            ]
        narrow = masked_delay | keyed_delay

        # The register of the other mode is zero (its mask is zero), so that `R == 0` is when
        # both registers read zero.
        mseq_zero_lo = Signal()
        mseq_zero_hi = Signal()
        masked_zero = Signal()
        zero_late = Signal()
        m.d.sync += [
            mseq_zero_lo.eq((mseq[1:16] == 0) & ~fixing),
            mseq_zero_hi.eq(mseq[16:] == 0),
            masked_zero.eq(narrow == 0),
            zero_late.eq((mseq[1:] == 0) & (narrow == 0) & fresh & self.delays.ready),
        ]
        zero = mseq_zero_lo & mseq_zero_hi & masked_zero & ~fresh

        # Delay, and hints for the scheduler
        delay = self.delays.payload
        with m.Switch(mode):
            with m.Case(DelayMode.MSEQ):
                m.d.comb += delay.value.eq(mseq_state - 1)
            with m.Case(DelayMode.MASKED, DelayMode.KEYED):
                m.d.comb += delay.value.eq(narrow)
        m.d.comb += [
            delay.kind.eq(mode.as_value()),
            delay.zero.eq(zero),
            delay.zero_late.eq(zero_late),
            delay.wide.eq(mseq),
            delay.narrow.eq(narrow),
        ]

        return m
