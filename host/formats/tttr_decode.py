"""The decoders of other instruments' recordings (:func:`.tttr_foreign.read_recording`), one a
kind of file, each giving a :class:`~.tttr_foreign.Recording`.

PicoQuant's T3 records, of PTU, HT3 and PT3 files alike, are decoded by ptufile
(:meth:`ptufile.PtuFile.decode_records`; the records of an HT3 or PT3 file are handed to it
under a PTU header of no records that names their record type). The headers: PTU ones checked
by :mod:`.ptu_header` and read by ptufile, HT3 ones by :mod:`.ht3_header`, PT3 ones by
phconvert (:func:`phconvert.pqreader.pt3_reader`). Becker & Hickl SPC files are decoded by
phconvert (:func:`phconvert.bhreader.load_spc`), their micro-time width taken from the ``.set``
file (:mod:`.tttr_spc`). Why these and not tttrlib: docs/file-format.md.
"""

import contextlib
import os
import sys
import tempfile
import warnings

import numpy as np

from ..errors import FormatError
from .ht3_header import read_ht3_header
from .ptu_records import header as ptu_header, ptufile_notes
from .tttr_recording import KINDS, Recording, check_mode
from .tttr_spc import set_file, spc_timing


__all__ = ["read_recording", "PTU_T3"]


#: ``TTResultFormat_TTTRRecType`` of PicoQuant's T3 records, by name.
PTU_T3 = {0x00010303: "PicoHarpT3", 0x00010304: "HydraHarpT3", 0x01010304: "HydraHarp2T3",
          0x00010305: "TimeHarp260NT3", 0x00010306: "TimeHarp260PT3",
          0x00010307: "GenericT3"}
#: The record types of HT3 files, by format version, and of PT3 files.
_HT3_RECORDS = {"1.0": 0x00010304, "2.0": 0x01010304}
_PT3_RECORDS = 0x00010303


def _failure(path, reader, what, error):
    detail = str(error).splitlines()[0] if str(error) else repr(error)
    return FormatError(f"{path}: {reader} cannot read it as {what} ({detail})")


def _library(name, what):
    try:
        return __import__(name)
    except ImportError:
        raise FormatError(f"{what} need the {name} package: pip install "
                          f"'fliss[formats]'") from None


@contextlib.contextmanager
def _console(said):
    # What a library prints (phconvert: "NOTE: You can speed-up ... numba") kept from the
    # command's output (a --json one above all) and appended to ``said``.
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as sink:
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            with contextlib.redirect_stdout(sys.__stdout__), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                yield
        finally:
            for stream in (sys.stdout, sys.stderr, sys.__stdout__):
                stream.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            said.extend(line.strip() for line in sink.read().decode(errors="replace")
                        .splitlines() if line.strip() and "numba" not in line)


@contextlib.contextmanager
def _ptufile_notes(problems):
    with ptufile_notes() as notes:
        try:
            yield
        finally:
            problems.extend(f"ptufile: {message}" for message in notes.messages[:1])


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


def _decode_ptu(path, kind, header):
    ptufile = _library("ptufile", "PTU files")
    record_type = header.tags["TTResultFormat_TTTRRecType"]
    if record_type not in PTU_T3:
        raise FormatError(f"{path}: not a PTU file fliss reads (its record type, "
                          f"TTResultFormat_TTTRRecType, is 0x{record_type:08X}: none of the "
                          f"T3 records {', '.join(PTU_T3.values())})")
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
    return _of_records(path, kind, f"a PTU file of a {instrument} ({PTU_T3[record_type]} "
                       f"records)", records, period_s, width_s, problems)


def _decode_t3(path, kind, source, words, record_type, period_s, width_s, problems):
    # T3 records of an HT3 or PT3 file by ptufile's decoder, their record type named by a PTU
    # header of no records.
    ptufile = _library("ptufile", "PicoQuant files")
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
        raise _failure(path, "ptufile", KINDS[kind], error) from None
    return _of_records(path, kind, source, records, period_s, width_s, problems)


