"""`fliss analyze` and `fliss plot` of PTU and Photon-HDF5 files made by other programs: the files
are written by ptufile's, tttrlib's and phconvert's own writers (never by fliss's exporter), and
their TCSPC histogram gets the peak table and suppression of a FLISS capture of the same counts.
A file that cannot be read is refused with one line."""

import contextlib
import io
import json
import warnings

import matplotlib.axes
import numpy as np
import phconvert
import ptufile
import pytest
import tttrlib

from fliss.host.cli import main
from fliss.host.formats.ptu_records import header

from format_captures import AGGRESSOR_S, VICTIM_S, histogram_capture, two_echoes


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def analysis(capsys, path):
    """`fliss analyze --json` of one file, told where the victim's and the aggressor's echoes
    are (files of other programs record no FLISS settings to tell): what its analysis found,
    and stderr."""
    status, out, err = fliss(capsys, "analyze", "--json", path, "--victim-tof",
                             f"{VICTIM_S * 1e9}ns", "--aggressor-tof", f"{AGGRESSOR_S * 1e9}ns")
    assert status == 0, err
    record = json.loads(out)[0]
    return {key: record[key] for key in ("bin_s", "counts", "background", "peaks",
                                         "suppression")}, err


def markers_left_out(path):
    """The warning of a PTU file in T3 image mode as ptufile writes one: its frame and line
    markers (one frame of one line) are counted and said to be left out."""
    return (f"fliss: warning: {path}: 3 marker records (markers 1, 2, 4) are not photons and "
            f"are left out\n")


def picoquant_ptu(path, counts, resolution_s, seed=1):
    """A T3 PTU of ``counts`` split over two channels, by ptufile's writer (T3 image mode, one
    pixel), as a two-detector PicoQuant instrument's histogram; the histogram spans the sync
    period."""
    first = np.random.default_rng(seed).binomial(counts, 0.5)
    data = np.zeros((1, 1, 2, len(counts)), dtype=np.uint32)
    data[0, 0, 0], data[0, 0, 1] = first, counts - first
    ptufile.imwrite(path, data, len(counts) * resolution_s, resolution_s, record_type=ptufile.PtuRecordType.GenericT3)


def photons(counts, seed=2):
    """The photons of a histogram in random order: (timestamps, nanotimes, detectors)."""
    rng = np.random.default_rng(seed)
    nanotimes = rng.permutation(np.repeat(np.arange(len(counts)), counts)).astype(np.uint16)
    timestamps = np.sort(rng.integers(0, 50_000_000, len(nanotimes)))
    return timestamps, nanotimes, rng.integers(0, 2, len(nanotimes)).astype(np.uint8)


def phconvert_file(path, counts, resolution_s, *, lifetime=True):
    """A Photon-HDF5 file of ``counts`` (two detectors, 50 MHz clock) by phconvert's writer."""
    timestamps, nanotimes, detectors = photons(counts)
    data = {"timestamps": timestamps, "detectors": detectors,
            "timestamps_specs": {"timestamps_unit": 20e-9}}
    specs = {"measurement_type": "generic",
             "detectors_specs": {"spectral_ch1": np.array([0, 1], dtype=np.uint8)}}
    if lifetime:
        data["nanotimes"] = nanotimes
        data["nanotimes_specs"] = {"tcspc_unit": resolution_s, "tcspc_num_bins": len(counts)}
        specs["laser_repetition_rate"] = 1e6
    data["measurement_specs"] = specs
    setup = {"num_pixels": 2, "num_spots": 1, "num_spectral_ch": 1, "num_polarization_ch": 1,
             "num_split_ch": 1, "modulated_excitation": False, "excitation_alternated": [False],
             "lifetime": lifetime, "excitation_cw": [not lifetime]}
    if lifetime:
        setup["laser_repetition_rates"] = [1e6]
    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        phconvert.hdf5.save_photon_hdf5({"description": "two detectors", "photon_data": data,
                                         "setup": setup}, h5_fname=str(path), overwrite=True)


