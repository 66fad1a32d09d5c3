"""Bit-exact models of :class:`fliss.hdl.tdc.TdcInterface`, :class:`~fliss.hdl.tdc.CoarseTdc`
and their :class:`~fliss.hdl.tdc.EventFilter`.

Cycle numbers are those of the gateware's clock. Per-cycle inputs (``enable``, ``pulse_index``,
``ready``) are given as arrays indexed by cycle, or as callables of the cycle.
"""

import numpy as np

from ...hdl.event import PULSE_BITS, ADDRESS_BITS
from ...hdl.tdc import (CAPTURE_LATENCY, FILTER_LATENCY, FILTER_COUNTERS, MAX_TIMESTAMP,
                        COUNTER_WIDTH)
from ...protocol.events import EVENT_DTYPE


__all__ = ["COUNTERS", "check_gate", "filter_events", "interface", "coarse"]


#: Names of the event counters, as the gateware's output ports, in order of precedence.
COUNTERS = FILTER_COUNTERS


def check_gate(gate_start, gate_end):
    """Raise :exc:`ValueError` unless ``gate_start … gate_end`` is a valid gate."""
    for name, value in (("Gate start", gate_start), ("Gate end", gate_end)):
        if not isinstance(value, (int, np.integer)) or not 0 <= value <= MAX_TIMESTAMP:
            raise ValueError(f"{name} must be a timestamp code from 0 to {MAX_TIMESTAMP}, "
                             f"not {value!r}")
    if gate_start > gate_end:
        raise ValueError(f"Gate start ({gate_start}) must not be after gate end ({gate_end})")


def _per_cycle(values):
    if callable(values):
        return values
    if np.isscalar(values):
        return lambda cycle: values
    values = np.asarray(values)
    return lambda cycle: values[cycle]


def filter_events(capture_cycles, events, *, enabled, overflow=None, gate_start=0,
                  gate_end=MAX_TIMESTAMP, drop_collisions=0, ready=1):
    """Model of :class:`~fliss.hdl.tdc.EventFilter`.

    Parameters
    ----------
    capture_cycles : array_like of int
        Cycle in which each event is presented with ``capture``, increasing.
    events : numpy.ndarray of EVENT_DTYPE
        The events.
    enabled, overflow : array_like of bool
        ``enable`` and ``overflow`` with each event.
    drop_collisions : int
        ``gate.drop_collisions``: drop the events whose ``collision`` flag is set.
    ready : array, callable or int
        ``events.ready`` per cycle.

    Returns
    -------
    accepted : numpy.ndarray of EVENT_DTYPE
    valid_cycles, transfer_cycles : numpy.ndarray of int64
        First cycle with ``events.valid`` high, and cycle of the transfer, of each accepted event.
    counters : dict
        Final value of each counter of :data:`COUNTERS`.
    """
    ready = _per_cycle(ready)
    enabled = np.asarray(enabled, dtype=bool)
    overflow = np.zeros(len(events), dtype=bool) if overflow is None else \
        np.asarray(overflow, dtype=bool)
    counters = dict.fromkeys(COUNTERS, 0)
    accepted, valid_cycles, transfer_cycles = [], [], []
    free_from = 0  # first cycle in which the output register is empty (or transfers)
    for cycle, event, enable, over in zip(capture_cycles, events, enabled, overflow):
        cycle = int(cycle) + FILTER_LATENCY - 1  # the cycle it meets the output register
        if not enable:
            counters["dropped_stopped"] += 1
        elif over:
            counters["dropped_overflow"] += 1
        elif drop_collisions and event["collision"]:
            counters["dropped_collision"] += 1
        elif not gate_start <= event["timestamp"] <= gate_end:
            counters["dropped_gate"] += 1
        elif free_from > cycle:
            counters["dropped_overrun"] += 1
        else:
            counters["accepted"] += 1
            accepted.append(event)
            valid_cycles.append(cycle + 1)
            transfer = cycle + 1
            while not ready(transfer):
                transfer += 1
            transfer_cycles.append(transfer)
            free_from = transfer
    top = (1 << COUNTER_WIDTH) - 1
    counters = {name: min(value, top) for name, value in counters.items()}
    return (np.array(accepted, dtype=EVENT_DTYPE), np.array(valid_cycles, dtype=np.int64),
            np.array(transfer_cycles, dtype=np.int64), counters)


def interface(strobe_cycles, timestamps, addresses, collisions, *, enable, pulse_index,
              gate_start=0, gate_end=MAX_TIMESTAMP, drop_collisions=0, ready=1):
    """Model of :class:`~fliss.hdl.tdc.TdcInterface`.

    ``strobe_cycles`` are the first cycles in which ``pin_valid`` reads high, one per event,
    with the sensor timing requirements met; the bus carries the event's fields. Returns what
    :func:`filter_events` returns.
    """
    enable = _per_cycle(enable)
    pulse_index = _per_cycle(pulse_index)
    strobe_cycles = np.asarray(strobe_cycles, dtype=np.int64)
    sample = strobe_cycles + CAPTURE_LATENCY
    events = np.zeros(len(strobe_cycles), dtype=EVENT_DTYPE)
    events["timestamp"] = timestamps
    events["address"] = addresses
    events["collision"] = collisions
    events["pulse"] = [(int(pulse_index(c)) - 1) % (1 << PULSE_BITS) for c in sample]
    enabled = [bool(enable(c)) for c in sample]
    return filter_events(sample + 1, events, enabled=enabled, gate_start=gate_start,
                         gate_end=gate_end, drop_collisions=drop_collisions, ready=ready)


def coarse(hit_cycles, start_cycles, *, enable, pulse_index, address=0, gate_start=0,
           gate_end=MAX_TIMESTAMP, ready=1):
    """Model of :class:`~fliss.hdl.tdc.CoarseTdc`.

    ``hit_cycles`` are the first cycles in which ``pin_hit`` reads high; ``start_cycles`` the
    cycles in which ``tdc_start`` is high. Returns what :func:`filter_events` returns.
    """
    if not isinstance(address, (int, np.integer)) or not 0 <= address < (1 << ADDRESS_BITS):
        raise ValueError(f"Pixel address must be from 0 to {(1 << ADDRESS_BITS) - 1}, "
                         f"not {address!r}")
    enable = _per_cycle(enable)
    pulse_index = _per_cycle(pulse_index)
    hit_cycles = np.asarray(hit_cycles, dtype=np.int64)
    start_cycles = np.sort(np.asarray(start_cycles, dtype=np.int64))
    last = np.searchsorted(start_cycles, hit_cycles, side="right") - 1
    elapsed = hit_cycles - np.where(last >= 0, start_cycles[np.maximum(last, 0)], 0)
    overflow = (last < 0) | (elapsed > MAX_TIMESTAMP)
    events = np.zeros(len(hit_cycles), dtype=EVENT_DTYPE)
    events["timestamp"] = np.where(overflow, 0, elapsed)
    events["address"] = address
    events["pulse"] = [(int(pulse_index(c)) - 1) % (1 << PULSE_BITS) for c in hit_cycles]
    sample = hit_cycles + CAPTURE_LATENCY
    enabled = [bool(enable(c)) for c in sample]
    return filter_events(sample + 1, events, enabled=enabled, overflow=overflow,
                         gate_start=gate_start, gate_end=gate_end, ready=ready)
