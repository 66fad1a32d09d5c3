"""TCSPC recordings of other instruments read as raw captures: PicoQuant PTU files (every T3
record type), HT3 files (HydraHarp 400), PT3 files (PicoHarp 300) and Becker & Hickl SPC files
(the 32-bit FIFO records of the SPC-130/150/160/180/830 modules, with their ``.set`` file).

ptufile decodes PicoQuant's T3 records (of PTU, HT3 and PT3 files; tttrlib reads the headers of
HT3 and PT3 files), tttrlib (Fluorescence-Tools, C++) decodes SPC files; why these, and what
maps to what: docs/file-format.md. :func:`read_recording` gives the decoded photons
as the file holds them (a :class:`Recording`: the sync count, the micro time, the channel of
each, and how many records were markers and overflows); :func:`to_capture` puts them in FLISS's
terms (a :class:`ForeignCapture`, a raw capture: the sync period as the laser period, the
sync count as the laser cycle, the micro time as the timestamp code, the channel as the pixel
address). What cannot map is refused with one line (:exc:`FormatError`): a T2 file (no laser
sync), a channel with no pixel address, a file that gives no sync period or micro-time width,
photons out of time order or further apart than FLISS's 32-bit laser cycle count tells.
Nothing is lost silently: markers (which are not photons) are counted and said to be left out,
overflow records counted, micro times too fine for FLISS's 13-bit codes binned and said so.
"""

import contextlib
import json
import logging
import math
import os
import sys
import tempfile
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ...hdl.event import PULSE_BITS, TDC_LSB_S, TIMESTAMP_BITS
from ...protocol.events import EVENT_DTYPE
from ..errors import FormatError
from ..fileformat import Capture
from .ptu_records import header as ptu_header
from .tttr_spc import spc_timing


#: Codes FLISS's timestamps hold.
_CODES = 1 << TIMESTAMP_BITS

__all__ = ["KINDS", "foreign_kind", "Recording", "read_recording", "ForeignCapture",
           "to_capture", "read_foreign"]


#: What each kind of file is called, and tttrlib's name of its container (tttrlib reads no PT3
#: files: phconvert reads their header).
KINDS = {
    "ptu": ("a PTU file", "PTU"),
    "ht3": ("an HT3 file", "HT3"),
    "pt3": ("a PT3 file", None),
    "spc": ("a Becker & Hickl SPC file", "SPC-130"),
}

#: The first bytes (the ``Ident`` field) of the HT3 and PT3 headers.
_IDENTS = ((b"HydraHarp", "ht3"), (b"PicoHarp", "pt3"))

#: ``TTResultFormat_TTTRRecType`` of the T3 records tttrlib decodes, by name.
_PTU_T3 = {0x00010303: "PicoHarpT3", 0x00010304: "HydraHarpT3", 0x01010304: "HydraHarp2T3",
           0x00010305: "TimeHarp260NT3", 0x00010306: "TimeHarp260PT3",
           0x00010307: "GenericT3"}

#: What tttrlib says of every HydraHarp 2.0 HT3 file it reads right (checked against another
#: decoder in tests/host/test_tttr_foreign.py): not a problem of the file.
_KNOWN_NOTES = ("WARNING: Only HT3 files in version 1.0 supported.",)


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
            raise FormatError(f"{path}: not {KINDS[kind][0]} (it does not begin with "
                              f"{idents}, the mark of one)")
    return None


@dataclass
class Recording:
    """The photons of a file as it holds them: ``sync`` the sync count (macro time, in sync
    periods: ``period_s``), ``micro`` the micro time (in ``width_s``), ``channel`` the
    channel of each; ``records`` the records of the file, of which ``markers`` were markers
    (their ``marker_channels``) and the rest, not photons, overflows (``overflows``);
    ``problems`` what of the file was not as it should be."""
    path: str
    kind: str
    source: str
    sync: np.ndarray
    micro: np.ndarray
    channel: np.ndarray
    period_s: float
    width_s: float
    records: int
    markers: int
    marker_channels: list
    problems: list = field(default_factory=list)
    #: The records its header announces (None: it does not say).
    announced: Optional[int] = None

    @property
    def overflows(self):
        return self.records - len(self.sync) - self.markers


def _tttrlib():
    try:
        import tttrlib
    except ImportError:
        raise FormatError("HT3, PT3 and SPC files, and PTU files of other programs, need the "
                          "tttrlib package: pip install 'fliss[formats]'") from None
    return tttrlib


@contextlib.contextmanager
def _console(said):
    # tttrlib (C++) writes its warnings to the process's stdout: kept from the command's
    # output (a --json one above all) and appended to ``said``.
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as sink:
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            said.extend(line.strip() for line in sink.read().decode(errors="replace")
                        .splitlines() if line.strip())


def _tags(header):
    # The header's tags by name (the last of a name given several times).
    try:
        return {tag["name"]: tag["value"] for tag in json.loads(header.json).get("tags", [])}
    except (ValueError, TypeError, KeyError):
        return {}


