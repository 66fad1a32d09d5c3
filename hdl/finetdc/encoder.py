"""The edge encoder: ones count of the sampled taps, and the cycle a hit arrives."""

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import POPCOUNT_FANIN, TAPS, popcount_stages


__all__ = ["Encoder"]


class Encoder(wiring.Component):
    """Ones count of the delay lines' taps, pipelined, and the hit strobe.

    The raw code is the number of taps that read 1, wherever they are and whichever line they
    are on: the sum of the lines' ones counts, their taps interleaved. A bubble (a 0 among the
    ones, a 1 among the zeros, from clock skew or a metastable flip-flop) moves the code by at
    most the bits it flips, where a search for the first zero could jump by many taps. The
    count takes :func:`~fliss.hdl.finetdc.popcount_stages` pipeline stages of
    :data:`~fliss.hdl.finetdc.POPCOUNT_FANIN` inputs each: ``taps`` of cycle ``c`` give
    ``code`` in cycle ``c + stages``. A hit is the first non-zero code after a zero one: the
    hit input must fall, and the lines empty (a whole sample of zeros), before the next hit.

    Parameters
    ----------
    taps : int
        Number of taps, of all the lines.

    Members
    -------
    taps : In(taps)
        The sampled taps.
    code : Out(range(taps + 1))
        Ones count.
    hit : Out(1)
        ``code`` is the first non-zero one after a zero one.
    """

    def __init__(self, taps=TAPS):
        self.count = taps
        self.stages = popcount_stages(taps)
        super().__init__({"taps": In(taps), "code": Out(range(taps + 1)), "hit": Out(1)})

    def elaborate(self, platform):
        m = Module()

        # Ones count: sums of groups of POPCOUNT_FANIN, one stage after the other
        values = list(self.taps)
        width = 1
        for stage in range(self.stages):
            groups = [values[k:k + POPCOUNT_FANIN] for k in range(0, len(values),
                                                                  POPCOUNT_FANIN)]
            width = min(width * POPCOUNT_FANIN, self.count)
            sums = []
            for index, group in enumerate(groups):
                total = Signal(range(width + 1), name=f"count_{stage}_{index}")
                m.d.sync += total.eq(_tree(group))
                sums.append(total)
            values = sums
        m.d.comb += self.code.eq(values[0])

        # Hit: non-zero after zero
        previous = Signal.like(self.code)
        m.d.sync += previous.eq(self.code)
        m.d.comb += self.hit.eq((self.code != 0) & (previous == 0))

        return m


def _tree(values):
    # The sum of `values` as a balanced tree of adders
    if len(values) == 1:
        return values[0]
    half = len(values) // 2
    return _tree(values[:half]) + _tree(values[half:])
