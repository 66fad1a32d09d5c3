"""A jumper wire on the virtual board's photon pin: a trigger output looped back to ``photon_hit``.

:class:`Jumper` copies each edge of a trigger output of the top level (``laser``, or
``aggressor_laser``) to its ``photon_hit`` input ``delay_s`` later (the model board's
:data:`~fliss.sim.boards.loopback.JUMPER_DELAY_S`, with a Gaussian jitter of ``jitter_s``,
:data:`~fliss.sim.boards.loopback.JITTER_S`), as a timed write in the simulator's resolution
(the 1 ps of :data:`fliss.sim.benches.runner.TIMESCALE`). The trigger's flip-flop sets it at a
clock edge; the copy rises 3.2 ns into that cycle, so the synchroniser's first flip-flop reads
it high at the cycle's closing edge, as a real pin, wire and input buffer under a clock period
do. The coarse TDC (``tdc_source`` 1) reads this pin; the fine TDC's jumper is
:class:`~fliss.sim.boards.fine_loopback.FineLoopback`'s.
"""

import numpy as np
import cocotb
from cocotb.triggers import Timer

from .loopback import JITTER_S, JUMPER_DELAY_S, JUMPERS


__all__ = ["TRIGGER_PINS", "Jumper"]


#: What the jumper carries -> the top level's output it is wired to.
TRIGGER_PINS = {"laser": "laser", "aggressor": "aggressor_laser"}


class Jumper:
    """Drives ``dut.photon_hit`` from the trigger output ``jumper`` (``"laser"`` or
    ``"aggressor"``) of ``dut`` (see the module's description)."""

    def __init__(self, dut, jumper, *, delay_s=JUMPER_DELAY_S, jitter_s=JITTER_S, seed=None):
        if jumper not in JUMPERS:
            raise ValueError(f"A jumper carries one of {', '.join(JUMPERS)}, not {jumper!r}")
        if not (delay_s >= 0 and jitter_s >= 0):
            raise ValueError(f"delay_s and jitter_s must not be negative, not {delay_s!r} and "
                             f"{jitter_s!r}")
        self.dut = dut
        self.trigger = getattr(dut, TRIGGER_PINS[jumper])
        self.delay_s = delay_s
        self.jitter_s = jitter_s
        self.rng = np.random.default_rng(seed)
        self.edges = 0
        dut.photon_hit.value = 0

    def start(self):
        cocotb.start_soon(self._run())

    def _delay_ps(self):
        delay_s = self.delay_s + self.rng.normal(0, self.jitter_s)
        return max(1, round(delay_s * 1e12))

    async def _run(self):
        while True:
            await self.trigger.value_change
            self.edges += 1
            cocotb.start_soon(self._copy(int(self.trigger.value), self._delay_ps()))

    async def _copy(self, level, delay_ps):
        await Timer(delay_ps, unit="ps")
        self.dut.photon_hit.value = level
