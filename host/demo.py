"""``fliss demo``: what FLISS does, from the models and the gateware simulation."""

from amaranth.sim import Simulator

from ..hdl import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ..hdl.core import DelayCore
from ..sim.delay import DelayMode
from ..sim import scheduler as scheduler_model
from .model_commands import prf_rows
from .units import format_frequency


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "demo", formatter_class=formatter, help="show FLISS at work, no hardware needed",
        description="Prints the effective PRF table (Table 2 of the paper) and a trace of the "
                    "pulse scheduler running in the gateware simulator, checked against the "
                    "reference model.")
    parser.add_argument("--pulses", type=int, default=12, help="pulses to trace")
    parser.set_defaults(run=run)


def trace_gateware(settings, cycles, clock_hz=DEFAULT_CLOCK_HZ):
    """Run the delay core in Amaranth's simulator; return its pulses and laser rising edges."""
    dut = DelayCore(clock_hz=clock_hz)
    pulses, edges = [], []

    async def testbench(ctx):
        for name in ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width"):
            ctx.set(getattr(dut, name), getattr(settings, name))
        await ctx.tick()
        ctx.set(dut.enable, 1)
        for cycle in range(1, cycles):
            if ctx.get(dut.fire):
                pulses.append((cycle, ctx.get(dut.fire_delay), settings.pulse_width,
                               ctx.get(dut.pulse_index)))
            if ctx.get(dut.tdc_start):
                edges.append(cycle)
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1 / clock_hz)
    sim.add_testbench(testbench)
    sim.run()
    return pulses, edges


def run(args):
    clock_hz, period = DEFAULT_CLOCK_HZ, period_cycles(DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ)
    print(f"FLISS at {format_frequency(clock_hz)}, nominal PRF {format_frequency(DEFAULT_PRF_HZ)}"
          f" (T = {period} cycles)\n")
    print("Effective PRF with complete m-sequences (paper, Table 2):")
    for mode, setting, max_delay, _, closed, measured in prf_rows(
            clock_hz, period, lengths=[3, 4, 5, 6, 8, 16, 32]):
        shown = format_frequency(measured if measured is not None else closed)
        print(f"  L = {setting['length']:>2}: delays 0..{max_delay:<10} PRF_eff = {shown}")

    settings = scheduler_model.Settings(mode=DelayMode.MSEQ, length=4, seed=1, period=period,
                                        pulse_width=2).check()
    cycles = (period + 15) * (args.pulses + 1)
    pulses, edges = trace_gateware(settings, cycles, clock_hz)
    expected = scheduler_model.simulate(settings, cycles - 1, enable=1)
    print(f"\nGateware trace (mseq, L = 4, seed 1), {len(pulses)} pulses, each fired "
          f"T + R cycles after the previous one:")
    print(f"  {'pulse':>5} {'delay R':>8} {'laser/TDC start':>16} {'interval':>9}")
    previous = None
    for (cycle, delay, _, index), edge in list(zip(pulses, edges))[:args.pulses]:
        interval = "" if previous is None else f"{edge - previous}"
        print(f"  {index:>5} {delay:>8} {edge:>16} {interval:>9}")
        previous = edge
    same = pulses == expected[:len(pulses)] and \
        edges == [fire + scheduler_model.LATENCY for fire, *_ in pulses]
    print(f"\nGateware and reference model agree bit for bit: {'yes' if same else 'NO'}")
    return 0 if same else 1
