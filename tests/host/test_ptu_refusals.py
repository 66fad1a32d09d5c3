"""A file that is not a PTU file, or not a whole one, is refused with one line that says why
(issue 41: ``junk.ptu`` gave "cannot access local variable 'tagid'"), and no cut or damaged
copy of a good PTU file ends in a traceback or in a capture of fewer records than its header
announces."""

import struct

import numpy as np
import pytest

from fliss.host.cli import main
from fliss.host.errors import FormatError
from fliss.host.formats import export_capture, read_file
from fliss.host.formats.ptu_records import GENERIC_T3, header, t3_records

from format_captures import histogram_capture, raw_capture


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def picoquant(path, photons, **changes):
    """A T3 file as PicoQuant's programs write one (no FLISS tags), of ``photons`` photons
    (and the overflow records between them)."""
    rng = np.random.default_rng(5)
    sync = np.sort(rng.integers(0, 5000, photons))
    body = t3_records(sync, rng.choice([530, 2030], photons), np.zeros(photons, int))
    tags = {"Measurement_Mode": 3, "Measurement_SubMode": 0, "MeasDesc_Resolution": 50e-12,
            "MeasDesc_GlobalResolution": 1e-6, "TTResult_SyncRate": 1_000_000,
            "TTResult_NumberOfRecords": len(body),
            "TTResultFormat_TTTRRecType": GENERIC_T3, "TTResultFormat_BitsPerRecord": 32,
            "File_Comment": "two echoes"}
    tags.update(changes)
    path.write_bytes(header(tags) + body.tobytes())
    return path


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """Good PTU files: a FLISS export of raw events, one of histograms, a PicoQuant T3 file."""
    folder = tmp_path_factory.mktemp("ptu")
    raw, _ = raw_capture(folder / "r.h5", n=300)
    export_capture(raw, folder / "raw.ptu", "ptu")
    rows = np.random.default_rng(2).poisson(3, (2, 4096)).astype(np.uint32)
    export_capture(histogram_capture(folder / "h.h5", rows), folder / "hist.ptu", "ptu")
    picoquant(folder / "pq.ptu", 200)
    return {name: (folder / name).read_bytes() for name in ("raw.ptu", "hist.ptu", "pq.ptu")}


def header_end(data):
    return data.index(b"Header_End".ljust(32, b"\0")) + 48


def records_announced(data):
    at = data.index(b"TTResult_NumberOfRecords".ljust(32, b"\0")) + 40
    return struct.unpack("<q", data[at:at + 8])[0]


def one_line_or_capture(path):
    """Read ``path``: the capture, or the refusal's message (one line, naming the file); any
    other exception fails the test."""
    try:
        return read_file(path)
    except FormatError as error:
        message = str(error)
        assert "\n" not in message and message.startswith(f"{path}: "), message
        return message


def test_every_cut_of_a_good_file_is_refused_in_one_line(tmp_path, good):
    for name, data in good.items():
        end = header_end(data)
        records = np.linspace(end, len(data) - 1, 60).astype(int)
        cuts = sorted(set(range(0, end, 8)) | set(records) | {end - 1, end, len(data) - 4})
        for cut in cuts:
            path = tmp_path / f"cut-{cut}-{name}"
            path.write_bytes(data[:cut])
            got = one_line_or_capture(path)
            assert isinstance(got, str), f"{name} cut at byte {cut} of {len(data)} was read"
            assert got.startswith(f"{path}: not a PTU file ("), got


def test_damaged_bytes_give_a_capture_or_one_line(tmp_path, good):
    rng = np.random.default_rng(41)
    refused = read = 0
    for name, data in good.items():
        end = header_end(data)
        places = np.concatenate([np.linspace(0, end - 1, 120).astype(int),
                                 rng.integers(end, len(data), 20)])
        for place in places:
            damaged = bytearray(data)
            damaged[place] ^= int(rng.integers(1, 256))
            path = tmp_path / f"bad-{place}-{name}"
            path.write_bytes(bytes(damaged))
            got = one_line_or_capture(path)
            if isinstance(got, str):
                refused += 1
            else:
                read += 1
    assert refused > 50 and read > 50         # both outcomes were exercised


