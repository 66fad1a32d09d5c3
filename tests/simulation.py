"""Helpers shared by the tests that run gateware in Amaranth's simulator.

* :func:`simulate` sets up a clocked simulation of a design, adds its testbenches and runs it;
* :func:`stream_put` and :func:`stream_get` move one payload over an ``amaranth.lib.stream``
  interface, following its transfer rules (``valid`` does not wait for ``ready``; the payload
  stays put until it is taken);
* :class:`Twins` runs two variants of a block side by side on the same inputs.
"""

from amaranth.hdl import Elaboratable, Module
from amaranth.lib import wiring
from amaranth.sim import Simulator

from fliss.hdl.clock import DEFAULT_CLOCK_HZ


__all__ = ["simulate", "stream_put", "stream_get", "stream_put_all", "stream_get_each", "Twins"]


def simulate(dut, *testbenches, background=(), clock_hz=DEFAULT_CLOCK_HZ, deadline=None):
    """Run ``dut`` with a clock of ``clock_hz`` in the ``sync`` domain.

    ``testbenches`` are ``async def testbench(ctx)`` functions; the simulation ends when they
    have all returned. ``background`` testbenches run beside them and do not keep it going.
    ``deadline``, in seconds of simulated time, stops a simulation that would run for ever.
    """
    sim = Simulator(dut)
    sim.add_clock(1 / clock_hz)
    for testbench in testbenches:
        sim.add_testbench(testbench)
    for testbench in background:
        sim.add_testbench(testbench, background=True)
    if deadline is None:
        sim.run()
    else:
        sim.run_until(deadline)
    return sim


async def stream_put(ctx, stream, payload):
    """Offer ``payload`` on ``stream`` (an interface whose ``valid`` and ``payload`` the
    testbench drives) until it is taken."""
    ctx.set(stream.valid, 1)
    ctx.set(stream.payload, payload)
    await ctx.tick().until(stream.ready)
    ctx.set(stream.valid, 0)


async def stream_get(ctx, stream, timeout=None):
    """Take one payload from ``stream`` (an interface whose ``ready`` the testbench drives);
    raise :exc:`AssertionError` if none comes within ``timeout`` cycles (if given)."""
    ctx.set(stream.ready, 1)
    for _ in iter(int, 1) if timeout is None else range(timeout):
        _, _, valid, payload = await ctx.tick().sample(stream.valid, stream.payload)
        if valid:
            break
    else:
        raise AssertionError(f"nothing on the stream for {timeout} cycles")
    ctx.set(stream.ready, 0)
    return payload


async def stream_put_all(ctx, stream, payloads, *, rng=None, idle=0.0):
    """Put each of ``payloads`` on ``stream`` in turn; before each, with probability ``idle``
    (drawn from ``rng``, a :class:`random.Random`), wait 1 to 3 cycles with ``valid`` low."""
    for payload in payloads:
        if rng is not None and rng.random() < idle:
            await ctx.tick().repeat(rng.randint(1, 3))
        await stream_put(ctx, stream, payload)


async def stream_get_each(ctx, stream, *, rng=None, idle=0.0):
    """Take payloads from ``stream`` for ever, yielding each; before each, with probability
    ``idle``, wait 1 to 4 cycles with ``ready`` low (back pressure)."""
    while True:
        if rng is not None and rng.random() < idle:
            await ctx.tick().repeat(rng.randint(1, 4))
        yield await stream_get(ctx, stream)


class Twins(Elaboratable):
    """Two components of the same signature (two variants of a block): the testbench drives
    ``first``'s inputs, which drive ``second``'s too; :meth:`outputs` lists both's outputs, for
    a comparison cycle by cycle."""

    def __init__(self, first, second):
        assert first.signature == second.signature
        self.first, self.second = first, second

    def _members(self, component):
        return list(component.signature.flatten(component))

    def outputs(self):
        """``(first, second)``: the two lists of output signals, in the same order."""
        return tuple([value for _, member, value in self._members(component)
                      if member.flow == wiring.Out] for component in (self.first, self.second))

    def run_compared(self, send, *, rng, ready=0.5):
        """Simulate with ``send(ctx)`` driving ``first``'s inputs and the ``ready`` of its output
        stream ``o`` high at random (with probability ``ready``); the two's outputs must be the
        same in every cycle. Returns the number of transfers on ``o``."""
        first, second = self.outputs()
        transfers = 0

        async def consume(ctx):
            while True:
                ctx.set(self.first.o.ready, rng.random() < ready)
                await ctx.tick()

        async def compare(ctx):
            nonlocal transfers
            cycle = 0
            async for _, _, taken, valid, *values in ctx.tick().sample(
                    self.first.o.ready, self.first.o.valid, *first, *second):
                assert values[:len(first)] == values[len(first):], f"cycle {cycle}"
                cycle += 1
                transfers += taken and valid

        simulate(self, send, background=[consume, compare])
        return transfers

    def elaborate(self, platform):
        m = Module()
        m.submodules.first, m.submodules.second = self.first, self.second
        for (_, member, value), (_, _, twin) in zip(self._members(self.first),
                                                    self._members(self.second)):
            if member.flow == wiring.In:
                m.d.comb += twin.eq(value)
        return m
