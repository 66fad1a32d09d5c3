"""What an export carries beside the photons and counts, and the captures that files give back.

The timing (laser period and PRF from the ``period`` register and the clock), the settings that
matter (:func:`settings`: delay mode, L or Wm, the seed or the IV, never the key), the laser
cycle of each event without the 32-bit wrap of ``pulse`` (:func:`laser_cycles`; run by run,
:func:`cycle_chunks`), and the :class:`~fliss.host.fileformat.Capture` of a file read back: a
FLISS export as the capture it came from (:func:`restored`), another program's file as one
TCSPC histogram (:func:`imported`).
"""

import datetime
import json
import math
from dataclasses import dataclass

import numpy as np

from ...hdl.delay.modes import mode_row
from ...hdl.event import PULSE_BITS, TDC_LSB_S
from ...hdl.registers import BY_NAME, value_of
from ...protocol.events import EVENT_DTYPE
from ..errors import FormatError
from ..fileformat import Capture


__all__ = ["timing", "settings", "configuration", "metadata", "created", "laser_cycles",
           "cycle_chunks", "CHUNK_EVENTS", "restored", "imported", "ImportedCapture"]


def timing(capture):
    """``(period_s, prf_hz)``: the laser period (the sync of a TCSPC file) and its rate."""
    if getattr(capture, "period_s", None):          # (a recording of another instrument)
        return capture.period_s, 1 / capture.period_s
    clock_hz = capture.clock_hz
    period = int(capture.configuration.get("period", 0))
    if not clock_hz or not period:
        raise FormatError(f"{capture.path}: the capture holds no laser period (clock_hz and "
                          f"the period setting), which is the sync of PTU and Photon-HDF5")
    return period / clock_hz, clock_hz / period


def configuration(capture):
    """The capture's register values by name, the write-only ones (the key) left out."""
    return {name: int(value) for name, value in capture.configuration.items()
            if name not in BY_NAME or not BY_NAME[name].write_only}


def settings(capture):
    """The settings that matter, by name, in the order they are written: the capture's mode,
    the delay mode and the settings its row of :data:`~fliss.hdl.delay.modes.MODES` needs
    (``length`` L and ``seed`` for mseq, ``mask_width`` Wm and ``seed`` for masked, Wm and
    ``iv`` for keyed; never the key), the PRF, the period, the
    clock, the TDC code and bin shift, and whether the aggressor was on."""
    if getattr(capture, "source", None):            # (a recording of another instrument)
        period_s, prf_hz = timing(capture)
        return {"mode": capture.mode, "source": capture.source, "prf_hz": prf_hz,
                "period_s": period_s, "code_s": capture.code_s, "bin_shift": capture.shift}
    c = configuration(capture)
    row = mode_row(c.get("delay_mode", 0))
    out = {"mode": capture.mode,
           "delay_mode": f"unknown ({c.get('delay_mode')})" if row is None else row.name}
    # the settings the mode needs (its row of the mode table), the key left out
    for name in () if row is None else row.needs:
        if name == "iv":
            if all(f"iv{k}" in c for k in range(3)):
                out["iv"] = f"0x{value_of(c, 'iv'):020x}"
        elif name != "key":
            out[name] = c[name]
    period_s, prf_hz = timing(capture)
    out.update(prf_hz=prf_hz, period_s=period_s, clock_hz=int(capture.clock_hz),
               code_s=capture.code_s, bin_shift=capture.shift,
               aggressor=bool(c.get("aggressor", 0)))
    return out


def metadata(capture):
    """The whole of the capture's metadata as JSON texts: ``configuration`` (never the key),
    ``identity`` and ``capture`` (the root attributes), for a FLISS reader to restore."""
    def plain(value):       # (the fine TDC's calibration table is an array)
        if isinstance(value, np.ndarray):
            return value.tolist()
        return value.item() if isinstance(value, np.generic) else value

    def text(values):
        return json.dumps({key: plain(value) for key, value in values.items()}, sort_keys=True)
    return {"configuration": text(configuration(capture)), "identity": text(capture.identity),
            "capture": text(capture.attrs)}


def created(capture):
    """When the capture began (naive UTC), or now for a file that does not say."""
    try:
        when = datetime.datetime.fromisoformat(str(capture.attrs["created_utc"]))
    except (KeyError, ValueError):
        return datetime.datetime.now(datetime.timezone.utc).replace(tzinfo=None)
    if when.tzinfo is not None:
        when = when.astimezone(datetime.timezone.utc).replace(tzinfo=None)
    return when