def test_more_bytes_than_records_announced_are_not_lost_silently(tmp_path, good):
    data = good["pq.ptu"]
    count = records_announced(data)
    assert count == (len(data) - header_end(data)) // 4
    path = tmp_path / "long.ptu"
    path.write_bytes(data + bytes(4 * 3))       # 3 more records: photons at dtime 0
    got = one_line_or_capture(path)
    assert got.total_histogram().sum() == 200
    assert got.problems == [f"12 bytes after the {count} records its header announces are "
                            f"left out"]


JUNK = b"PQTTTR\0\0" + b"just some text, no tags"


@pytest.mark.parametrize("content, why", [
    (b"", "it is empty"),
    (b"hello\n", "it does not begin with PQTTTR, the mark of a PTU file"),
    (b"PQTTTR\0\0" + b"1.0", "it ends at byte 11, in its header"),
    (JUNK, f"it ends at byte {len(JUNK)}, in its header, before Header_End"),
    (b"PQTTTR\0\x001.0.00\0\0" + b"Foo".ljust(32, b"\0") + struct.pack("<iIq", -1, 0x1234, 0),
     "the tag at byte 16, 'Foo', has no PTU type (0x00001234)"),
    (b"PQTTTR\0\x001.0.00\0\0" + b"Text".ljust(32, b"\0")
     + struct.pack("<iIq", -1, 0x4001FFFF, 1 << 40),
     f"its AnsiString tag 'Text' at byte 16 holds {1 << 40} bytes, past the end of the file "
     f"at byte 64"),
])
def test_files_that_are_not_ptu_files_say_why(tmp_path, capsys, content, why):
    path = tmp_path / "junk.ptu"
    path.write_bytes(content)
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, out, err) == (1, "", f"fliss: error: {path}: not a PTU file ({why})\n")


@pytest.mark.parametrize("changes, why", [
    ({"Measurement_Mode": None}, "its header has no Measurement_Mode"),
    ({"TTResultFormat_BitsPerRecord": 16}, "its records are of 16 bits; T3 records are of 32"),
    ({"MeasDesc_Resolution": 0.0}, "its MeasDesc_Resolution, the width of a TCSPC bin, is 0.0 s"),
    ({"TTResult_NumberOfRecords": "many"}, "its TTResult_NumberOfRecords is 'many', not a "
                                           "whole number"),
    ({"TTResult_NumberOfRecords": 10_000}, "it is cut short: its header announces 10000 "
                                           "records, 40000 bytes, and {} follow it"),
])
def test_headers_that_do_not_describe_t3_records_say_why(tmp_path, capsys, changes, why):
    path = picoquant(tmp_path / "pq.ptu", 200, **changes)
    why = why.format(len(picoquant(tmp_path / "whole.ptu", 200).read_bytes()) - header_end(
        path.read_bytes()))
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, out, err) == (1, "", f"fliss: error: {path}: not a PTU file ({why})\n")


def test_an_unknown_record_type_and_a_mode_other_than_t3_say_so(tmp_path, capsys):
    path = picoquant(tmp_path / "odd.ptu", 10, TTResultFormat_TTTRRecType=0x00010308)
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, err) == (1, f"fliss: error: {path}: not a PTU file fliss reads (its record "
                                f"type, TTResultFormat_TTTRRecType, is 0x00010308: none of the "
                                f"T3 records PicoHarpT3, HydraHarpT3, HydraHarp2T3, "
                                f"TimeHarp260NT3, TimeHarp260PT3, GenericT3)\n")
    path = picoquant(tmp_path / "t1.ptu", 10, Measurement_Mode=1)
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, err) == (1, f"fliss: error: {path}: its Measurement_Mode is 1, not 3 (T3 "
                                f"records); fliss reads T3 files\n")
