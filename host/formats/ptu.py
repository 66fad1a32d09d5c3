"""PicoQuant PTU files: FLISS captures written as T3 records, and PTU files read as captures.

A raw capture becomes T3 point-mode records (:mod:`.ptu_records`: one per event, the laser cycle
as the sync count, the TDC code as ``dtime``, the pixel address as the channel); a histogram or
image capture becomes a T3 image-mode file, the form of PTU that carries TCSPC histograms,
written by ptufile's :class:`ptufile.PtuWriter`: one frame per histogram row, one image pixel
per sensor pixel, one record per count. Both use the ``GenericT3`` record (MultiHarp,
PicoHarp 330): its 15-bit ``dtime`` holds the 8192 codes of the TDC (PicoHarp T3's 12 bits hold
4096) and its 6-bit channel the 64 pixel addresses. The settings go into tags named
``FLISS_<setting>`` (docs/file-format.md).

Reading (ptufile): a FLISS export gives back the capture it was made of; any other T3 file the
TCSPC histogram of all its photons.
"""

import json
import struct
import uuid

import numpy as np

from ... import __version__
from ...hdl.event import TIMESTAMP_BITS
from ...protocol.events import EVENT_DTYPE
from ..errors import FormatError
from ..kinds import KINDS, names
from .metadata import created, cycle_chunks, imported, metadata, restored, settings, timing
from .ptu_header import read_header
from .ptu_records import GENERIC_T3, header, number_records_at, ptufile_notes, t3_records


__all__ = ["write_ptu", "read_ptu", "ptu_tags"]


def _ptufile():
    try:
        import ptufile
    except ImportError:
        raise FormatError("PTU files need the ptufile package: pip install "
                          "'fliss[formats]'") from None
    return ptufile


def ptu_tags(capture):
    """The ``FLISS_*`` tags of a capture's export: the settings that matter and the whole
    metadata (JSON texts), never the key. Of another instrument's recording, its source and
    timing only: read back, it is that recording again (:mod:`.tttr_foreign`)."""
    tags = {f"FLISS_{name}": value for name, value in settings(capture).items()}
    if not getattr(capture, "source", None):
        tags.update({f"FLISS_{name}": text for name, text in metadata(capture).items()})
    return tags


def _comment(capture):
    if getattr(capture, "source", None):
        return f"{capture.source}: {capture.path}, converted by fliss"
    s = settings(capture)
    detail = ", ".join(f"{name} {s[name]}" for name in ("length", "mask_width", "seed", "iv")
                       if name in s)
    return (f"FLISS {capture.mode} capture {capture.path}: delay mode {s['delay_mode']}"
            + (f" ({detail})" if detail else "") + f", PRF {s['prf_hz']:g} Hz")


def write_ptu(capture, path):
    """Write ``capture`` (of a kind of data that PTU takes: raw, histogram or image) to the PTU
    file ``path``: its events as T3 records, or its frames as an image of T3 records; returns
    the number of records."""
    kind = KINDS.get(capture.mode)
    if kind is None or "ptu" not in kind.exports:
        raise FormatError(f"{capture.path}: a {capture.mode} capture has no PTU form")
    if not kind.framed:
        return _write_events(capture, path)
    return _write_histograms(capture, path)


def _write_events(capture, path):
    # Run by run (metadata.CHUNK_EVENTS events), the number of records patched in at the end.
    period_s, prf_hz = timing(capture)
    events = capture.events
    tags = {
        "File_GUID": f"{{{uuid.uuid4()}}}",
        "File_CreatingTime": created(capture),
        "File_Comment": _comment(capture),
        "CreatorSW_Name": "fliss",
        "CreatorSW_Version": __version__,
        "Measurement_Mode": 3,              # T3
        "Measurement_SubMode": 1,           # a point: no image markers
        "MeasDesc_BinningFactor": 1,
        "MeasDesc_Resolution": float(capture.code_s),
        "MeasDesc_GlobalResolution": float(period_s),
        "TTResult_SyncRate": int(round(prf_hz)),
        "TTResult_NumberOfRecords": 0,
        "TTResultFormat_TTTRRecType": GENERIC_T3,
        "TTResultFormat_BitsPerRecord": 32,
        "HW_InpChannels": 1 << 6,
    }
    if "capture_s" in capture.attrs:
        tags["MeasDesc_AcquisitionTime"] = int(round(float(capture.attrs["capture_s"]) * 1e3))
    tags.update(ptu_tags(capture))
    head = header(tags)
    written, before = 0, 0
    with open(path, "wb") as f:
        f.write(head)
        for start, cycles in cycle_chunks(capture):
            run = events[start:start + len(cycles)]
            records = t3_records(cycles, run["timestamp"], run["address"], before)
            f.write(records.tobytes())
            written, before = written + len(records), int(cycles[-1])
        f.seek(number_records_at(head))
        f.write(struct.pack("<q", written))
    return written


