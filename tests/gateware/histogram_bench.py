"""The histogram engine's bench for the tests: stimulus, a run of the gateware in Amaranth's
simulator, and the check of its frames against the model (tests/gateware/test_histogram.py,
tests/gateware/test_histogram_pixels.py)."""

import numpy as np

from fliss.sim.models import histogram as model

from simulation import simulate

__all__ = ["BANK_BITS", "hazard_stimulus", "run_histogram", "check_against_model", "spaced",
           "hits"]

def hazard_stimulus(rng, cycles, *, bins, shift, gaps=True):
    """Timestamps with long runs of one bin, A,A,B,A patterns, random bins; optional gaps.

    Returns per-cycle ``valid`` (bool) and ``timestamp`` arrays.
    """
    timestamps = []
    while len(timestamps) < cycles:
        kind = rng.integers(6)
        a, b = rng.integers(bins, size=2) << shift

        def jitter(n, shift=shift):
            return rng.integers(1 << shift, size=n) if shift else 0

        if kind == 0:    # long run of one bin, timestamps anywhere inside it
            n = int(rng.integers(50, 400))
            timestamps.extend(a + jitter(n) * np.ones(n, dtype=np.int64))
        elif kind == 1:  # A,A,B,A,B,B,...: same bin one and two cycles apart
            n = int(rng.integers(20, 200))
            timestamps.extend(np.where(rng.integers(2, size=n) == 1, a, b) + jitter(n))
        elif kind == 2:  # strictly alternating A,B
            n = int(rng.integers(20, 200))
            timestamps.extend(np.where(np.arange(n) % 2 == 0, a, b) + jitter(n))
        elif kind == 3:  # A,A,B,A with a third bin
            c = rng.integers(bins) << shift
            pattern = np.array([a, a, b, a, c, a, b, b])
            timestamps.extend(np.tile(pattern, int(rng.integers(5, 40))))
        else:            # random over all codes
            n = int(rng.integers(50, 300))
            timestamps.extend(rng.integers(1 << 13, size=n))
    timestamps = np.asarray(timestamps[:cycles], dtype=np.int64)
    valid = np.ones(cycles, dtype=bool)
    if gaps:
        # a few idle stretches and isolated idle cycles
        valid &= rng.random(cycles) > 0.02
        for start in rng.integers(cycles, size=5):
            valid[start:start + int(rng.integers(1, 30))] = False
    return valid, timestamps


#: The bank of these tests, unless they say otherwise: 8192 bins, one pixel of every code.
BANK_BITS = 13


def run_histogram(dut, valid, timestamps, *, integration, shift, ready=None, settle=None,
                  probe=None, garbage=None, wait_init=True, addresses=None, pixel_bits=0,
                  first_pixel=0):
    """Drive ``valid``/``timestamps`` from cycle 0, with ``enable`` high from cycle 0 to the
    cycle after the last event; collect the read out frames. Cycle 0 is the first cycle a frame
    can start in (``dut.init_cycles`` after reset: before it, ``enable`` is low and no event
    arrives). ``garbage``: a random generator to fill both banks with at reset (the
    single-port engine must clear them, like SPRAM at power-up). ``wait_init=False``: cycle 0 is
    the first after reset, whatever ``dut.init_cycles``.

    ``addresses``: the events' pixel addresses (default all 0); ``pixel_bits`` and
    ``first_pixel``: the split, held for every frame.

    Returns frames (list of (flat counts, (shift, pixel_bits, first_pixel) of the frame as
    presented)) and the final counters.
    """
    cycles = len(valid)
    frames = []
    result = {}
    readout_bins = model.bins_read(shift, dut.bank_bits, pixel_bits)
    if settle is None:
        settle = 4 * model.readout_cycles(shift, dut.bank_bits, pixel_bits) + 100
    if addresses is None:
        addresses = np.zeros(cycles, dtype=np.int64)

    async def stimulus(ctx):
        if garbage is not None:
            for bank in dut.banks:
                for index, value in enumerate(garbage.integers(1 << dut.count_width,
                                                               size=bank.data.depth)):
                    ctx.set(bank.data[index], int(value))
        if dut.init_cycles and wait_init:
            await ctx.tick().repeat(dut.init_cycles)
        ctx.set(dut.settings.integration, integration)
        ctx.set(dut.settings.bin_shift, shift)
        ctx.set(dut.settings.pixel_bits, pixel_bits)
        ctx.set(dut.settings.first_pixel, first_pixel)
        ctx.set(dut.enable, 1)
        for cycle in range(cycles):
            ctx.set(dut.events.valid, int(valid[cycle]))
            ctx.set(dut.events.payload.timestamp, int(timestamps[cycle]))
            ctx.set(dut.events.payload.address, int(addresses[cycle]))
            await ctx.tick()
        ctx.set(dut.events.valid, 0)
        ctx.set(dut.enable, 0)
        idle = 0
        for _ in range(settle):                 # until every frame is read out
            _, _, pending = await ctx.tick().sample(dut.pending)
            idle = 0 if pending else idle + 1
            if idle == 10:
                break
        result.update(dropped=ctx.get(dut.dropped), overflow=ctx.get(dut.overflow),
                      frames=ctx.get(dut.frames), pending=ctx.get(dut.pending),
                      dropped_busy=ctx.get(dut.dropped_busy),
                      dropped_pixel=ctx.get(dut.dropped_pixel))

    async def consumer(ctx):
        counts = []
        cycle = 0
        while True:
            if ready is not None:
                ctx.set(dut.readout.ready, int(ready(cycle)))
            else:
                ctx.set(dut.readout.ready, 1)
            _, _, got, rdy, index, count, last, *split = await ctx.tick().sample(
                dut.readout.valid, dut.readout.ready, dut.readout.payload.index,
                dut.readout.payload.count, dut.readout.payload.last,
                dut.readout_split.shift, dut.readout_split.pixel_bits,
                dut.readout_split.first_pixel)
            cycle += 1
            if got and rdy:
                assert index == len(counts)
                counts.append(count)
                assert last == (index == readout_bins - 1)
                if last:
                    frames.append((np.array(counts), tuple(split)))
                    counts = []

    simulate(dut, stimulus, background=[consumer] + ([probe] if probe is not None else []))
    return frames, result


