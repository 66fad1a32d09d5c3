"""Real recordings of other TCSPC instruments (tests/host/data/tttr/README.md says where each
comes from) read by fliss event for event as a second, independent decoder reads them: phconvert
(HT3 1.0, PicoHarp T3 records, SPC), libpicoquant's ``picoquant`` program (its dumps beside the
HT3 files), PicoQuant's documented record layout (PicoHarp T3 records, whose markers phconvert
and tttrlib 0.26 get wrong), ptufile (PTU files fliss exports from them). Their markers and overflow records are
counted as the words of the file, decoded after PicoQuant's documented layout, count them; what
cannot map is refused in one line; an HT3 file converts to Photon-HDF5 and PTU."""

import contextlib
import io
import json
import os
import shutil
import struct
import urllib.request
import warnings
from pathlib import Path

import h5py
import numpy as np
import ptufile
import pytest
import tttrlib
from phconvert import bhreader, pqreader

from fliss.host.cli import main
from fliss.host.errors import FormatError
from fliss.host.formats import read_file
from fliss.host.formats.ht3_header import read_ht3_header
from fliss.host.formats.ptu_header import read_header
from fliss.host.formats.tttr_foreign import foreign_kind, read_recording, to_capture

DATA = Path(__file__).parent / "data" / "tttr"


def recording(path):
    path = Path(path)
    kind = foreign_kind(path, path.read_bytes()[:16])
    return read_recording(path, kind, read_header(path) if kind == "ptu" else None)


def photons(sync, micro, channel):
    return (np.asarray(sync, dtype=np.int64), np.asarray(micro, dtype=np.int64),
            np.asarray(channel, dtype=np.int64))


# Second decoders, each giving (sync, micro, channel) of the photons.

