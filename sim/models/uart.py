"""Bit-level model of the UART (:mod:`fliss.hdl.link.uart`), cycle exact.

* :func:`characters` gives the bits of 8N1 characters;
* :func:`tx_runs` is the waveform :class:`~fliss.hdl.link.uart.UartTx` sends, cycle for cycle;
* :func:`line_runs` is an ideal line at any baud rate (for example 2 % off the receiver's),
  sampled at the receiver's clock, with optional bad stop bits and idle gaps;
* :func:`receive` is :class:`~fliss.hdl.link.uart.UartRx`: what it makes of a sampled line.

Waveforms are lists of runs ``(level, cycles)``; :func:`expand` turns them into one sample per
cycle.
"""

import math

import numpy as np

from ...hdl.link.uart import DATA_BITS, CHARACTER_BITS
from ...hdl.clock import FRACTION_BITS, bit_cycles


__all__ = ["characters", "tx_runs", "line_runs", "expand", "receive", "SYNC_STAGES"]


#: Flip-flops in the receiver's input synchroniser: the line reaches the receiver logic this
#: many cycles late.
SYNC_STAGES = 2


def characters(data, *, bad_stop=()):
    """The line bits of each byte of ``data``: start, 8 data bits LSB first, stop.

    The stop bit of the characters whose index is in ``bad_stop`` is 0 (a framing error).
    """
    bad_stop = set(bad_stop)
    out = []
    for index, byte in enumerate(bytes(data)):
        bits = [0] + [(byte >> k) & 1 for k in range(DATA_BITS)]
        bits.append(0 if index in bad_stop else 1)
        out.append(bits)
    return out


def _merge(runs):
    out = []
    for level, count in runs:
        if count <= 0:
            continue
        if out and out[-1][0] == level:
            out[-1] = (level, out[-1][1] + count)
        else:
            out.append((level, count))
    return out


def tx_runs(data, clock_hz, baud, *, lead=1):
    """Waveform of :class:`~fliss.hdl.link.uart.UartTx` sending ``data`` back to back, the first byte being offered
    from the start: ``lead`` idle cycles (the transfer cycle), then the characters; bit ``k`` of
    the burst begins ``(k * C + 2**(F-1)) >> F`` cycles after the first start bit."""
    step = bit_cycles(clock_hz, baud)
    half = 1 << (FRACTION_BITS - 1)
    bits = [level for char in characters(data) for level in char]
    edges = [(k * step + half) >> FRACTION_BITS for k in range(len(bits) + 1)]
    runs = [(1, lead)]
    runs += [(level, edges[k + 1] - edges[k]) for k, level in enumerate(bits)]
    return _merge(runs)


def line_runs(data, clock_hz, baud, *, lead_bits=1.0, gap_bits=0.0, bad_stop=(), tail_bits=2.0):
    """An ideal line at ``baud`` (any value) sampled at ``clock_hz``.

    ``lead_bits`` idle bit times come first, ``gap_bits`` idle bit times after each character and
    ``tail_bits`` at the end; a level change at time ``t`` is seen from the first sample at or
    after ``t``.
    """
    bits = [1]
    times = [0.0]
    t = lead_bits
    for bits_of_char in characters(data, bad_stop=bad_stop):
        for level in bits_of_char:
            bits.append(level)
            times.append(t)
            t += 1
        bits.append(1)
        times.append(t)
        t += gap_bits
    end = t + tail_bits
    cycles = [math.ceil(tb * clock_hz / baud - 1e-9) for tb in times]
    end_cycle = math.ceil(end * clock_hz / baud - 1e-9)
    runs = [(level, cycles[k + 1] - cycles[k]) for k, level in enumerate(bits[:-1])]
    runs.append((bits[-1], end_cycle - cycles[-1]))
    return _merge(runs)


def expand(runs):
    """One sample per cycle from runs."""
    return np.concatenate([np.full(count, level, dtype=np.uint8) for level, count in runs])


def receive(samples, clock_hz, baud):
    """What :class:`~fliss.hdl.link.uart.UartRx` receives from the line ``samples`` (one per cycle, raw pin), its
    output being always ready.

    Returns ``(received, framing_errors)``: the list of ``(cycle, byte)`` in order, ``cycle``
    being the cycle in which the byte appears on the receiver's output, and the list of cycles
    in which ``framing_error`` is strobed.
    """
    step = bit_cycles(clock_hz, baud)
    line = np.concatenate([np.ones(SYNC_STAGES, dtype=np.uint8), np.asarray(samples, np.uint8)])
    received, errors = [], []
    state = "IDLE"
    prev1 = prev2 = 1
    cycle = edge = bit = shreg = 0
    for now, rx in enumerate(line[:len(samples)]):
        vote = 1 if int(rx) + prev1 + prev2 >= 2 else 0
        if state == "IDLE":
            if not rx:
                state, cycle, edge, bit = "RECEIVE", 1, step // 2, 0
        elif state == "RECEIVE":
            if cycle == (edge >> FRACTION_BITS) + 1:
                edge += step
                if bit == 0:
                    if vote:
                        state = "IDLE"
                elif bit == CHARACTER_BITS - 1:
                    if vote:
                        received.append((now + 1, shreg))
                        state = "IDLE"
                        if not rx:      # the next start bit begins in this cycle
                            state, cycle, edge, bit = "RECEIVE", 1, step // 2, 0
                            prev2, prev1 = prev1, int(rx)
                            continue
                    else:
                        errors.append(now + 1)
                        state = "BREAK"
                else:
                    shreg = (shreg >> 1) | (vote << (DATA_BITS - 1))
                bit += 1
            cycle += 1
        elif state == "BREAK":
            if rx:
                state = "IDLE"
        prev2, prev1 = prev1, int(rx)
    return received, errors