def tttrlib_ptu(path, counts, resolution_s):
    """A PTU of HydraHarp 2 T3 records, by tttrlib's writer."""
    timestamps, nanotimes, detectors = photons(counts)
    tttr = tttrlib.TTTR()
    tttr.append_events(timestamps.astype(np.uint64), nanotimes, detectors.astype(np.int8),
                       np.zeros(len(timestamps), dtype=np.int8), False, 0)
    tags = [("Measurement_Mode", 0x10000008, 3), ("Measurement_SubMode", 0x10000008, 1),
            ("MeasDesc_GlobalResolution", 0x20000008, len(counts) * resolution_s),
            ("MeasDesc_Resolution", 0x20000008, resolution_s),
            ("TTResult_SyncRate", 0x10000008, 1_000_000),
            ("TTResultFormat_TTTRRecType", 0x10000008, ptufile.PtuRecordType.HydraHarp2T3.value),
            ("TTResultFormat_BitsPerRecord", 0x10000008, 32), ("Header_End", 0xFFFF0008, None)]
    head = tttrlib.TTTRHeader(0)
    head.set_json(json.dumps({"MeasDesc_ContainerType": 0, "MeasDesc_RecordType": 4,
                              "Tag Version": "1.0.00",
                              "tags": [{"idx": -1, "name": name, "type": kind, "value": value}
                                       for name, kind, value in tags]}))
    head.tttr_record_type = 4                   # tttrlib's HydraHarp 2 T3
    assert tttr.write(str(path), head)


@pytest.fixture
def reference(tmp_path, capsys):
    """The counts of two echoes at 50 ps and the analysis of a FLISS capture of them."""
    counts = two_echoes(0)
    histogram_capture(tmp_path / "c.h5", [counts], shift=0, configuration=dict(aggressor=1))
    result, err = analysis(capsys, tmp_path / "c.h5")
    assert err == ""
    # The analysis finds the echoes where they were put, and their ratio of 2 (3 dB).
    tofs = sorted(peak["tof_s"] for peak in result["peaks"])
    assert tofs == pytest.approx([VICTIM_S, AGGRESSOR_S], abs=0.1e-9)
    assert [peak["role"] for peak in result["peaks"]] == ["victim", "aggressor"]
    assert result["suppression"]["value_db"] == pytest.approx(3.0, abs=0.5)
    assert result["suppression"]["bound"] == "equal"
    return counts, result


def test_ptu_files_of_other_writers_get_the_analysis_of_a_capture(tmp_path, capsys, reference):
    counts, expected = reference
    picoquant_ptu(tmp_path / "pq.ptu", counts, 50e-12)
    assert analysis(capsys, tmp_path / "pq.ptu") == (expected, markers_left_out(tmp_path / "pq.ptu"))
    tttrlib_ptu(tmp_path / "tl.ptu", counts, 50e-12)
    got, err = analysis(capsys, tmp_path / "tl.ptu")
    assert got == expected
    # tttrlib's header is one ptufile complains of (its tags are not 8-byte aligned): one line.
    assert len(err.splitlines()) <= 1
    assert err == "" or err.startswith(f"fliss: warning: {tmp_path / 'tl.ptu'}: ptufile: ")


def test_photon_hdf5_files_get_the_analysis_of_a_capture(tmp_path, capsys, reference):
    counts, expected = reference
    phconvert_file(tmp_path / "p.hdf5", counts, 50e-12)
    assert analysis(capsys, tmp_path / "p.hdf5") == (expected, "")


def test_a_histogram_of_wider_bins_is_analysed_as_a_capture_of_that_bin_width(tmp_path, capsys):
    counts = two_echoes(3)                                   # 400 ps bins
    histogram_capture(tmp_path / "c.h5", [counts], shift=3)
    expected, _ = analysis(capsys, tmp_path / "c.h5")
    assert expected["bin_s"] == pytest.approx(400e-12)
    picoquant_ptu(tmp_path / "pq.ptu", counts, 400e-12)
    phconvert_file(tmp_path / "p.hdf5", counts, 400e-12)
    assert analysis(capsys, tmp_path / "pq.ptu") == (expected, markers_left_out(tmp_path / "pq.ptu"))
    assert analysis(capsys, tmp_path / "p.hdf5") == (expected, "")


