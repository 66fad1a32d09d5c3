"""Register file: the settings, their range and consistency checks, and the commit of a WRITE."""

from functools import reduce
from operator import or_

from amaranth.hdl import Array, Cat, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import lookup
from .clock import DEFAULT_CLOCK_HZ
from .protocol import NakCode
from .registers import (REGISTERS, GROUPS, DELAY_SETTINGS, FINE_TDC, KEYED_SOURCE, KEYING,
                        settings_layout, defaults, register_maxima)
from .event import ADDRESS_BITS, TIMESTAMP_BITS
from .delay.modes import MODES, missing_modes
from .finetdc import TABLE_BITS as FINE_TABLE_BITS
from .delay.settings import BANK_BITS, MAX_BANK_BITS, MIN_BANK_BITS, IV_BITS


__all__ = ["RegisterFile"]


class RegisterFile(wiring.Component):
    """Register file of :mod:`fliss.hdl.registers`, written by the command processor.

    A command begins with a copy of the settings as the candidate; a WRITE puts its values, one
    at a time, into the candidate: each value is range-checked (its register's minimum and
    maximum), and the settings the candidate makes are checked together
    (:func:`fliss.hdl.registers.problems`); ``commit`` then applies every value written at once.

    Parameters
    ----------
    clock_hz : int
        Clock frequency, for the reset values.
    maxima : dict
        Register name -> a lower maximum than the register map's
        (:func:`~fliss.hdl.registers.register_maxima`).
    bank_bits : int
        Width of the histogram bank's address, from 13 (the reset split, one pixel of 8192
        bins, must fit) to 19: a split with ``pixel_bits + 13 - bin_shift > bank_bits`` is
        inconsistent (:func:`~fliss.hdl.registers.split_problems`).

    Members
    -------
    begin : In(1)
        A command begins: forget the values written and the error, copy the settings into the
        candidate.
    start : In(1)
        The first value of a WRITE goes to register ``start_address``.
    start_address : In(16)
    value : In(32)
        The value being received; complete in the cycle before ``check``.
    check : In(1)
        ``value`` is complete: check it, put it in the candidate, and move to the next address.
    error : Out(1)
        A value was refused, two cycles after its ``check`` (the first refusal stays):
    error_code : Out(NakCode)
        ``BAD_ADDRESS`` (no such register) or ``OUT_OF_RANGE``;
    error_detail : Out(16)
        the address of the value refused.
    consistent : Out(1)
        The candidate settings are consistent, three cycles after they are complete.
    commit : In(1)
        Apply the values written.
    read_address : In(range(len(REGISTERS) + 2))
    read_data : Out(32)
        The register at ``read_address``, as a u32: 0 for a write-only register (the key), the
        value in use for the IV (``iv``).
    iv : In(80)
        The IV in use by the keyed source, read as the IV registers; a WRITE of the IV without
        the key must put it above this (:func:`~fliss.hdl.registers.iv_problem`), unless the
        maxima hold the key and IV at 0 (a build without the keyed source).
    rekey : Out(1)
        A commit writes the key or the IV (to the keyed source).
    table_seek, table_write : Out(1)
        A commit wrote ``table_address``, ``table_data`` (to the fine TDC's calibration table):
        high in the cycle after the commit, when ``fine_tdc`` holds the values written.
    table_read : In(TABLE_BITS)
        The calibration table's entry at its pointer, read as ``table_data``.
    settings : Out(settings_layout(maxima))
        Every register, each as wide as its maximum needs.
    victim, aggressor, aggressor_delay, acquisition, gate, histogram, depth, fine_tdc, keying
        The registers of each group of :data:`~fliss.hdl.registers.GROUPS`, as its struct
        (``Out(group.layout(maxima))``).
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, maxima=None, bank_bits=BANK_BITS):
        if not isinstance(bank_bits, int) or not MIN_BANK_BITS <= bank_bits <= MAX_BANK_BITS:
            raise ValueError(f"Histogram bank address width must be an integer from "
                             f"{MIN_BANK_BITS} to {MAX_BANK_BITS} bits, not {bank_bits!r}")
        self.bank_bits = bank_bits
        self.clock_hz = int(clock_hz)
        self.maxima = register_maxima(maxima, self.clock_hz)
        # Without the keyed source (key and IV held at 0), no IV rule and no `rekey`
        self._keyed = any(self.maxima[r.name] for r in KEYING.members)
        super().__init__({
            "begin":         In(1),
            "start":         In(1),
            "start_address": In(16),
            "value":         In(32),
            "check":         In(1),
            "error":         Out(1),
            "error_code":    Out(NakCode, init=NakCode.BAD_ADDRESS),
            "error_detail":  Out(16),
            "consistent":    Out(1),
            "commit":        In(1),
            "read_address":  In(range(len(REGISTERS) + 2)),
            "read_data":     Out(32),
            "iv":            In(IV_BITS),
            "rekey":         Out(1),
            "table_seek":    Out(1),
            "table_write":   Out(1),
            "table_read":    In(FINE_TABLE_BITS),
            "settings":      Out(settings_layout(self.maxima), init=defaults(self.clock_hz)),
            **{group.name: Out(group.layout(self.maxima)) for group in GROUPS},
        })

    def elaborate(self, platform):
        m = Module()

        settings = self.settings
        layout = settings_layout(self.maxima)
        address_bits = (len(REGISTERS) - 1).bit_length()    # enough to address every register

        # Groups: the registers of each, as its struct
        for group in GROUPS:
            port = getattr(self, group.name)
            m.d.comb += [port[r.field].eq(settings[r.name]) for r in group.members]
            m.d.comb += [port[name].eq(value) for name, value in group.fixed.items()]

        # Registers as u32 words, in address order
        words = Array(Signal(32, name=f"reg_{r.name}") for r in REGISTERS)
        for register, word in zip(REGISTERS, words):
            if register.write_only:
                continue        # (reads 0)
            if register.in_use:
                index = int(register.field[-1])
                m.d.comb += word.eq(self.iv[32 * index:32 * index + register.width])
            elif register.name == "table_data":
                m.d.comb += word.eq(self.table_read)
            else:
                m.d.comb += word.eq(settings[register.name])
        m.d.comb += self.read_data.eq(words[self.read_address])

        # A command begins by copying `settings` into `candidate`; a WRITE puts its values
        # there and marks them in `written` (for the keyed source's rules). The candidate is
        # then the settings the WRITE would make, as the consistency checks need them, and a
        # commit copies it all. (The copy's multiplexer in front of each candidate bit shares
        # the bit's logic cell with it; choosing between candidate and settings for the
        # checks instead took a LUT of its own per bit checked.)
        candidate = Signal(layout, init=defaults(self.clock_hz))
        written = Signal(len(REGISTERS))

        # Range check of a WRITE value, one cycle after it completes (`check`; the value is
        # still in `value` then), its verdict registered and applied a cycle later: its
        # register's bounds come out of constant tables, so one set of comparators serves them
        # all. The minima are small, and the maxima are small or all ones below their top bit,
        # so the bits from `LOW` up are only checked against a mask (the bits the register's
        # values may have) and the comparators are `LOW` bits wide.
        LOW = 6
        for register in REGISTERS:
            top = self.maxima[register.name]
            assert register.minimum < 1 << LOW, register
            assert top < 1 << LOW or top & (top + 1) == 0, register
        value = self.value
        value_address = Signal(16)      # address of the value being received
        known = Signal()
        allowed = Signal(32)            # bits that may be set: `maximum` rounded up to all ones
        minimum = Signal(LOW)
        maximum = Signal(LOW)           # `maximum`, or all ones if that is larger
        # (The bounds are looked up into registers, from tables indexed by the low bits of the
        # address: the address was set, or moved on, at least four cycles before the value at
        # it is complete.)
        register_index = value_address[:address_bits]
        tops = [self.maxima[register.name] for register in REGISTERS]
        m.d.sync += [
            known.eq((value_address[address_bits:] == 0) & (register_index < len(REGISTERS))),
            allowed.eq(lookup([(1 << top.bit_length()) - 1 for top in tops], register_index, 32,
                              rom=True)),
            minimum.eq(lookup([register.minimum for register in REGISTERS], register_index, LOW,
                              rom=True)),
            maximum.eq(lookup([min(top, (1 << LOW) - 1) for top in tops], register_index, LOW,
                              rom=True)),
        ]
        out_of_range = ((value & ~allowed).any() |
                        ((value[LOW:] == 0) & (value[:LOW] < minimum)) |
                        (value[:LOW] > maximum))
        checked = Signal()              # the verdict on the value checked in the last cycle:
        checked_unknown = Signal()      # no register at its address
        checked_bad = Signal()          # out of its register's range
        checked_address = Signal(16)
        m.d.sync += [
            checked.eq(self.check),
            checked_unknown.eq(~known),
            checked_bad.eq(out_of_range),
            checked_address.eq(value_address),
        ]
        with m.If(checked & ~self.error):
            with m.If(checked_unknown):
                m.d.sync += [self.error.eq(1), self.error_code.eq(NakCode.BAD_ADDRESS),
                             self.error_detail.eq(checked_address)]
            with m.Elif(checked_bad):
                m.d.sync += [self.error.eq(1), self.error_code.eq(NakCode.OUT_OF_RANGE),
                             self.error_detail.eq(checked_address)]
        with m.If(self.check):
            # (Decoded from the low bits of the address only: a value whose address has high
            # bits set lands on some register here, but it is refused above, so the WRITE is
            # never committed.)
            with m.Switch(register_index):
                for register in REGISTERS:
                    with m.Case(register.address):
                        m.d.sync += candidate[register.name].eq(value)
            # (its flag in `written` set through a decoder of the whole word: the same logic
            # as a flag set per case, and one operation, not one a flag, in a simulator)
            m.d.sync += written.eq(written | (1 << register_index)[:len(written)])
            m.d.sync += value_address.eq(value_address + 1)
        with m.If(self.start):
            m.d.sync += value_address.eq(self.start_address)
        with m.If(self.begin):
            m.d.sync += [self.error.eq(0), written.eq(0), candidate.eq(settings)]

        # Commit (a build without the keyed source has no key or IV: nothing to tell it)
        if self._keyed:
            m.d.comb += self.rekey.eq(self.commit & Cat(written[r.address]
                                                        for r in KEYING.members).any())
        fine = {r.field: r.address for r in FINE_TDC.members}
        # (the cycle after the commit, when `settings` hold the values written)
        m.d.sync += [self.table_seek.eq(self.commit & written[fine["table_address"]]),
                     self.table_write.eq(self.commit & written[fine["table_data"]])]
        with m.If(self.commit):
            m.d.sync += settings.eq(candidate)

        # Consistency of the candidate settings
        self._consistency(m, candidate, written)

        return m

    def _consistency(self, m, c, written):
        # Consistency of the candidate settings `c`, in three registered steps (the largest
        # delays and the seeds' high bits, then the sum for the grid condition); it is needed
        # three cycles after the candidate is complete. The checks of each delay core's group
        # are made from its group definition and the table of delay modes.

        def below(n, width):
            # `(1 << n) - 1` in `width` bits (all ones from `n = width` on), out of a constant
            # table: a little logic per bit, where a shifter by `n` would be a barrel shifter
            # (and comparators per bit would be carry chains).
            return lookup([min((1 << k) - 1, (1 << width) - 1) for k in range(1 << len(n))],
                          n, width, rom=True)

        def power_less(n, less):
            # `2**n - less` (`less` 1 or 2) for each `n` the field holds, in at most 34 bits
            # (all ones from there on, and where it would be negative)
            width = min(34, (1 << len(n)) - 1)
            if less == 1:
                return below(n, width)
            zero = n == 0
            return Cat(zero, below(n, width)[1:] | zero.replicate(width - 1))

        def max_delay(g):
            # The largest delay of the mode `g["mode"]` (:meth:`~.delay.modes.Mode.max_delay`): `2**n - less`
            # of its size setting `n`, zero without one; modes of the same size share it.
            sized = {}
            for row in MODES.values():
                if row.size is not None:
                    sized.setdefault((row.size, row.less), []).append(row.mode)
            largest = 0
            for (size, less), modes in reversed(sized.items()):
                largest = Mux(reduce(or_, (g["mode"] == mode for mode in modes)),
                              power_less(g[size], less), largest)
            return largest

        def narrow_less(a, b):
            # `a < b` for a narrower `a`: the high bits of `b` need no carry chain
            return (b[len(a):] != 0) | (a < b[:len(a)])

        def seed_high(seed, length):
            # The bits of `seed` at `2**length` and up (without the shifter), OR-ed in groups of
            # four: all zeros when the seed fits in `length` bits.
            high = seed & ~below(length, len(seed))
            return Cat(high[k:k + 4].any() for k in range(0, len(high), 4))

        simple = [c.gate_start <= c.gate_end]       # in the first step
        # The histogram's pixel split: it fits the bank (pixel_bits + 13 - bin_shift <=
        # bank_bits), and its pixels are addresses of the sensor (first_pixel + 2**pixel_bits
        # <= 64; the power of two out of a table)
        pixels = lookup([1 << k for k in range(1 << len(c.pixel_bits))], c.pixel_bits, rom=True)
        simple += [c.pixel_bits + TIMESTAMP_BITS <= c.bin_shift + self.bank_bits,
                   c.first_pixel + pixels <= (1 << ADDRESS_BITS)]
        # The IV rule: an IV written without a key goes above the IV in use
        keying = {r.field: r for r in KEYING.members}
        iv_written = Cat(written[keying[f"iv{k}"].address] for k in range(3)).any()
        key_written = Cat(written[keying[f"key{k}"].address] for k in range(3)).any()
        iv_above = Signal()
        m.d.sync += iv_above.eq(Cat(c.iv0, c.iv1, c.iv2) > self.iv)

        seeds = []                                  # in the second step
        grids = []                                  # in the third step
        if self._keyed:
            seeds.append(iv_written & ~key_written & ~iv_above)
        for group in GROUPS:
            if group.settings is not DELAY_SETTINGS:
                continue
            g = {r.field: c[r.name] for r in group.members}
            simple.append(narrow_less(g["pulse_width"], g["period"]))
            # a mode that the core has not, below its register's maximum
            simple += [g["mode"] != row.mode for row in
                       missing_modes(self._keyed and KEYED_SOURCE[group.name])]
            # a mode whose seed is a state of a register as long as a setting says
            for row in MODES.values():
                if not isinstance(row.seed_bits, str):
                    continue
                moded = Signal(name=f"{group.name}_{row.name}")
                high = Signal((len(g["seed"]) + 3) // 4, name=f"{group.name}_seed_high")
                m.d.sync += [moded.eq(g["mode"] == row.mode),
                             high.eq(seed_high(g["seed"], g[row.seed_bits]))]
                seeds.append(moded & high.any())
            if "grid" in g:
                largest = Signal(34, name=f"{group.name}_max_delay")
                delay_and_pulse = Signal(35, name=f"{group.name}_delay_and_pulse")
                m.d.sync += [largest.eq(max_delay(g)),
                             delay_and_pulse.eq(largest + g["pulse_width"])]
                grids.append(~g["grid"] | (delay_and_pulse < g["period"]))

        first = Signal()
        all_but_grid = Signal()
        m.d.sync += [
            first.eq(Cat(simple).all()),
            all_but_grid.eq(first & ~Cat(seeds).any()),
            self.consistent.eq(all_but_grid & Cat(grids).all()),
        ]
