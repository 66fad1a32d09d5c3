"""Harness ``keyed.key_hidden``: the key is write-only, proved with two register files
(``hdl/regfile.py``) side by side (a miter). Both take the same commands (``begin``, ``start``,
``start_address``, ``check``, ``commit``, ``read_address``, the IV in use and the calibration
table's entry) and the same values, except a value checked into a key register (``key0`` to
``key2``), which is free in each: different keys are written, both accepted or both refused by
the range check (the check answers for the value sent, which the host knows). Every output but the
key's own wires to the keyed source is then the same in both: the read data of every address, the
error, its code and address, the consistency, the ``rekey``, ``table_seek`` and ``table_write``
strobes, and every setting but the key. The induction's invariant: every register of the two is
the same, but the key's bits of the candidate and of the settings.

The register file's outputs are all that the command processor (``hdl/link/command.py``: replies,
their lengths and timing, NAK codes) and the STATUS counters read of the settings; the key goes
only to the keyed source (``hdl/top.py``), whose ``iv`` and ``busy`` do not depend on it
(``keyed.iv_rule``'s harness and ``hdl/delay/keyed.py``: the IV is the one written or the one in
use plus one, ``busy`` follows Trivium's fixed count)."""

from amaranth.hdl import Assert, Assume, Cover, Module, ResetSignal, Signal, Value
from amaranth.hdl._ast import Assign, Switch
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In

from ..hdl.regfile import RegisterFile
from ..hdl.registers import KEYING, REGISTERS, settings_layout
from ._harness import assigned, open_block


__all__ = ["KeyHiddenHarness"]


KEY_NAMES = [r.name for r in REGISTERS if r.write_only]
KEY_ADDRESSES = {r.address for r in KEYING.members if r.write_only}


def _registers(module):
    """The signals the ``sync`` statements of ``module`` assign, in order, each once."""
    found = []

    def walk(statements):
        for statement in statements:
            if isinstance(statement, Assign):
                for signal in statement._lhs_signals():
                    if not any(signal is other for other in found):
                        found.append(signal)
            elif isinstance(statement, Switch):
                for case in statement.cases:
                    walk(case[1] if isinstance(case, tuple) else statement.cases[case])

    module._flush()
    walk(module._statements.get("sync", []))
    return found


def _reading_key(block, module):
    # the mutant: key0 reads as itself, not 0
    key0 = next(r for r in REGISTERS if r.name == "key0")
    with module.If(block.read_address == key0.address):
        module.d.comb += block.read_data.eq(block.settings["key0"])


class KeyHiddenHarness(wiring.Component):
    begin:         In(1)
    start:         In(1)
    start_address: In(16)
    check:         In(1)
    commit:        In(1)
    read_address:  In(range(len(REGISTERS) + 2))
    iv:            In(80)
    value_a:       In(32)
    value_b:       In(32)

    def __init__(self, *, mutate=None):
        self.mutate = mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.d.comb += Assume(~ResetSignal())
        copies = [RegisterFile(), RegisterFile()]
        modules = [open_block(copy, self.mutate) for copy in copies]
        m.submodules.a, m.submodules.b = modules
        layout = settings_layout(copies[0].maxima)
        for copy, value in zip(copies, (self.value_a, self.value_b)):
            m.d.comb += [copy.begin.eq(self.begin), copy.start.eq(self.start),
                         copy.start_address.eq(self.start_address), copy.check.eq(self.check),
                         copy.commit.eq(self.commit), copy.read_address.eq(self.read_address),
                         copy.iv.eq(self.iv), copy.value.eq(value)]
        a, b = copies

        # the values differ only where a key register takes one
        address, = assigned(modules[0], "value_address")
        index = address[:(len(REGISTERS) - 1).bit_length()]
        to_key = self.check & index.matches(*KEY_ADDRESSES)
        m.d.comb += Assume(to_key | (self.value_a == self.value_b))
        # ... and both pass or both fail the range check (the bounds the register file holds
        # for the register at `value_address`), which answers for the value sent, not the key
        allowed, minimum, maximum = assigned(modules[0], "allowed", "minimum", "maximum")

        def out_of_range(value):
            low = len(minimum)
            return ((value & ~allowed).any() |
                    ((value[low:] == 0) & (value[:low] < minimum)) | (value[:low] > maximum))

        m.d.comb += Assume(out_of_range(self.value_a) == out_of_range(self.value_b))

        # every register the same, but the key's bits of the candidate and the settings
        settings = [copy.settings.as_value() for copy in copies]
        pairs = list(zip(_registers(modules[0]), _registers(modules[1])))
        assert len(pairs) == len(_registers(modules[0])) == len(_registers(modules[1]))
        for ra, rb in pairs:
            assert ra.name == rb.name, (ra.name, rb.name)
            if ra.name == "candidate" or ra is settings[0]:
                va, vb = data.View(layout, ra), data.View(layout, rb)
                for name in layout.members:
                    if name not in KEY_NAMES:
                        m.d.comb += Assert(va[name] == vb[name])
            else:
                m.d.comb += Assert(ra == rb)
        for name in ("read_data", "error", "error_code", "error_detail", "consistent", "rekey",
                     "table_seek", "table_write"):
            m.d.comb += Assert(Value.cast(getattr(a, name)) == Value.cast(getattr(b, name)))

        # the keys differ, then a READ of a key register
        keys_differ = Signal()
        m.d.comb += keys_differ.eq(a.settings["key2"] != b.settings["key2"])
        m.d.comb += Cover(keys_differ & self.read_address.matches(*KEY_ADDRESSES))
        return m
