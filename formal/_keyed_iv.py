"""Harness ``keyed.iv_rule``: no keystream is used twice under one key. The register file
(``hdl/regfile.py``) and the keyed stream (``hdl/delay/keyed.py``, its Trivium abstracted:
``formal/_abstract.py``) wired as the top level wires them (``hdl/top.py``: the key and IV
registers into the stream, ``rekey`` with them, the IV in use back); the stream's load, mode,
take and width are free in every cycle.

The register file is driven as the command processor drives it (``hdl/link/command.py``): a
command ``begin``\\ s, then a WRITE's values are checked (``start``, ``check``, the values and
addresses free), and a commit, at most one per command, comes only at least four cycles after
the last check (when ``consistent`` holds the whole candidate), and only if the WRITE is
consistent and without error. No initialisation of the keystream happens inside a WRITE (from
its ``begin`` to its commit): on the board the delay source is loaded in every cycle while
stopped, so an initialisation a stop calls for comes in the cycle after it, and while running
only an ``update`` loads it, which follows a commit; commands are one at a time.

The property: whenever the keystream is initialised again (``restart``) and no key was written
since its initialisation before (since the reset, the first one), the new IV is above the one
before, with no exception: after the last IV (``2**80 - 1``) the stream does not initialise
again until a key is written (it is spent), so the IV never wraps around to 0 (the finding in
``docs/verification.md``).
"""

from amaranth.hdl import Assert, Assume, Cat, Cover, Module, Mux, ResetSignal, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from ..hdl.delay.keyed import KeyedStream
from ..hdl.delay.settings import MAX_MASK_WIDTH
from ..hdl.regfile import RegisterFile
from ..hdl.registers import KEYING, REGISTERS, settings_layout
from ._abstract import free_trivium
from ._harness import assigned, open_block, past
from .runner import internals


__all__ = ["IvRuleHarness"]


KEY_ADDRESSES = [r.address for r in KEYING.members if r.write_only]


def _iv_at_or_above(block, module):
    # the mutant: the IV rule lets through an IV equal to the IV in use
    candidate, iv_above = assigned(module, "candidate", "iv_above")
    c = data.View(settings_layout(block.maxima), candidate)
    module.d.sync += iv_above.eq(Cat(c.iv0, c.iv1, c.iv2) >= block.iv)


def _wrapping_stream(block, module):
    # the mutant (of the stream): after the last IV, a load initialises again with the IV in
    # use plus one, wrapped around to 0 (the stream before the fix)
    restart, pending, used = assigned(module, "restart", "pending", "used")
    module.d.comb += restart.eq(block.load & block.keyed & (pending | used))


class IvRuleHarness(wiring.Component):
    begin:         In(1)
    start:         In(1)
    start_address: In(16)
    value:         In(32)
    check:         In(1)
    commit:        In(1)
    read_address:  In(range(len(REGISTERS) + 2))
    load:          In(1)
    keyed:         In(1)
    take:          In(1)
    width:         In(range(MAX_MASK_WIDTH + 1))

    def __init__(self, *, mutate=None, mutate_stream=None):
        self.mutate = mutate
        self.mutate_stream = mutate_stream
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.d.comb += Assume(~ResetSignal())
        registers = RegisterFile()
        m.submodules.registers = regfile = open_block(registers, self.mutate)
        stream = KeyedStream()
        with free_trivium():
            if self.mutate_stream is None:
                m.submodules.stream, (restart,) = internals(stream, "restart")
            else:
                m.submodules.stream = inner = open_block(stream, self.mutate_stream)
                restart, = assigned(inner, "restart")
        m.d.comb += [
            registers.begin.eq(self.begin), registers.start.eq(self.start),
            registers.start_address.eq(self.start_address), registers.value.eq(self.value),
            registers.check.eq(self.check), registers.commit.eq(self.commit),
            registers.read_address.eq(self.read_address),
            registers.iv.eq(stream.iv),
            stream.keying.eq(registers.keying), stream.rekey.eq(registers.rekey),
            stream.load.eq(self.load), stream.keyed.eq(self.keyed), stream.take.eq(self.take),
            stream.width.eq(self.width),
        ]
        written, = assigned(regfile, "written")

        # The command processor's contract
        in_write = Signal()         # from a command's begin to its commit
        since_check = Signal(3)     # cycles since the last check, saturating at 7
        with m.If(self.begin):
            m.d.sync += in_write.eq(1)
        with m.If(self.commit):
            m.d.sync += in_write.eq(0)
        m.d.sync += since_check.eq(Mux(self.check, 0, Mux(since_check == 7, 7, since_check + 1)))
        m.d.comb += [
            Assume(~(self.begin & self.commit)),
            Assume(~(self.check | self.start) | (in_write & ~self.begin)),
            Assume(~self.commit | (in_write & (since_check >= 3) & ~self.check & ~self.start
                                   & registers.consistent & ~registers.error)),
        ]
        # (no initialisation of the stream inside a WRITE)
        m.d.comb += Assume(~(restart & (in_write | self.begin)))
        return self._property(m, stream, restart, written)

    def _property(self, m, stream, restart, written):
        key_written = Signal()      # a key written since the last initialisation
        initialised = Signal()      # an initialisation since the reset
        with m.If(self.commit & Cat(written[a] for a in KEY_ADDRESSES).any()):
            m.d.sync += key_written.eq(1)
        with m.If(restart):
            m.d.sync += [key_written.eq(0), initialised.eq(1)]
        before = past(m, stream.iv, name="iv_before")
        checked = past(m, restart & initialised & ~key_written, name="checked")
        with m.If(checked):
            m.d.comb += Assert(stream.iv > before)
        # an initialisation with the IV in use plus one, and one with an IV written
        m.d.comb += [Cover(checked & (stream.iv == before + 1) & (before != 0)),
                     Cover(checked & (stream.iv > before + 1))]
        return m