def test_plot_draws_the_histograms_of_other_programs_files(tmp_path, capsys, monkeypatch,
                                                           reference):
    counts, _ = reference
    picoquant_ptu(tmp_path / "pq.ptu", counts, 50e-12)
    phconvert_file(tmp_path / "p.hdf5", counts, 50e-12)
    drawn = []
    step = matplotlib.axes.Axes.step

    def recording_step(self, x, y, *args, **kwargs):
        drawn.append((np.asarray(x), np.asarray(y)))
        return step(self, x, y, *args, **kwargs)

    monkeypatch.setattr(matplotlib.axes.Axes, "step", recording_step)
    status, out, err = fliss(capsys, "plot", tmp_path / "c.h5", tmp_path / "pq.ptu",
                             tmp_path / "p.hdf5", "-o", tmp_path / "p.png")
    assert (status, err) == (0, markers_left_out(tmp_path / "pq.ptu"))
    assert (tmp_path / "p.png").stat().st_size > 0
    times_ns = (np.arange(8192) + 0.5) * 0.05
    assert len(drawn) == 3
    for x, y in drawn:
        np.testing.assert_allclose(x, times_ns)
        np.testing.assert_array_equal(y, counts)


def refused(capsys, path):
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, out) == (1, "")
    assert len(err.splitlines()) == 1
    return err


def test_files_that_cannot_be_read_get_one_line(tmp_path, capsys, reference):
    counts, _ = reference
    picoquant_ptu(tmp_path / "pq.ptu", counts, 50e-12)
    (tmp_path / "cut.ptu").write_bytes((tmp_path / "pq.ptu").read_bytes()[:200])
    assert refused(capsys, tmp_path / "cut.ptu") == (
        f"fliss: error: {tmp_path / 'cut.ptu'}: not a PTU file (it ends at byte 200, in its "
        f"header, before Header_End)\n")
    (tmp_path / "t2.ptu").write_bytes(header({
        "Measurement_Mode": 2, "Measurement_SubMode": 0, "MeasDesc_Resolution": 5e-12,
        "MeasDesc_GlobalResolution": 5e-12, "TTResult_SyncRate": 1_000_000,
        "TTResult_NumberOfRecords": 1,
        "TTResultFormat_TTTRRecType": ptufile.PtuRecordType.HydraHarp2T2.value,
        "TTResultFormat_BitsPerRecord": 32}) + b"\x00\x00\x00\x02")
    assert refused(capsys, tmp_path / "t2.ptu") == (
        f"fliss: error: {tmp_path / 't2.ptu'}: a T2 PTU file (time tags without a laser sync) "
        f"holds no TCSPC histogram; fliss reads T3 files\n")
    (tmp_path / "h.phu").write_bytes(b"PQHISTO\0" + bytes(64))
    assert refused(capsys, tmp_path / "h.phu") == (
        f"fliss: error: {tmp_path / 'h.phu'}: a PicoQuant histogram (PHU) file; fliss reads "
        f"PTU files (T3 records), HT3, PT3 and SPC files, Photon-HDF5 files and FLISS capture "
        f"files\n")
    phconvert_file(tmp_path / "cw.hdf5", counts, 50e-12, lifetime=False)
    assert refused(capsys, tmp_path / "cw.hdf5") == (
        f"fliss: error: {tmp_path / 'cw.hdf5'}: /photon_data has no nanotimes (not a TCSPC "
        f"measurement): there is no histogram to analyse\n")
    status, out, err = fliss(capsys, "plot", tmp_path / "cw.hdf5", "-o", tmp_path / "x.png")
    assert (status, out) == (1, "") and err == refused(capsys, tmp_path / "cw.hdf5")