def read_recording(path, kind, ptu_header=None):
    """The :class:`Recording` of the file ``path`` of ``kind`` (a key of :data:`KINDS`); for a
    PTU file, ``ptu_header`` is its header as :func:`.ptu_header.read_header` checked it.
    PicoQuant's T3 records (PTU, HT3, PT3) are decoded by ptufile, the headers of HT3 and PT3
    files read by tttrlib; SPC files are decoded by tttrlib (docs/file-format.md says why)."""
    what = KINDS[kind][0]
    path = str(path)
    if not os.path.isfile(path):
        raise FormatError(f"no such file: {path}" if not os.path.exists(path) else
                          f"{path} is not a regular file, not {what}")
    if os.path.getsize(path) == 0:
        raise FormatError(f"{path} is empty, not {what}")
    decode = {"ptu": _decode_ptu, "spc": _decode_spc}.get(kind, _decode_classic)
    recording = decode(path, kind, ptu_header)
    if recording.announced is not None and recording.announced > recording.records:
        recording.problems.append(f"it is cut short: its header announces "
                                  f"{recording.announced} records and {recording.records} "
                                  f"follow it; those are read")
    return recording


def _failure(path, reader, what, error):
    detail = str(error).splitlines()[0] if str(error) else repr(error)
    return FormatError(f"{path}: {reader} cannot read it as {what} ({detail})")


def _read_tttrlib(path, kind):
    # tttrlib's TTTR of the file and what it said; refused in one line if it cannot.
    what, container = KINDS[kind]
    tttrlib = _tttrlib()
    said = []
    with _console(said):
        try:
            tttr = tttrlib.TTTR(path, container)
        except Exception as error:          # whatever tttrlib finds wrong: one line
            tttr, failure = None, error
    if tttr is None:
        raise _failure(path, "tttrlib", what, failure)
    return tttr, [f"tttrlib: {line}" for line in said if line not in _KNOWN_NOTES]


def _decode_spc(path, kind, _):
    timing = spc_timing(path)                   # (refused before decoding)
    tttr, problems = _read_tttrlib(path, kind)
    source, announced = _check_header(path, kind, _tags(tttr.header), timing)
    types = np.asarray(tttr.event_types)
    channels = np.asarray(tttr.routing_channels)
    photon = types == 0
    return Recording(
        path, kind, source, np.asarray(tttr.macro_times)[photon].astype(np.uint64),
        np.asarray(tttr.micro_times)[photon].astype(np.uint16),
        channels[photon].astype(np.int16), float(tttr.header.macro_time_resolution),
        float(timing[0]), int(tttr.n_records_in_file), int(np.count_nonzero(types == 1)),
        sorted(int(c) for c in np.unique(channels[types == 1])), problems)


class _Notes(logging.Handler):
    # ptufile's complaints about a file it reads anyway.
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def _ptufile():
    try:
        import ptufile
    except ImportError:
        raise FormatError("PicoQuant files need the ptufile package: pip install "
                          "'fliss[formats]'") from None
    return ptufile


@contextlib.contextmanager
def _ptufile_notes(problems):
    notes, logger = _Notes(), logging.getLogger("ptufile")
    logger.addHandler(notes)
    propagate, logger.propagate = logger.propagate, False
    try:
        yield
    finally:
        logger.removeHandler(notes)
        logger.propagate = propagate
        problems.extend(f"ptufile: {message}" for message in notes.messages[:1])


def _decode_ptu(path, kind, header):
    ptufile = _ptufile()
    record_type = header.tags["TTResultFormat_TTTRRecType"]
    if record_type not in _PTU_T3:
        raise FormatError(f"{path}: not a PTU file fliss reads (its record type, "
                          f"TTResultFormat_TTTRRecType, is 0x{record_type:08X}: none of the "
                          f"T3 records {', '.join(_PTU_T3.values())})")
    problems = []
    try:
        with _ptufile_notes(problems), ptufile.PtuFile(path) as ptu:
            records = ptu.decode_records()
            period_s, width_s = ptu.global_resolution, ptu.tcspc_resolution
    except Exception as error:              # whatever ptufile finds wrong: one line
        raise _failure(path, "ptufile", "a PTU file", error) from None
    extra = header.data_bytes - 4 * len(records)
    if extra > 0:
        problems.append(f"{extra} bytes after the {len(records)} records its header "
                        f"announces are left out")
    instrument = header.tags.get("HW_Type") or "PicoQuant instrument"
    return _of_records(path, kind, f"a PTU file of a {instrument} ({_PTU_T3[record_type]} "
                       f"records)", records, period_s, width_s, problems)


def _of_records(path, kind, source, records, period_s, width_s, problems):
    # The Recording of T3 records as ptufile decodes them: a channel of 0 and up a photon,
    # else a marker (its bits in ``marker``) or an overflow.
    photon = records["channel"] >= 0
    marker = ~photon & (records["marker"] > 0)
    return Recording(
        path, kind, source, records["time"][photon].astype(np.uint64),
        records["dtime"][photon].astype(np.uint16), records["channel"][photon].astype(np.int16),
        float(period_s), float(width_s), len(records), int(np.count_nonzero(marker)),
        sorted(int(m) for m in np.unique(records["marker"][marker])), problems)