#: Events converted at a time by the exporters: what an export holds beside the capture.
CHUNK_EVENTS = 1 << 20


def laser_cycles(capture):
    """The laser cycle of each event (``int64``), counted on past the 32-bit wrap of
    ``pulse``; refused when the events are not in the order of their cycles."""
    chunks = [cycles for _, cycles in cycle_chunks(capture)]
    return np.concatenate(chunks) if chunks else np.zeros(0, dtype=np.int64)


def cycle_chunks(capture, size=None):
    """(first event, laser cycles) of each run of up to ``size`` events, as
    :func:`laser_cycles` gives them whole, so that an export holds one run at a time (``size``
    :data:`CHUNK_EVENTS` unless given)."""
    size = size or CHUNK_EVENTS
    pulses = capture.events["pulse"]
    last = None                             # (pulse, cycle) of the run before
    for start in range(0, len(pulses), size):
        pulse = pulses[start:start + size].astype(np.int64)
        before = pulse[:1] if last is None else np.array([last[0]], dtype=np.int64)
        steps = np.diff(pulse, prepend=before) % (1 << PULSE_BITS)
        back = np.flatnonzero(steps >= 1 << (PULSE_BITS - 1))
        if len(back):
            i = start + int(back[0])
            raise FormatError(f"{capture.path}: event {i} (laser cycle {pulses[i]}) comes "
                              f"before event {i - 1} (cycle {pulses[i - 1]}): PTU and "
                              f"Photon-HDF5 hold records in time order")
        cycles = (pulse[0] if last is None else last[1]) + np.cumsum(steps)
        last = (int(pulse[-1]), int(cycles[-1]))
        yield start, cycles


def restored(path, texts, *, histograms=None, events=None, pixels=None, incomplete=(),
             first_frame=0, problems=()):
    """The capture a FLISS export was made of, from its metadata ``texts`` (as
    :func:`metadata` gives them) and its counts (``(N, bins)``, ``(N, P, bins)``) or events
    (``EVENT_DTYPE``). What the export does not hold is absent: row times are NaN, batches
    and counters empty."""
    try:
        attrs, identity, registers = (json.loads(texts[key]) for key in
                                      ("capture", "identity", "configuration"))
    except (KeyError, TypeError, ValueError) as error:
        raise FormatError(f"{path}: its FLISS metadata cannot be read ({error})") from None
    if histograms is None:
        histograms = np.zeros((0, 0), dtype=np.uint32)
    rows = len(histograms)
    complete = np.ones(rows, dtype=bool)
    complete[[i for i in incomplete if 0 <= i < rows]] = False
    shift = int(registers.get("bin_shift", 0))
    return Capture(str(path), attrs, identity, {k: int(v) for k, v in registers.items()},
                   histograms, first_frame + np.arange(rows, dtype=np.uint32),
                   np.full(rows, shift, dtype=np.uint8), np.full(rows, np.nan), complete,
                   np.zeros(0, dtype=EVENT_DTYPE) if events is None else events,
                   np.zeros(0), {}, list(problems),
                   np.zeros(0, dtype=np.int64) if pixels is None else pixels)


@dataclass
class ImportedCapture(Capture):
    """One TCSPC histogram read from another program's file (a histogram capture of one
    complete row), its bins ``resolution_s`` wide. ``shift`` is the power of two nearest the
    bins' width in 50 ps codes, so that the analysis smooths a histogram over the same time
    (:func:`fliss.host.analysis.analyze`) as it does a FLISS capture of that bin width."""
    resolution_s: float = TDC_LSB_S

    @property
    def code_s(self):
        return self.resolution_s / (1 << self.shift)


def imported(path, counts, resolution_s, source, problems=()):
    """An :class:`ImportedCapture` of the histogram ``counts`` with bins of ``resolution_s``
    from a file of another program (``source`` names the format and the instrument)."""
    if not resolution_s > 0:
        raise FormatError(f"{path}: its TCSPC resolution is {resolution_s!r} s, not a width")
    shift = min(max(0, round(math.log2(resolution_s / TDC_LSB_S))), 16)
    counts = np.asarray(counts, dtype=np.int64)[np.newaxis, :]
    return ImportedCapture(
        str(path), {"mode": "histogram", "end_reason": f"unknown ({source})"}, {}, {}, counts,
        np.zeros(1, dtype=np.uint32), np.full(1, shift, dtype=np.uint8), np.full(1, np.nan),
        np.ones(1, dtype=bool), np.zeros(0, dtype=EVENT_DTYPE), np.zeros(0), {},
        list(problems), resolution_s=float(resolution_s))
