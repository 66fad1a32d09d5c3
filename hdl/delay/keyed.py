"""Keystream of the ``keyed`` delay source: Trivium, its bit buffer, and the IV rule."""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from .settings import IV_BITS, KEY_BITS, KEYED_ROUNDS, MAX_MASK_WIDTH
from .trivium import TriviumCore


__all__ = ["Keying", "KeyedStream"]


class Keying(data.Struct):
    """The key and IV of the ``keyed`` source, as the registers hold them (the fields of
    :data:`~fliss.hdl.registers.KEYING`): the 80-bit integers their printed bytes spell, in
    32-bit words, least significant first."""
    iv0:  32
    iv1:  32
    iv2:  IV_BITS - 64
    key0: 32
    key1: 32
    key2: KEY_BITS - 64


class KeyedStream(wiring.Component):
    """Keystream bits for the ``keyed`` delay source, always a delay's worth in hand.

    Trivium (:class:`~fliss.hdl.delay.trivium.TriviumCore`, ``KEYED_ROUNDS`` bits a cycle) fills a
    32-bit buffer whenever it holds 16 bits or fewer; a take removes ``width`` bits from its
    bottom. Once initialised, the buffer never holds fewer than 16 bits, even with a take in
    every cycle.

    The IV rule: a load in keyed mode initialises Trivium again if the key or IV was written
    since the last initialisation (``rekey``; from the IV written), or if bits were taken since
    (with the IV in use plus one). Under one key the IVs used thus only grow, so the keystream is
    never replayed (the register file refuses an IV written not above the one in use). The IV
    never wraps around: once bits of the last IV's (``2**80 - 1``) keystream were taken, the
    next load does not initialise but leaves the source ``spent`` (its buffer emptied, so
    ``busy`` stays high and no delay is given) until a load after a key write initialises it.

    Members
    -------
    keying : In(Keying)
        Key and IV, sampled by a load that initialises.
    rekey : In(1)
        The key or the IV was written (in the cycle before ``keying`` shows it).
    load : In(1)
    keyed : In(1)
        A load of the delay source; ``keyed``: its mode is ``keyed``.
    take : In(1)
    width : In(range(MAX_MASK_WIDTH + 1))
        Remove ``width`` bits (a delay's worth) from the buffer; ``width`` is sampled on
        ``load``.
    bits : Out(MAX_MASK_WIDTH)
        The next keystream bits, the first at bit 0.
    busy : Out(1)
        No delay in hand: from the cycle after a load that initialises until the buffer has
        its first bits, and while spent (a take then is ignored). Straight from a register's
        compare, for the scheduler's enable.
    iv : Out(80)
        The IV of the keystream in use (or being initialised).
    spent : Out(1)
        Every IV under the key is used: a load (in any mode) found the last IV's keystream
        taken from and no key or IV written since, so the source gives no delay; low again from
        the cycle after a write of the key (``rekey``). From registers only.
    """

    keying: In(Keying)
    rekey:  In(1)
    load:   In(1)
    keyed:  In(1)
    take:   In(1)
    width:  In(range(MAX_MASK_WIDTH + 1))
    bits:   Out(MAX_MASK_WIDTH)
    busy:   Out(1)
    iv:     Out(IV_BITS)
    spent:  Out(1)

    def elaborate(self, platform):
        m = Module()
        keying = self.keying

        m.submodules.trivium = trivium = TriviumCore(rounds=KEYED_ROUNDS)

        # Bit buffer: `level` bits at the bottom of `buffer`, in keystream order. `width` is
        # sampled on load; `level_w` (`level - width`, the level after a take) and `has_bits`
        # (`level != 0`) are kept in registers beside `level`, so that a take only selects
        # between two next states computed from registers.
        buffer = Signal(2 * MAX_MASK_WIDTH)
        level = Signal(range(2 * MAX_MASK_WIDTH + 1))
        width = Signal.like(self.width)
        level_w = Signal.like(level)
        has_bits = Signal()

        # When to initialise, and with which IV. `iv_next` and `last` (the IV in use is all
        # ones: `iv + 1` carries out) follow `iv` a cycle late: bits are taken only long after
        # an initialisation. Once bits of the last IV's keystream were taken, any load (in any
        # mode: every cycle while stopped) with no key or IV written since makes the source
        # `spent` (`refuse`) instead, until an initialisation after a key write.
        pending = Signal(init=1)    # key or IV written since the last initialisation
        used = Signal()             # bits taken since the last initialisation
        spent = Signal()            # every IV under the key used: no keystream
        iv_next = Signal(IV_BITS)
        last = Signal()
        restart = Signal()
        refuse = Signal()
        m.d.comb += [
            restart.eq(self.load & self.keyed & (pending | (used & ~last))),
            refuse.eq(self.load & ~pending & used & last),
        ]
        m.d.sync += Cat(iv_next, last).eq(self.iv + 1)
        written_iv = Cat(keying.iv0, keying.iv1, keying.iv2)
        start_iv = Mux(pending, written_iv, iv_next)
        m.d.comb += [
            trivium.key.eq(Cat(keying.key0, keying.key1, keying.key2)),
            trivium.iv.eq(start_iv),
            trivium.load.eq(restart),
        ]
        taking = self.take & has_bits
        with m.If(taking):
            m.d.sync += used.eq(1)
        with m.If(restart):
            # (a take in this cycle is of the keystream before)
            m.d.sync += [self.iv.eq(start_iv), pending.eq(0), used.eq(0), spent.eq(0)]
        with m.If(refuse):
            m.d.sync += spent.eq(1)
        with m.If(self.rekey):
            m.d.sync += pending.eq(1)

        width_next = Mux(self.load, self.width, width)
        m.d.sync += width.eq(width_next)
        # Next states with and without a take; Trivium fills when 16 bits or fewer would stay
        fill_t = trivium.ready & (level_w <= MAX_MASK_WIDTH)
        fill_n = trivium.ready & (level <= MAX_MASK_WIDTH)
        buffer_t = (buffer >> width) | Mux(fill_t, trivium.z << level_w, 0)
        buffer_n = buffer | Mux(fill_n, trivium.z << level, 0)
        level_t = level_w + Mux(fill_t, KEYED_ROUNDS, 0)
        level_n = level + Mux(fill_n, KEYED_ROUNDS, 0)
        # (emptied by an initialisation, and kept empty while spent)
        empty = restart | refuse | spent
        level_next = Signal.like(level)
        m.d.comb += [
            level_next.eq(Mux(empty, 0, Mux(taking, level_t, level_n))),
            trivium.next.eq(Mux(taking, fill_t, fill_n)),
        ]
        m.d.sync += [
            buffer.eq(Mux(empty, 0, Mux(taking, buffer_t, buffer_n))),
            level.eq(level_next),
            level_w.eq(level_next - width_next),
            has_bits.eq(level_next != 0),
        ]
        m.d.comb += [
            self.bits.eq(buffer[:MAX_MASK_WIDTH]),
            self.busy.eq(~has_bits),
            self.spent.eq(spent & ~pending),
        ]

        return m