#: PTU record types of the records of HT3 files (by format version) and of PT3 files.
_HT3_RECORDS = {"1": 0x00010304, "2": 0x01010304}
_PT3_RECORDS = 0x00010303


def _ht3(path, kind):
    # HT3: the header by tttrlib; (source, records announced, period, width, record type,
    # the records, problems).
    what = KINDS[kind][0]
    tttr, problems = _read_tttrlib(path, kind)
    tags = _tags(tttr.header)
    source, announced = _check_header(path, kind, tags, None)
    version = str(tags.get("FormatVersion", "")).strip()[:1]
    if version not in _HT3_RECORDS:
        raise FormatError(f"{path}: {what} of format version {tags.get('FormatVersion')!r}, "
                          f"which fliss does not read (1.0 and 2.0)")
    header = tttr.header
    offset = int(header.end())
    count, extra = divmod(max(0, os.path.getsize(path) - offset), 4)
    if extra:
        problems.append(f"its last {extra} bytes are not a whole record and are left out")
    words = np.fromfile(path, dtype="<u4", count=count, offset=offset)
    return (source, announced, header.macro_time_resolution, header.micro_time_resolution,
            _HT3_RECORDS[version], words, problems)


def _pt3(path, kind):
    # PT3: the header and the records by phconvert (tttrlib reads no PT3 files).
    try:
        from phconvert import pqreader
    except ImportError:
        raise FormatError("PT3 files need the phconvert package: pip install "
                          "'fliss[formats]'") from None
    said = []
    try:
        with _console(said):
            words, period_s, width_s, meta = pqreader.pt3_reader(path)
        header = meta["header"]
        tags = {"MeasurementMode": int(header["MeasurementMode"][0]),
                "Ident": header["Ident"][0].decode(errors="replace").strip(),
                "FormatVersion": header["FormatVersion"][0].decode(errors="replace").strip()}
        announced = int(meta["ttmode"]["nRecords"][0])
    except Exception as error:              # whatever phconvert finds wrong: one line
        raise _failure(path, "phconvert", KINDS[kind][0], error) from None
    source, _ = _check_header(path, kind, tags, None)
    return (source, announced, period_s, width_s, _PT3_RECORDS, words,
            [f"phconvert: {line}" for line in said])


def _decode_classic(path, kind, _):
    # HT3 and PT3: the records by ptufile's decoder of T3 records, their PTU record type named
    # by a PTU header of no records.
    what = KINDS[kind][0]
    source, announced, period_s, width_s, record_type, words, problems = \
        (_ht3 if kind == "ht3" else _pt3)(path, kind)
    ptufile = _ptufile()
    stub = ptu_header({
        "Measurement_Mode": 3, "Measurement_SubMode": 0, "MeasDesc_Resolution": width_s,
        "MeasDesc_GlobalResolution": period_s, "TTResult_NumberOfRecords": 0,
        "TTResultFormat_TTTRRecType": record_type, "TTResultFormat_BitsPerRecord": 32})
    try:
        with tempfile.TemporaryDirectory() as folder:
            name = os.path.join(folder, "records.ptu")
            with open(name, "wb") as f:
                f.write(stub)
            with _ptufile_notes(problems), ptufile.PtuFile(name) as ptu:
                records = ptu.decode_records(np.ascontiguousarray(words, dtype=np.uint32))
    except Exception as error:              # whatever ptufile finds wrong: one line
        raise _failure(path, "ptufile", what, error) from None
    recording = _of_records(path, kind, source, records, period_s, width_s, problems)
    recording.announced = announced
    return recording


def _check_header(path, kind, tags, timing):
    # (what made the file, for the capture's source; the records its header announces), or a
    # refusal of a T2 file.
    what = KINDS[kind][0]
    if kind == "spc":
        return f"{what} of an {timing[1]} (its .set file gives the micro-time width)", None
    mode = tags.get("MeasurementMode")
    if mode == 2:
        raise FormatError(f"{path}: a T2 {what.split(' ', 1)[1]} (time tags without a laser "
                          f"sync) holds no TCSPC histogram; fliss reads T3 files")
    if mode != 3:
        raise FormatError(f"{path}: its MeasurementMode is {mode!r}, not 3 (T3 records); fliss "
                          f"reads T3 files")
    version = str(tags.get("FormatVersion", "?")).strip()
    return (f"{what} of a {tags.get('Ident', 'PicoQuant instrument')} (format {version})",
            tags.get("nRecords") or None)


@dataclass
class ForeignCapture(Capture):
    """A raw capture read from another instrument's file: its timestamp codes are
    ``code_width_s`` wide (not a FLISS TDC's), its laser period is the file's sync period
    (``period_s``), and ``source`` names the format and the instrument. Its histogram
    (:meth:`total_histogram`) has a bin per code, as many as the sync period holds (or up to
    the last photon's code); ``bin_shift`` is the power of two nearest the codes' width in
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
            raise FormatError(f"{path}: {KINDS[r.kind][0]} that gives no {name} ({value!r} s), "
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
