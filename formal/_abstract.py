"""Abstractions of blocks too large for the solver: a Trivium whose outputs are free.

The keyed source's Trivium (``hdl/delay/trivium.py``: 288 state bits, 72 cycles of
initialisation) is replaced, while a harness elaborates, by :class:`FreeTrivium`, whose
``ready`` and keystream bits ``z`` are free in every cycle (``AnySeq``). Every behaviour of the
real Trivium is one of these, so a safety property proved with it holds with the real one, for
every key, IV and keystream; what it cannot show is anything that needs the real keystream (that
is ``keyed.trivium_vectors``).
"""

from contextlib import contextmanager

from amaranth.hdl import Fragment, Module
from amaranth.hdl._ast import AnySeq
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

import fliss.hdl.delay.keyed as keyed_module
from ..hdl.delay.settings import IV_BITS, KEY_BITS


__all__ = ["FreeTrivium", "free_trivium", "elaborate_with_free_trivium"]


class FreeTrivium(wiring.Component):
    """:class:`~fliss.hdl.delay.trivium.TriviumCore`'s signature, with ``ready`` and ``z`` free."""

    def __init__(self, *, rounds):
        self.rounds = rounds
        super().__init__({"key": In(KEY_BITS), "iv": In(IV_BITS), "load": In(1),
                          "ready": Out(1), "z": Out(rounds), "next": In(1)})

    def elaborate(self, platform):
        m = Module()
        m.d.comb += [self.ready.eq(AnySeq(1)), self.z.eq(AnySeq(self.rounds))]
        return m


@contextmanager
def free_trivium():
    """While in it, the keyed stream (``hdl/delay/keyed.py``) builds a :class:`FreeTrivium`."""
    saved = keyed_module.TriviumCore
    keyed_module.TriviumCore = FreeTrivium
    try:
        yield
    finally:
        keyed_module.TriviumCore = saved


def elaborate_with_free_trivium(block, platform=None):
    """``block`` elaborated (its whole hierarchy) with :class:`FreeTrivium` in the keyed stream:
    the fragment to add as the submodule in its place."""
    with free_trivium():
        return Fragment.get(block, platform)