def _decode_ht3(path, kind, _):
    header = read_ht3_header(path)
    check_mode(path, kind, header.mode)
    if header.version not in _HT3_RECORDS:
        raise FormatError(f"{path}: an HT3 file of format version {header.version!r}, which "
                          f"fliss does not read (1.0 and 2.0)")
    problems = []
    if header.extra:
        problems.append(f"its last {header.extra} bytes are not a whole record and are left "
                        f"out")
    period_s = 1 / header.sync_hz if header.sync_hz > 0 else float("nan")
    words = np.fromfile(path, dtype="<u4", count=header.records, offset=header.data_offset)
    recording = _decode_t3(path, kind, f"an HT3 file of a HydraHarp (format {header.version})",
                           words, _HT3_RECORDS[header.version], period_s, header.resolution_s,
                           problems)
    recording.announced = header.announced
    return recording


def _decode_pt3(path, kind, _):
    pqreader = _library("phconvert", "PT3 files").pqreader
    said = []
    try:
        with _console(said):
            words, period_s, width_s, meta = pqreader.pt3_reader(path)
        mode = int(meta["header"]["MeasurementMode"][0])
        version = meta["header"]["FormatVersion"][0].decode(errors="replace").strip()
        announced = int(meta["ttmode"]["nRecords"][0])
    except Exception as error:              # whatever phconvert finds wrong: one line
        raise _failure(path, "phconvert", KINDS[kind], error) from None
    check_mode(path, kind, mode)
    recording = _decode_t3(path, kind, f"a PT3 file of a PicoHarp 300 (format {version})",
                           words, _PT3_RECORDS, period_s, width_s,
                           [f"phconvert: {line}" for line in said])
    recording.announced = announced
    return recording


def _decode_spc(path, kind, _):
    # Refused before decoding without the .set file, which gives the micro-time width.
    width_s, module = spc_timing(path)
    size = os.path.getsize(path)
    if size < 4:
        raise FormatError(f"{path}: not {KINDS[kind]} (it ends at byte {size}, in its first "
                          f"record, which gives the macro-time clock)")
    bhreader = _library("phconvert", "SPC files").bhreader
    said = []
    try:
        with _console(said):
            data = bhreader.load_spc(path, set_file(path), SPC_type="SPC-1XX")["photon_data"]
    except Exception as error:              # whatever phconvert finds wrong: one line
        raise _failure(path, "phconvert", KINDS[kind], error) from None
    detector = np.asarray(data["detectors"])
    marker = np.isin(detector, np.asarray(data["marker_ids"]))
    records, extra = divmod(size - 4, 4)
    problems = [f"phconvert: {line}" for line in said]
    if extra:
        problems.append(f"its last {extra} bytes are not a whole record and are left out")
    # B&H's GAP flag (bit 29 of a record): the module's FIFO overflowed before it, photons lost.
    gaps = int(np.count_nonzero(np.fromfile(path, dtype="<u4", count=records, offset=4)
                                & np.uint32(1 << 29)))
    if gaps:
        problems.append(f"{gaps} record{'s' * (gaps > 1)} carry the GAP flag: the module's "
                        f"FIFO overflowed there and the photons it could not hold were lost "
                        f"in the recording")
    # (phconvert numbers a marker past the photons' channels: 16 and up for 4 routing bits)
    return Recording(
        path, kind, f"a Becker & Hickl SPC file of an {module} (its .set file gives the "
        f"micro-time width)", np.asarray(data["timestamps"])[~marker].astype(np.uint64),
        np.asarray(data["nanotimes"])[~marker].astype(np.uint16),
        detector[~marker].astype(np.int16), float(data["timestamps_unit"]), float(width_s),
        records, int(np.count_nonzero(marker)),
        sorted(int(d) for d in np.unique(detector[marker])), problems)


#: The decoder of each kind of file.
_DECODERS = {"ptu": _decode_ptu, "ht3": _decode_ht3, "pt3": _decode_pt3, "spc": _decode_spc}


def read_recording(path, kind, ptu_header=None):
    """The :class:`Recording` of the file ``path`` of ``kind`` (a key of :data:`KINDS`); for a
    PTU file, ``ptu_header`` is its header as :func:`.ptu_header.read_header` checked it."""
    what = KINDS[kind]
    path = str(path)
    if not os.path.isfile(path):
        raise FormatError(f"no such file: {path}" if not os.path.exists(path) else
                          f"{path} is not a regular file, not {what}")
    if os.path.getsize(path) == 0:
        raise FormatError(f"{path} is empty, not {what}")
    recording = _DECODERS[kind](path, kind, ptu_header)
    if recording.announced is not None and recording.announced > recording.records:
        recording.problems.append(f"it is cut short: its header announces "
                                  f"{recording.announced} records and {recording.records} "
                                  f"follow it; those are read")
    return recording