def _write_histograms(capture, path):
    ptufile = _ptufile()
    period_s, _ = timing(capture)
    counts = capture.histograms
    if not len(counts):
        raise FormatError(f"{capture.path}: the capture holds no histograms to export")
    if counts.ndim == 2:        # (one pixel: a histogram per frame)
        counts = counts[:, np.newaxis, :]
    if capture.bin_s > period_s:
        raise FormatError(f"{capture.path}: its bins ({capture.bin_s * 1e9:g} ns) are wider "
                          f"than the laser period ({period_s * 1e9:g} ns), which PTU does not "
                          f"allow")
    tags = ptu_tags(capture)
    tags.update(CreatorSW_Name="fliss", CreatorSW_Version=__version__,
                FLISS_first_frame=int(capture.frames[0]),
                FLISS_incomplete_rows=json.dumps(np.flatnonzero(~capture.complete).tolist()))
    if capture.histograms.ndim == 3:        # (per-pixel histograms)
        tags["FLISS_first_pixel"] = int(capture.pixels[0])
    # (frames, Y, X, channels, bins): a line of pixels, one channel.
    data = np.ascontiguousarray(counts[:, np.newaxis, :, np.newaxis, :])
    pixel_time = period_s * max(1, int(data.sum(axis=-1).max()))
    try:
        with ptufile.PtuWriter(path, data.shape, period_s, capture.bin_s, pixel_time,
                               record_type=ptufile.PtuRecordType.GenericT3, has_frames=True,
                               comment=_comment(capture), datetime=created(capture),
                               tags=tags) as writer:
            writer.write(data)
    except ValueError as error:
        raise FormatError(f"{capture.path}: ptufile cannot write it ({error})") from None
    with ptufile.PtuFile(path) as written:
        return written.number_records


def read_ptu(path):
    """The capture of a PTU file: a FLISS export as the capture it was made of; any other T3
    file as one TCSPC histogram (all its photons, all channels). Refused with one line
    (:exc:`FormatError`): a file that is not a PTU file or not a whole one (its header checked
    first, :func:`.ptu_header.read_header`), T2 records (no sync, so no TCSPC histogram), a
    record type that is not one of PicoQuant's T3 records, records ptufile cannot decode."""
    ptufile = _ptufile()
    header = read_header(path)
    kind = header.tags["TTResultFormat_TTTRRecType"]
    t3 = {record.value: record.name for record in ptufile.PtuRecordType
          if record.name.endswith("T3")}
    if kind not in t3:
        raise FormatError(f"{path}: not a PTU file fliss reads (its record type, "
                          f"TTResultFormat_TTTRRecType, is 0x{kind:08X}: none of the T3 "
                          f"records {', '.join(t3.values())})")
    with ptufile_notes() as notes:
        try:
            ptu = ptufile.PtuFile(path)
        except Exception as error:          # whatever ptufile finds wrong: one line
            raise FormatError(f"{path}: not a PTU file ptufile can read "
                              f"({str(error).splitlines()[0] if str(error) else error!r})") \
                from None
        with ptu:
            return _read(ptufile, ptu, path, notes, header)


def _read(ptufile, ptu, path, notes, header):
    try:
        if "FLISS_configuration" in ptu.tags:
            capture = _restore(ptu, path)
        else:
            # The bins of one sync period, or up to the last photon's if later.
            bins = max(ptu.number_bins_in_period, ptu.number_bins)
            counts = ptu.decode_histogram(dtype=np.uint64, dtime=bins)
            kind = ptufile.PtuRecordType(ptu.tags["TTResultFormat_TTTRRecType"]).name
            capture = imported(path, counts.sum(axis=0), ptu.tcspc_resolution,
                               f"a PTU file, {kind} records")
    except FormatError:
        raise
    except Exception as error:              # whatever ptufile finds wrong: one line
        raise FormatError(f"{path}: ptufile cannot decode its records "
                          f"({str(error).splitlines()[0] if str(error) else error!r})") from None
    count, extra = ptu.number_records, header.data_bytes - 4 * ptu.number_records
    if extra > 0:
        capture.problems.append(f"{extra} bytes after the {count} records its header "
                                f"announces are left out")
    if notes.messages:
        more = len(notes.messages) - 1
        capture.problems.append(f"ptufile: {notes.messages[0]}"
                                + (f" (and {more} more)" if more else ""))
    return capture


def _restore(ptu, path):
    tags = ptu.tags
    texts = {name: tags.get(f"FLISS_{name}") for name in ("configuration", "identity",
                                                           "capture")}
    mode = tags.get("FLISS_mode")
    kind = KINDS.get(mode)
    if kind is None or "ptu" not in kind.exports:
        raise FormatError(f"{path}: its FLISS_mode tag is {mode!r}, not "
                          f"{names(lambda kind: 'ptu' in kind.exports, 'or')}")
    if not kind.framed:
        records = ptu.decode_records()
        photons = records[records["channel"] >= 0]
        events = np.zeros(len(photons), dtype=EVENT_DTYPE)
        events["pulse"] = photons["time"] & np.uint64(0xFFFFFFFF)
        events["timestamp"] = photons["dtime"]
        events["address"] = photons["channel"]
        return restored(path, texts, events=events)
    registers = json.loads(texts["configuration"] or "{}")
    bins = (1 << TIMESTAMP_BITS) >> int(registers.get("bin_shift", 0))
    counts = ptu.decode_image(dtype=np.uint32, dtime=bins)[:, 0, :, 0, :]
    pixels = None
    if not kind.imager:         # (one pixel)
        counts = counts[:, 0, :]
    else:
        pixels = int(tags.get("FLISS_first_pixel", 0)) + np.arange(counts.shape[1])
    return restored(path, texts, histograms=counts, pixels=pixels,
                    incomplete=json.loads(tags.get("FLISS_incomplete_rows", "[]")),
                    first_frame=int(tags.get("FLISS_first_frame", 0)))
