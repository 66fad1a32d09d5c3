"""TCSPC recordings of other instruments read as raw captures: PicoQuant PTU files (every T3
record type), HT3 files (HydraHarp 400), PT3 files (PicoHarp 300) and Becker & Hickl SPC files
(the 32-bit FIFO records of the SPC-130/150/160/180/830 modules, with their ``.set`` file).

:func:`read_recording` gives the photons as the file holds them (a :class:`Recording`: the sync
count, the micro time, the channel of each, and how many records were markers and overflows;
the decoders, :mod:`.tttr_decode`); :func:`to_capture` puts them in FLISS's terms (a
:class:`ForeignCapture`, a raw capture: the sync period as the laser period, the sync count as
the laser cycle, the micro time as the timestamp code, the channel as the pixel address). What
cannot map is refused with one line (:exc:`FormatError`): a T2 file (no laser sync), a channel
with no pixel address, a file that gives no sync period or micro-time width, photons out of
time order or further apart than FLISS's 32-bit laser cycle count tells. Nothing is lost
silently: markers (which are not photons) are counted and said to be left out, overflow
records counted, micro times too fine for FLISS's 13-bit codes binned and said so. What maps
to what, and which library decodes what and why: docs/file-format.md.
"""

import math
from dataclasses import dataclass

import numpy as np

from ...hdl.event import PULSE_BITS, TDC_LSB_S, TIMESTAMP_BITS
from ...protocol.events import EVENT_DTYPE
from ..errors import FormatError
from ..fileformat import Capture
from .tttr_decode import read_recording
from .tttr_recording import KINDS, Recording, check_mode


__all__ = ["KINDS", "foreign_kind", "Recording", "read_recording", "check_mode",
           "ForeignCapture", "to_capture", "read_foreign"]


#: The first bytes (the ``Ident`` field) of the HT3 and PT3 headers.
_IDENTS = ((b"HydraHarp", "ht3"), (b"PicoHarp", "pt3"))

#: Codes FLISS's timestamps hold.
_CODES = 1 << TIMESTAMP_BITS


def foreign_kind(path, head):
    """The kind (a key of :data:`KINDS`) of the file ``path`` that begins with the bytes
    ``head`` (16 or more), or None for none of them. A name ending in .ht3, .pt3 whose bytes
    are not those of the format is refused, saying so."""
    if head.startswith(b"PQTTTR\0\0"):
        return "ptu"
    for ident, kind in _IDENTS:
        if head.startswith(ident):
            return kind
    name = str(path).lower()
    if name.endswith(".spc"):
        return "spc"
    for kind in ("ht3", "pt3"):
        if name.endswith("." + kind):
            idents = " or ".join(ident.decode() for ident, k in _IDENTS if k == kind)
            raise FormatError(f"{path}: not {KINDS[kind]} (it does not begin with "
                              f"{idents}, the mark of one)")
    return None


@dataclass
class ForeignCapture(Capture):
    """A raw capture read from another instrument's file: its timestamp codes are
    ``code_width_s`` wide (not a FLISS TDC's), its laser period is the file's sync period
    (``period_s``), and ``source`` names the format and the instrument. Its histogram
    (:meth:`total_histogram`) has a bin per code, as many as the sync period holds (or up to
    the last photon's code; at most FLISS's 8192); ``bin_shift`` is the power of two nearest the codes' width in
    50 ps codes, so that the analysis smooths it over the time it smooths a FLISS capture's
    (as for :class:`.metadata.ImportedCapture`)."""
    code_width_s: float = TDC_LSB_S
    period_s: float = 0.0
    source: str = ""
    bin_shift: int = 0

    @property
    def code_s(self):
        return self.code_width_s

    @property
    def shift(self):
        return self.bin_shift

    @property
    def bin_s(self):
        return self.code_width_s

    def total_histogram(self, complete_only=True):
        """The histogram of the photons' timestamp codes."""
        codes = self.events["timestamp"].astype(np.int64)
        bins = max(int(round(self.period_s / self.code_width_s)),
                   int(codes.max()) + 1 if len(codes) else 0)
        return np.bincount(codes, minlength=min(bins, _CODES)).astype(np.int64)