def phconvert_ht3(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sync, detector, micro, *_ = pqreader.load_ht3(str(path))
    photon = detector < 64                  # (64 and up: markers; 127 the overflows)
    return photons(sync[photon], micro[photon], detector[photon])


def picoharp_records(path):
    header = read_header(path)
    count = header.tags["TTResult_NumberOfRecords"]
    return np.fromfile(path, dtype="<u4", count=count, offset=header.data_offset)


def picoharp_layout(words):
    """PicoHarp T3 records decoded after PicoQuant's documented layout, as their demo programs
    decode them: bits 28-31 the channel (1 to 4 a photon's, 15 a special record), 16-27 the
    micro time (of a special record: 0 an overflow of 65536 syncs, else the marker bits), 0-15
    the sync count. Channels counted from 0, as ptufile counts them."""
    channel, micro, nsync = words >> 28, (words >> 16) & 0xFFF, (words & 0xFFFF).astype(np.int64)
    special = channel == 15
    overflow = special & (micro == 0)
    sync = nsync + 65536 * np.cumsum(overflow)
    photon = ~special
    return photons(sync[photon], micro[photon], channel[photon].astype(np.int64) - 1)


def phconvert_picoharp(path):
    """PicoHarp T3 records (of a PTU file) by phconvert's decoder of them (its PT3 reader's),
    which counts each marker record as an overflow too: its sync counts are taken back by
    65536 for each marker before the photon, and must then be the layout's."""
    words = picoharp_records(path)
    detector, sync, micro, _ = pqreader.process_t3records(
        words, time_bit=16, dtime_bit=12, ch_bit=4, special_bit=False)
    photon = detector < 15                  # (15: overflows; markers moved to 16 and up)
    markers = np.cumsum(((words >> 28) == 15) & (((words >> 16) & 0xFFF) != 0))
    return photons(sync[photon].astype(np.int64) - 65536 * markers[photon], micro[photon],
                   detector[photon].astype(np.int64) - 1)


def phconvert_pt3(path):
    """A PT3 file by phconvert's reader (right on files without markers)."""
    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("ignore")
        sync, detector, micro, *_ = pqreader.load_pt3(str(path))
        words = pqreader.pt3_reader(str(path))[0]
    assert not np.any(((words >> 28) == 15) & (((words >> 16) & 0xFFF) != 0))  # no markers
    photon = detector < 15
    return photons(sync[photon], micro[photon], detector[photon].astype(np.int64) - 1)


def phconvert_spc(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = bhreader.load_spc(str(path), str(Path(path).with_suffix(".set")))["photon_data"]
    photon = ~np.isin(data["detectors"], data["marker_ids"])
    return photons(data["timestamps"][photon], data["nanotimes"][photon],
                   data["detectors"][photon])


def tttrlib_events(path, container):
    """tttrlib's photons (HT3 and SPC files: it misreads PicoHarp markers, see
    docs/file-format.md)."""
    with contextlib.redirect_stdout(io.StringIO()):
        tttr = tttrlib.TTTR(str(path), container)
    photon = np.asarray(tttr.event_types) == 0
    return photons(np.asarray(tttr.macro_times)[photon], np.asarray(tttr.micro_times)[photon],
                   np.asarray(tttr.routing_channels)[photon])


def picoquant_dump(path, resolution_ps):
    """libpicoquant's decoding (lines "channel,sync,time in ps") of the first photons."""
    rows = [line.split(",") for line in Path(f"{path}.data").read_text().splitlines()]
    rows = np.array([[int(v) for v in row] for row in rows if len(row) == 3])
    assert np.all(rows[:, 2] % resolution_ps == 0)
    return photons(rows[:, 1], rows[:, 2] // resolution_ps, rows[:, 0])


SAMPLES = [("hydraharp_v10.ht3", phconvert_ht3), ("rh110_sm.ht3", phconvert_ht3),
           ("hazelnut_z1.ptu", phconvert_picoharp),
           ("hazelnut_z1.ptu", lambda path: picoharp_layout(picoharp_records(path))),
           ("test_noise.spc", phconvert_spc),
           ("test_noise.spc", lambda path: tttrlib_events(path, "SPC-130")),
           ("rh110_sm.ht3", lambda path: tttrlib_events(path, "HT3")),
           ("hydraharp_v20.ht3", lambda path: tttrlib_events(path, "HT3")),
           ("hydraharp_v10.ht3", lambda path: picoquant_dump(path, 4)),
           ("hydraharp_v20.ht3", lambda path: picoquant_dump(path, 16))]


def assert_same_photons(got, expected, first=None):
    n = len(expected[0]) if first is None else first
    assert n > 0 and len(got.sync) >= n
    for ours, theirs in zip(photons(got.sync, got.micro, got.channel), expected):
        np.testing.assert_array_equal(ours[:n], theirs[:n])
    if first is None:
        assert len(got.sync) == len(expected[0])


@pytest.mark.parametrize("name, second", SAMPLES)
def test_real_recordings_read_event_for_event_as_a_second_decoder_reads_them(name, second):
    got = recording(DATA / name)
    expected = second(DATA / name)
    # The dumps hold every photon of v10.ht3, the first 100 of v20.ht3.
    first = len(expected[0]) if name == "hydraharp_v20.ht3" else None
    assert_same_photons(got, expected, first)


def hydraharp_words(path, data_offset):
    words = np.fromfile(path, dtype="<u4", offset=data_offset)
    special, channel = words >> 31, (words >> 25) & 63
    return int(np.count_nonzero(special == 0)), int(np.count_nonzero(special & (channel == 63))), \
        int(np.count_nonzero(special & (channel > 0) & (channel < 16)))


def test_markers_and_overflow_records_are_counted_as_the_files_words_count_them():
    # HT3: a 32-bit word a record, bit 31 special, bits 25-30 the channel (63: an overflow,
    # 1-15: markers); PicoHarp T3: bits 28-31 the channel (15: special), bits 16-27 the
    # micro time (0 for an overflow, else the markers).
    for name in ("rh110_sm.ht3", "hydraharp_v20.ht3"):
        got = recording(DATA / name)
        photon_count, overflows, markers = hydraharp_words(DATA / name, 880 if "rh110" in
                                                           name else 800)
        assert (len(got.sync), got.overflows, got.markers) == (photon_count, overflows, markers)
        assert overflows > 0
    words = picoharp_records(DATA / "hazelnut_z1.ptu")
    special = (words >> 28) == 15
    marks = special & (((words >> 16) & 0xFFF) != 0)
    got = recording(DATA / "hazelnut_z1.ptu")
    assert (len(got.sync), got.markers, got.overflows) == (
        np.count_nonzero(~special), np.count_nonzero(marks), np.count_nonzero(special & ~marks))
    assert got.markers > 0 and got.records == 5000


def test_a_recording_maps_to_a_raw_capture_of_its_photons():
    got = recording(DATA / "rh110_sm.ht3")
    capture = to_capture(got)
    # Micro times of 1 ps up to 31256 need 15 bits: divided by 4 into 13-bit codes of 4 ps.
    assert int(got.micro.max()).bit_length() == 15 and got.width_s == pytest.approx(1e-12)
    assert capture.code_s == pytest.approx(4e-12) and capture.bin_s == pytest.approx(4e-12)
    np.testing.assert_array_equal(capture.events["timestamp"], got.micro // 4)
    np.testing.assert_array_equal(capture.events["pulse"], got.sync % (1 << 32))
    np.testing.assert_array_equal(capture.events["address"], got.channel)
    assert capture.mode == "raw" and capture.period_s == pytest.approx(got.period_s)
    assert any("divided by 4" in problem for problem in capture.problems)
    # The sync period of rh110 (32 MHz) holds 7812 codes of 4 ps: the histogram's bins.
    assert len(capture.total_histogram()) == round(got.period_s / 4e-12)
    assert capture.total_histogram().sum() == len(got.sync)
    ptu = to_capture(recording(DATA / "hazelnut_z1.ptu"))
    # (the first 5000 records hold line markers, 1 and 2, and no frame marker, 4)
    assert ptu.problems == [f"{ptu.counters['records']['markers']} marker records (markers 1, "
                            f"2) are not photons and are left out"]


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def refused(capsys, path):
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, out) == (1, "") and len(err.splitlines()) == 1, err
    return err


def test_what_cannot_map_is_refused_in_one_line(tmp_path, capsys):
    path = DATA / "hydraharp_v10.ht2"
    assert refused(capsys, path) == (f"fliss: error: {path}: a T2 HT3 file (time tags without "
                                     f"a laser sync) holds no TCSPC histogram; fliss reads T3 "
                                     f"files\n")
    alone = tmp_path / "alone.spc"
    shutil.copy(DATA / "test_noise.spc", alone)
    assert refused(capsys, alone) == (
        f"fliss: error: {alone}: a Becker & Hickl SPC file does not hold the width of its "
        f"micro-time channels; its .set file ({tmp_path / 'alone'}.set), which does, is not "
        f"beside it\n")
    (tmp_path / "junk.ht3").write_bytes(b"not a recording at all")
    assert refused(capsys, tmp_path / "junk.ht3") == (
        f"fliss: error: {tmp_path / 'junk.ht3'}: not an HT3 file (it does not begin with "
        f"HydraHarp, the mark of one)\n")


def test_photons_an_spc_module_lost_are_not_lost_silently(tmp_path):
    # B&H's record: bit 29 the GAP flag, set where the FIFO overflowed and photons were lost.
    data = bytearray((DATA / "test_noise.spc").read_bytes())
    words = np.frombuffer(bytes(data[4:]), dtype="<u4").copy()
    photon = np.flatnonzero((words >> 30) == 0)[[10, 20]]
    words[photon] |= np.uint32(1 << 29)
    (tmp_path / "gap.spc").write_bytes(bytes(data[:4]) + words.tobytes())
    shutil.copy(DATA / "test_noise.set", tmp_path / "gap.set")
    got = recording(tmp_path / "gap.spc")
    assert got.problems == ["2 records carry the GAP flag: the module's FIFO overflowed there "
                            "and the photons it could not hold were lost in the recording"]
    assert recording(DATA / "test_noise.spc").problems == []


def test_an_ht3_file_converts_to_photon_hdf5_and_ptu(tmp_path, capsys):
    source = DATA / "hydraharp_v20.ht3"
    got = recording(source)
    codes = got.micro >> 2                  # (15-bit micro times of 16 ps: codes of 64 ps)
    status, out, err = fliss(capsys, "export", source, "--to", "photon-hdf5", "-o",
                             tmp_path / "v20.hdf5")
    assert status == 0, err
    with h5py.File(tmp_path / "v20.hdf5", "r") as f:
        data = f["photon_data"]
        np.testing.assert_array_equal(data["timestamps"][()], got.sync)
        np.testing.assert_array_equal(data["nanotimes"][()], codes)
        np.testing.assert_array_equal(data["detectors"][()], got.channel)
        assert data["timestamps_specs/timestamps_unit"][()] == pytest.approx(got.period_s)
        assert data["nanotimes_specs/tcspc_unit"][()] == pytest.approx(4 * got.width_s)
    status, out, err = fliss(capsys, "export", source, "--to", "ptu", "-o", tmp_path / "v20.ptu")
    assert status == 0, err
    with ptufile.PtuFile(tmp_path / "v20.ptu") as ptu:
        records = ptu.decode_records()
        assert ptu.tcspc_resolution == pytest.approx(4 * got.width_s)
    photon = records["channel"] >= 0
    assert_same_photons(recording(tmp_path / "v20.ptu"),
                        photons(records["time"][photon], records["dtime"][photon],
                                records["channel"][photon]))
    np.testing.assert_array_equal(records["time"][photon], got.sync)
    np.testing.assert_array_equal(records["dtime"][photon], codes)


# The whole recordings the samples were cut from, and more of their sets: (name, repository,
# commit, path in it, second decoder).
_RAW = "https://raw.githubusercontent.com"
FULL = [
    ("v10.ht3", "tsbischof/libpicoquant", "62659bb273eb484bf663f7605d303c8f4711bd21",
     "sample_data/hydraharp/v10.ht3", phconvert_ht3),
    ("v20.ht3", "tsbischof/libpicoquant", "62659bb273eb484bf663f7605d303c8f4711bd21",
     "sample_data/hydraharp/v20.ht3", None),
    ("Split_rh110 sm-000000.ht3", "Fluorescence-Tools/tttrlib",
     "08f770821ae028a3c309d4fe5917bebfb25a1cb9", "examples/PQ/HT3/Split_rh110 sm-000000.ht3",
     phconvert_ht3),
] + [(f"ptu_stack_FLIM_z{z}.ptu", "zoccoler/napari-flim-phasor-plotter", commit,
      f"src/napari_flim_phasor_plotter/data/hazelnut_FLIM_z_stack/ptu_stack_FLIM_z{z}.ptu",
      lambda path: picoharp_layout(picoharp_records(path)))
     for z, commit in ((1, "92105a5c3eb34ebb45c422e056416f44057cb946"),
                       (2, "92105a5c3eb34ebb45c422e056416f44057cb946"),
                       (10, "a1825ebd209437ffa67ccfd6f3fc60d6e6b89f1f"),
                       (11, "9a0777384142ebce6dcb096592b8a335f39528b0"))] + [
    ("test_noise.spc", "Photon-HDF5/phconvert", "a46246a3b9bdf680204ffe88663059605034db2b",
     "tests/test_files/test_noise.spc", phconvert_spc),
    # (GPL-2.0, so not kept in this repository: PicoHarp 300, FCS of TopFluor PE)
    ("topfluorPE_2_1_1_1.pt3", "dwaithe/FCS_point_correlator",
     "6332ad845ea0ec693179bb6e29535fe61e335499", "topfluorPE_2_1_1_1.pt3", phconvert_pt3),
]


def whole(name, repository, commit, path, folder):
    """The file ``name`` from FLISS_TTTR_SAMPLES, or fetched from GitHub into ``folder``;
    skipped, saying why, when it cannot be had."""
    given = os.environ.get("FLISS_TTTR_SAMPLES")
    if given:
        if not (Path(given) / name).is_file():
            pytest.skip(f"{name} is not in FLISS_TTTR_SAMPLES ({given})")
        return Path(given) / name
    target = folder / name
    try:
        for suffix in ((".spc", ".set") if name.endswith(".spc") else (Path(name).suffix,)):
            url = f"{_RAW}/{repository}/{commit}/{path[:-4]}{suffix}".replace(" ", "%20")
            with urllib.request.urlopen(url, timeout=20) as response:
                target.with_suffix(suffix).write_bytes(response.read())
    except OSError as error:
        pytest.skip(f"offline: {name} cannot be fetched from GitHub ({error})")
    return target


@pytest.mark.parametrize("name, repository, commit, path, second", FULL,
                         ids=[entry[0] for entry in FULL])
def test_whole_public_recordings_read_event_for_event(tmp_path, name, repository, commit, path,
                                                      second):
    file = whole(name, repository, commit, path, tmp_path)
    got = recording(file)
    if name.endswith(".pt3"):               # (and PicoQuant's layout, on the same records)
        with contextlib.redirect_stdout(io.StringIO()):
            assert_same_photons(got, picoharp_layout(pqreader.pt3_reader(str(file))[0]))
    if second is None:                      # (HT3 2.0: libpicoquant's dump of its start)
        assert_same_photons(got, picoquant_dump(DATA / "hydraharp_v20.ht3", 16),
                            first=100)
        assert len(got.sync) == 44141
    else:
        assert_same_photons(got, second(file))
    capture = to_capture(got)
    assert capture.total_histogram().sum() == len(got.sync)


def pt3_file(path, words, *, mode=3, sync_hz=78_020_000, resolution_ns=0.0969697):
    """A PT3 file (PicoHarp 300, format 2.0) of the T3 ``words``: its header after PicoQuant's
    documented layout, 728 bytes (text fields, then int32 and float32 fields; the measurement
    mode at byte 348, the resolution in ns at 584, the sync rate at 704, the number of records
    at 720, no imaging header). No public PT3 recording was found: the records are real ones,
    the PicoHarp T3 records of hazelnut_z1.ptu."""
    head = bytearray(728)
    head[0:16] = b"PicoHarp 300".ljust(16, b"\0")
    head[16:22] = b"2.0".ljust(6, b"\0")
    struct.pack_into("<i", head, 332, 32)                       # bits per record
    struct.pack_into("<i", head, 348, mode)
    struct.pack_into("<f", head, 584, resolution_ns)
    struct.pack_into("<i", head, 704, sync_hz)
    struct.pack_into("<i", head, 720, len(words))
    path.write_bytes(bytes(head) + words.astype("<u4").tobytes())
    return path


def test_pt3_files_read_event_for_event_and_t2_ones_are_refused(tmp_path, capsys):
    words = picoharp_records(DATA / "hazelnut_z1.ptu")
    got = recording(pt3_file(tmp_path / "z1.pt3", words))
    assert_same_photons(got, picoharp_layout(words))
    assert got.period_s == pytest.approx(1 / 78_020_000)
    assert got.width_s == pytest.approx(96.9697e-12, rel=1e-6)
    ptu = recording(DATA / "hazelnut_z1.ptu")
    assert (got.records, got.markers, got.overflows) == (ptu.records, ptu.markers, ptu.overflows)
    t2 = pt3_file(tmp_path / "t2.pt3", words, mode=2)
    assert refused(capsys, t2) == (f"fliss: error: {t2}: a T2 PT3 file (time tags without a "
                                   f"laser sync) holds no TCSPC histogram; fliss reads T3 "
                                   f"files\n")


@pytest.mark.parametrize("name", ["hydraharp_v10.ht3", "hydraharp_v20.ht3", "rh110_sm.ht3"])
def test_ht3_headers_read_as_tttrlib_reads_them(name):
    header = read_ht3_header(DATA / name)
    with contextlib.redirect_stdout(io.StringIO()):
        tttr = tttrlib.TTTR(str(DATA / name), "HT3")
    tags = {tag["name"]: tag["value"] for tag in json.loads(tttr.header.json)["tags"]}
    assert (header.version, header.mode, header.sync_hz, header.announced) == (
        tags["FormatVersion"], tags["MeasurementMode"], tags["SyncRate"], tags["nRecords"])
    assert header.resolution_s == pytest.approx(tttr.header.micro_time_resolution)
    assert header.data_offset == tttr.header.end()
    assert header.records == tttr.n_records_in_file


def one_line_or_capture(path):
    try:
        return read_file(path)
    except FormatError as error:
        message = str(error)
        assert "\n" not in message and message.startswith(f"{path}"), message
        return message


def test_cut_and_damaged_recordings_are_read_or_refused_in_one_line(tmp_path):
    good = (DATA / "hydraharp_v10.ht3").read_bytes()
    for cut in range(0, 800, 7):            # (tttrlib, handed these, reads past the end)
        path = tmp_path / f"cut{cut}.ht3"
        path.write_bytes(good[:cut])
        assert isinstance(one_line_or_capture(path), str), cut
    shutil.copy(DATA / "test_noise.set", tmp_path / "s.set")
    spc = (DATA / "test_noise.spc").read_bytes()
    rng = np.random.default_rng(3)
    outcomes = []
    for name, data in [("d.ht3", good)] * 150 + [("s.spc", spc)] * 100:
        damaged = bytearray(data)
        damaged[int(rng.integers(0, len(data)))] = int(rng.integers(0, 256))
        (tmp_path / name).write_bytes(bytes(damaged))
        outcomes.append(isinstance(one_line_or_capture(tmp_path / name), str))
    assert 0 < sum(outcomes) < len(outcomes)    # both outcomes were exercised