def check_against_model(frames, result, valid, timestamps, *, integration, shift, bank_bits,
                        addresses=None, pixel_bits=0, first_pixel=0):
    cycles = np.flatnonzero(valid)
    expected, overflow, dropped, dropped_pixel = model.frames(
        cycles, timestamps[valid], None if addresses is None else addresses[valid],
        integration=integration, enable=0, disable=len(valid), shift=shift,
        bank_bits=bank_bits, pixel_bits=pixel_bits, first_pixel=first_pixel)
    q, _ = model.split(shift, pixel_bits, bank_bits)
    assert len(frames) == len(expected) >= 3
    for k, ((counts, split), want) in enumerate(zip(frames, expected)):
        assert split == (shift, q, first_pixel)
        want = want.ravel()     # the readout order
        mismatch = np.flatnonzero(counts != want)
        assert mismatch.size == 0, \
            f"frame {k}: bins {mismatch[:8]} read {counts[mismatch[:8]]}, want {want[mismatch[:8]]}"
    assert result["overflow"] == overflow
    assert result["dropped"] == dropped
    assert result["dropped_pixel"] == dropped_pixel
    assert result["dropped_busy"] == 0
    assert result["frames"] == len(expected)
    assert result["pending"] == 0
    # Every event is counted exactly once: in a bin, in overflow, dropped or dropped_pixel.
    assert sum(int(f.sum()) for f, _ in frames) + overflow + dropped + dropped_pixel == \
        int(valid.sum())


def spaced(rng, valid, timestamps, *, length=None):
    """The events of ``valid``/``timestamps`` in order, at least two cycles apart: mostly two,
    else three to six (the most the single-port engine takes). ``length``: cut or pad to that
    many cycles."""
    ts = timestamps[valid]
    gaps = np.where(rng.random(len(ts)) < 0.7, 2, rng.integers(3, 7, size=len(ts)))
    cycles = np.cumsum(gaps) - gaps[0]
    if length is None:
        length = int(cycles[-1]) + 1
    keep = cycles < length
    out_valid = np.zeros(length, dtype=bool)
    out_timestamps = np.zeros(length, dtype=np.int64)
    out_valid[cycles[keep]] = True
    out_timestamps[cycles[keep]] = ts[keep]
    return out_valid, out_timestamps


def hits(valid, timestamps, shift, apart):
    """Events whose bin is that of the event before, which arrived ``apart`` cycles earlier."""
    cycles = np.flatnonzero(valid)
    bins = timestamps[valid] >> shift
    return int(np.count_nonzero((np.diff(cycles) == apart) & (bins[1:] == bins[:-1])))