def to_capture(recording):
    """The :class:`ForeignCapture` of a :class:`Recording`: the sync count modulo 2**32 as
    ``pulse`` (the laser cycle), the micro time as ``timestamp`` (divided by the power of two
    that brings the largest into FLISS's 8192 codes, if it is not already), the channel as
    ``address``."""
    r, path = recording, recording.path
    for name, value in (("sync period", r.period_s), ("micro-time width", r.width_s)):
        if not (0 < value < math.inf):
            raise FormatError(f"{path}: {KINDS[r.kind]} that gives no {name} ({value!r} s), "
                              f"which fliss cannot represent")
    bad = np.flatnonzero((r.channel < 0) | (r.channel >= 64))
    if len(bad):
        raise FormatError(f"{path}: photon {bad[0]} is on channel {r.channel[bad[0]]}, which "
                          f"does not exist among FLISS's 64 pixel addresses (0 to 63)")
    steps = np.diff(r.sync.astype(np.int64))
    back = np.flatnonzero(steps < 0)
    if len(back):
        raise FormatError(f"{path}: photon {back[0] + 1} (sync {r.sync[back[0] + 1]}) comes "
                          f"before photon {back[0]} (sync {r.sync[back[0]]}): the records "
                          f"are not in time order")
    far = np.flatnonzero(steps >= 1 << (PULSE_BITS - 1))
    if len(far):
        raise FormatError(f"{path}: photons {far[0]} and {far[0] + 1} are {steps[far[0]]} "
                          f"sync periods apart, more than FLISS's {PULSE_BITS}-bit laser cycle "
                          f"count tells apart (2**{PULSE_BITS - 1})")
    problems = list(r.problems)
    top = int(r.micro.max()) if len(r.micro) else 0
    drop = max(0, top.bit_length() - TIMESTAMP_BITS)
    width_s = r.width_s * (1 << drop)
    if drop:
        problems.append(f"its micro times (up to {top}, of {r.width_s * 1e12:g} ps) are more "
                        f"than FLISS's {_CODES} timestamp codes: each is divided by "
                        f"{1 << drop} (codes of {width_s * 1e12:g} ps), its lowest {drop} "
                        f"bit{'s' * (drop > 1)} dropped")
    shift = min(max(0, round(math.log2(width_s / TDC_LSB_S))), 16)
    if r.markers:
        channels = ", ".join(str(c) for c in r.marker_channels)
        problems.append(f"{r.markers} marker record{'s' * (r.markers > 1)} (marker"
                        f"{'s' * (len(r.marker_channels) > 1)} {channels}) are not photons "
                        f"and are left out")
    events = np.zeros(len(r.sync), dtype=EVENT_DTYPE)
    events["pulse"] = r.sync & np.uint64(0xFFFFFFFF)
    events["timestamp"] = r.micro >> drop
    events["address"] = r.channel
    source = (f"{r.source}: {r.records} records, {len(r.sync)} photons, {r.markers} markers, "
              f"{r.overflows} overflow records")
    counters = {"records": {"records": r.records, "photons": len(r.sync),
                            "markers": r.markers, "overflows": r.overflows}}
    return ForeignCapture(
        path, {"mode": "raw", "end_reason": f"unknown ({source})"}, {}, {},
        np.zeros((0, 0), dtype=np.uint32), np.zeros(0, dtype=np.uint32),
        np.zeros(0, dtype=np.uint8), np.zeros(0), np.zeros(0, dtype=bool), events,
        np.zeros(0), counters, problems, code_width_s=width_s,
        period_s=r.period_s, source=r.source, bin_shift=shift)


def read_foreign(path, kind, ptu_header=None):
    """The :class:`ForeignCapture` of the file ``path`` of ``kind`` (:func:`read_recording`,
    then :func:`to_capture`)."""
    return to_capture(read_recording(path, kind, ptu_header))
