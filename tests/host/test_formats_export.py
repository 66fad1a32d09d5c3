"""`fliss export`: captures written as PTU (ptufile; the events by fliss's own T3 writer) and as
Photon-HDF5 (phconvert), read back by those libraries and by tttrlib, an independent second
reader, every event and every count compared with the capture's."""

import json

import numpy as np
import phconvert
import ptufile
import pytest
import tttrlib

from fliss.host.cli import main
from fliss.host.errors import FormatError
from fliss.host.formats import export_capture, read_file

from format_captures import (CLOCK_HZ, LSB_S, VICTIM_S, depth_capture, histogram_capture,
                             image_capture, raw_capture, two_echoes)


PERIOD_S = 1e-6                     # the default period: 80 cycles of 80 MHz


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def photons_of(path):
    """ptufile's decoding of a PTU file's photon records: (sync count, dtime, channel)."""
    with ptufile.PtuFile(path) as ptu:
        records = ptu.decode_records()
        tags = ptu.tags
    photons = records[records["channel"] >= 0]
    return photons["time"].astype(np.int64), photons["dtime"], photons["channel"], tags


def test_raw_capture_to_ptu_reads_back_in_ptufile_and_tttrlib(tmp_path, capsys):
    capture, cycles = raw_capture(tmp_path / "r.h5", configuration=dict(delay_mode=1, length=7,
                                                                        seed=0x2B))
    status, out, err = fliss(capsys, "export", tmp_path / "r.h5", "--to", "ptu",
                             "-o", tmp_path / "r.ptu")
    assert status == 0 and err == ""
    assert out.startswith(f"wrote {tmp_path / 'r.ptu'}: PTU (PicoQuant), ")
    events = capture.events
    sync, dtime, channel, tags = photons_of(tmp_path / "r.ptu")
    np.testing.assert_array_equal(sync, cycles)             # the laser cycle, unwrapped
    np.testing.assert_array_equal(dtime, events["timestamp"])
    np.testing.assert_array_equal(channel, events["address"])
    tttr = tttrlib.TTTR(str(tmp_path / "r.ptu"))
    assert tttr.get_n_valid_events() == len(events)
    np.testing.assert_array_equal(tttr.macro_times.astype(np.int64), cycles)
    np.testing.assert_array_equal(tttr.micro_times, events["timestamp"])
    np.testing.assert_array_equal(tttr.routing_channels, events["address"])
    assert tttr.get_header().macro_time_resolution == pytest.approx(PERIOD_S)
    assert tttr.get_header().micro_time_resolution == pytest.approx(LSB_S)
    # The record type and the settings in the PTU's own tags.
    assert tags["TTResultFormat_TTTRRecType"] == ptufile.PtuRecordType.GenericT3
    assert (tags["Measurement_Mode"], tags["Measurement_SubMode"]) == (3, 1)
    assert tags["MeasDesc_GlobalResolution"] == pytest.approx(PERIOD_S)
    assert tags["MeasDesc_Resolution"] == pytest.approx(LSB_S)
    assert tags["TTResult_SyncRate"] == 1_000_000
    assert tags["TTResult_NumberOfRecords"] == (tmp_path / "r.ptu").stat().st_size // 4 - \
        _header_words(tmp_path / "r.ptu")
    assert (tags["FLISS_mode"], tags["FLISS_delay_mode"], tags["FLISS_length"],
            tags["FLISS_seed"]) == ("raw", "mseq", 7, 0x2B)
    assert tags["FLISS_prf_hz"] == pytest.approx(1e6)
    assert "FLISS_mask_width" not in tags and "FLISS_iv" not in tags


def _header_words(path):
    data = path.read_bytes()
    return (data.index(b"Header_End") + 48) // 4


def test_raw_capture_to_photon_hdf5_reads_back_in_phconvert_and_tttrlib(tmp_path, capsys):
    capture, cycles = raw_capture(tmp_path / "r.h5", configuration=dict(
        delay_mode=3, mask_width=5, iv0=0x11111111, iv1=0x22222222, iv2=0x3333))
    status, out, err = fliss(capsys, "export", tmp_path / "r.h5", "--to", "photon-hdf5",
                             "-o", tmp_path / "r.hdf5")
    assert status == 0 and err == ""
    assert out.startswith(f"wrote {tmp_path / 'r.hdf5'}: Photon-HDF5, 5000 photons, ")
    events = capture.events
    h5 = phconvert.hdf5.load_photon_hdf5(str(tmp_path / "r.hdf5"), warnings=False)
    try:
        data, setup, user = h5.root.photon_data, h5.root.setup, h5.root.user.fliss
        np.testing.assert_array_equal(data.timestamps.read(), cycles)
        np.testing.assert_array_equal(data.nanotimes.read(), events["timestamp"])
        np.testing.assert_array_equal(data.detectors.read(), events["address"])
        np.testing.assert_array_equal(user.collision.read(), events["collision"])
        assert data.timestamps_specs.timestamps_unit.read() == pytest.approx(PERIOD_S)
        assert data.nanotimes_specs.tcspc_unit.read() == pytest.approx(LSB_S)
        assert data.nanotimes_specs.tcspc_num_bins.read() == 8192
        assert list(setup.laser_repetition_rates.read()) == pytest.approx([1e6])
        assert data.measurement_specs.laser_repetition_rate.read() == pytest.approx(1e6)
        assert user.delay_mode.read().decode() == "keyed"
        assert user.mask_width.read() == 5
        assert user.iv.read().decode() == "0x33332222222211111111"
        assert "seed" not in user and "length" not in user
    finally:
        h5.close()
    tttr = tttrlib.TTTR(str(tmp_path / "r.hdf5"), "PHOTON-HDF5")
    assert tttr.get_n_valid_events() == len(events)
    np.testing.assert_array_equal(tttr.macro_times.astype(np.int64), cycles)
    np.testing.assert_array_equal(tttr.micro_times, events["timestamp"])
    np.testing.assert_array_equal(tttr.routing_channels, events["address"])


def test_the_key_is_never_written(tmp_path):
    capture, _ = raw_capture(tmp_path / "r.h5", configuration=dict(delay_mode=3))
    key = {"key0": 0x5EC2E7AA, "key1": 0x5EC2E7BB, "key2": 0x5EC2}
    capture.configuration.update(key)           # as if a file held it
    for to, name in (("ptu", "k.ptu"), ("photon-hdf5", "k.hdf5")):
        export_capture(capture, tmp_path / name, to)
        data = (tmp_path / name).read_bytes()
        for register, value in key.items():
            assert register.encode() not in data
            assert str(value).encode() not in data
            assert value.to_bytes(4, "little") not in data


def test_histogram_capture_to_ptu_t3_image(tmp_path):
    rows = np.array([two_echoes(1, seed=s) for s in range(4)])
    capture = histogram_capture(tmp_path / "h.h5", rows, shift=1, incomplete=(2,),
                                configuration=dict(delay_mode=2, mask_width=6, seed=9))
    records = export_capture(capture, tmp_path / "h.ptu", "ptu")
    with ptufile.PtuFile(tmp_path / "h.ptu") as ptu:
        assert ptu.number_records == records
        assert ptu.shape[:4] == (4, 1, 1, 1) and ptu.dims == ("T", "Y", "X", "C", "H")
        counts = ptu.decode_image(dtype=np.uint32, dtime=4096)
        tags = ptu.tags
    np.testing.assert_array_equal(counts[:, 0, 0, 0, :], rows)
    assert tags["TTResultFormat_TTTRRecType"] == ptufile.PtuRecordType.GenericT3
    assert tags["Measurement_SubMode"] == 3                        # image
    assert tags["MeasDesc_Resolution"] == pytest.approx(100e-12)   # 2 codes of 50 ps
    assert tags["MeasDesc_GlobalResolution"] == pytest.approx(PERIOD_S)
    assert (tags["FLISS_delay_mode"], tags["FLISS_mask_width"], tags["FLISS_seed"]) == \
        ("masked", 6, 9)
    assert json.loads(tags["FLISS_incomplete_rows"]) == [2]
    assert tags["FLISS_first_frame"] == 10
    np.testing.assert_array_equal(_tttrlib_image(tmp_path / "h.ptu", 4096)[:, 0, 0], rows)


def _tttrlib_image(path, bins):
    """tttrlib's reading of a T3 image PTU: (frames, lines, pixels, bins), the photons of
    each pixel as tttrlib's CLSMImage assigns them, histogrammed by micro time."""
    tttr = tttrlib.TTTR(str(path))
    image = tttrlib.CLSMImage(tttr, channels=[0])
    micro = tttr.micro_times
    out = np.zeros((image.n_frames, image.n_lines, image.n_pixel, bins), dtype=np.int64)
    for f in range(image.n_frames):
        for y in range(image.n_lines):
            for x in range(image.n_pixel):
                index = np.asarray(image[f][y][x].tttr_indices, dtype=np.int64)
                out[f, y, x] = np.bincount(micro[index], minlength=bins)
    return out


def test_image_capture_to_ptu_one_image_pixel_per_sensor_pixel(tmp_path):
    capture = image_capture(tmp_path / "i.h5")
    export_capture(capture, tmp_path / "i.ptu", "ptu")
    with ptufile.PtuFile(tmp_path / "i.ptu") as ptu:
        counts = ptu.decode_image(dtype=np.uint32, dtime=1024)
        assert ptu.tags["FLISS_first_pixel"] == 8
        assert ptu.tags["MeasDesc_Resolution"] == pytest.approx(400e-12)
    np.testing.assert_array_equal(counts[:, 0, :, 0, :], capture.histograms)
    np.testing.assert_array_equal(_tttrlib_image(tmp_path / "i.ptu", 1024)[:, 0],
                                  capture.histograms)


def test_exports_read_back_as_the_captures_they_were(tmp_path):
    raw, _ = raw_capture(tmp_path / "r.h5")
    rows = np.array([two_echoes(1, seed=s) for s in range(3)])
    histogram = histogram_capture(tmp_path / "h.h5", rows, incomplete=(1,))
    image = image_capture(tmp_path / "i.h5")
    for capture, to, name in ((raw, "ptu", "r.ptu"), (raw, "photon-hdf5", "r.hdf5"),
                              (histogram, "ptu", "h.ptu"), (image, "ptu", "i.ptu")):
        export_capture(capture, tmp_path / name, to)
        back = read_file(tmp_path / name)
        assert (back.mode, back.problems) == (capture.mode, [])
        assert back.configuration == capture.configuration
        assert back.identity == capture.identity
        assert back.attrs == capture.attrs
        assert back.bin_s == capture.bin_s
        np.testing.assert_array_equal(back.histograms, capture.histograms)
        np.testing.assert_array_equal(back.complete, capture.complete)
        np.testing.assert_array_equal(back.frames, capture.frames)
        np.testing.assert_array_equal(back.pixels, capture.pixels)
        fields = list(raw.events.dtype.names)
        if to == "ptu":                             # PTU has no place for the collision flag
            fields.remove("collision")
        np.testing.assert_array_equal(back.events[fields], capture.events[fields])


def test_analyze_of_an_export_is_the_analysis_of_the_capture(tmp_path, capsys):
    rows = np.array([two_echoes(0, seed=s) for s in range(3)])
    histogram_capture(tmp_path / "h.h5", rows, shift=0, configuration=dict(aggressor=1))
    status, out, err = fliss(capsys, "export", tmp_path / "h.h5", "--to", "ptu", "-o",
                             tmp_path / "h.ptu")
    assert status == 0, err
    victim = ["--victim-tof", f"{VICTIM_S * 1e9}ns"]
    _, first, _ = fliss(capsys, "analyze", tmp_path / "h.h5", *victim)
    _, second, _ = fliss(capsys, "analyze", tmp_path / "h.ptu", *victim)
    assert "suppression S = " in first
    assert second == first.replace(str(tmp_path / "h.h5"), str(tmp_path / "h.ptu"))


def test_depth_captures_are_refused_with_the_formats_that_hold_them(tmp_path, capsys):
    depth_capture(tmp_path / "d.h5")
    for to, name, title in (("ptu", "d.ptu", "PTU (PicoQuant)"),
                            ("photon-hdf5", "d.hdf5", "Photon-HDF5")):
        status, out, err = fliss(capsys, "export", tmp_path / "d.h5", "--to", to, "-o",
                                 tmp_path / name)
        assert (status, out) == (1, "")
        assert err == (f"fliss: error: {tmp_path / 'd.h5'}: a depth capture cannot go to "
                       f"{title}: PTU and Photon-HDF5 hold photons and TCSPC histograms, not "
                       f"depth frames: a depth capture goes to a point cloud (--to ply, pcd, "
                       f"las, mcap or mcap-ros2; docs/point-clouds.md)\n")
        assert not (tmp_path / name).exists()


def test_histograms_are_refused_by_photon_hdf5(tmp_path, capsys):
    histogram_capture(tmp_path / "h.h5", [two_echoes(1)])
    (tmp_path / "h.hdf5").write_bytes(b"kept")
    status, out, err = fliss(capsys, "export", tmp_path / "h.h5", "--to", "photon-hdf5",
                             "-o", tmp_path / "h.hdf5", "--overwrite")
    assert (status, out) == (1, "")
    assert err == (f"fliss: error: {tmp_path / 'h.h5'}: a histogram capture cannot go to "
                   f"Photon-HDF5, which holds photons one by one, not histograms: export it "
                   f"to PTU (--to ptu)\n")
    assert (tmp_path / "h.hdf5").read_bytes() == b"kept"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.h5", "h.hdf5"]   # no leftover


def test_events_out_of_order_are_refused(tmp_path):
    capture, _ = raw_capture(tmp_path / "r.h5", n=10)
    capture.events["pulse"][6] = capture.events["pulse"][5] - 1
    with pytest.raises(FormatError) as error:
        export_capture(capture, tmp_path / "r.ptu", "ptu")
    assert str(error.value) == (
        f"{tmp_path / 'r.h5'}: event 6 (laser cycle {capture.events['pulse'][6]}) comes "
        f"before event 5 (cycle {capture.events['pulse'][5]}): PTU and Photon-HDF5 hold "
        f"records in time order")
    assert not (tmp_path / "r.ptu").exists()


def test_export_refuses_to_write_over_its_capture(tmp_path, capsys):
    raw_capture(tmp_path / "r.h5", n=10)
    status, out, err = fliss(capsys, "export", tmp_path / "r.h5", "--to", "ptu", "-o",
                             tmp_path / "r.h5", "--overwrite", "--any-extension")
    assert (status, out) == (1, "")
    assert err == (f"fliss: error: --output: {tmp_path / 'r.h5'} is the capture itself; "
                   f"give another file\n")


@pytest.mark.parametrize("to, name, named, has, instead", [
    ("ptu", "out.h5", "*.ptu", "not *.h5", "out.ptu"),
    ("ptu", "out", "*.ptu", "and this name has no ending", "out.ptu"),
    ("photon-hdf5", "out.ptu", "*.hdf5 or *.h5", "not *.ptu", "out.hdf5"),
])
def test_an_output_named_for_another_format_is_refused(tmp_path, capsys, to, name, named, has,
                                                      instead):
    raw_capture(tmp_path / "r.h5", n=10)
    out_path = tmp_path / name
    status, out, err = fliss(capsys, "export", tmp_path / "r.h5", "--to", to, "-o", out_path)
    what = "a PTU file" if to == "ptu" else "a Photon-HDF5 file"
    assert (status, out, err) == (1, "", f"fliss: error: -o {out_path}: {what} is named {named}, "
                                         f"{has}: give -o {tmp_path / instead}, or "
                                         f"--any-extension to keep the name\n")
    assert not out_path.exists()
    status, out, err = fliss(capsys, "export", tmp_path / "r.h5", "--to", to, "-o", out_path,
                             "--any-extension")
    assert status == 0, err
    assert read_file(out_path).events.shape == (10,)     # what it is, whatever its name


def test_a_capture_from_the_model_board_exports(tmp_path, capsys):
    from fliss.sim.boards.model import model_board
    from fliss.sim.scene import Scene
    with model_board(scene=Scene(detections_per_pulse=0.1, background_hz=2e5)) as model:
        status, _, err = fliss(capsys, "capture", "--port", model.path, "--timeout", "2",
                               "--readout", "raw", "--integration", "2ms", "--duration",
                               "0.1s", "-o", tmp_path / "m.h5")
    assert status == 0, err
    capture = read_file(tmp_path / "m.h5")
    assert len(capture.events) > 100 and capture.clock_hz == CLOCK_HZ
    export_capture(capture, tmp_path / "m.ptu", "ptu")
    sync, dtime, channel, _ = photons_of(tmp_path / "m.ptu")
    np.testing.assert_array_equal(sync & 0xFFFFFFFF, capture.events["pulse"])
    np.testing.assert_array_equal(dtime, capture.events["timestamp"])
    np.testing.assert_array_equal(channel, capture.events["address"])


def test_an_empty_raw_capture_exports_and_reads_back(tmp_path):
    capture, _ = raw_capture(tmp_path / "r.h5", n=0)
    for to, name in (("ptu", "e.ptu"), ("photon-hdf5", "e.hdf5")):
        assert export_capture(capture, tmp_path / name, to) == 0
        back = read_file(tmp_path / name)
        assert (back.mode, len(back.events), back.problems) == ("raw", 0, [])


@pytest.mark.parametrize("to, name", [("ptu", "r.ptu"), ("photon-hdf5", "r.hdf5")])
def test_an_export_made_run_by_run_holds_every_event(tmp_path, monkeypatch, to, name):
    # Runs of 7 events: run edges fall on the 32-bit wrap, the gap of 3 overflow records and
    # between events of one laser cycle; the cycles are the capture's own, worked out whole.
    capture, cycles = raw_capture(tmp_path / "r.h5", n=3001)
    whole = export_capture(capture, tmp_path / f"whole.{name}", to)
    monkeypatch.setattr("fliss.host.formats.metadata.CHUNK_EVENTS", 7)
    assert export_capture(capture, tmp_path / name, to) == whole
    events = capture.events
    if to == "ptu":
        sync, dtime, channel, tags = photons_of(tmp_path / name)
        assert tags["TTResult_NumberOfRecords"] == whole
        header = _header_words(tmp_path / name) * 4
        assert (tmp_path / name).read_bytes()[header:] == \
            (tmp_path / f"whole.{name}").read_bytes()[header:]
    else:
        tttr = tttrlib.TTTR(str(tmp_path / name), "PHOTON-HDF5")
        sync, dtime, channel = (tttr.macro_times.astype(np.int64), tttr.micro_times,
                                tttr.routing_channels)
        h5 = phconvert.hdf5.load_photon_hdf5(str(tmp_path / name), warnings=False)
        try:
            detectors = h5.root.setup.detectors
            np.testing.assert_array_equal(detectors.id.read(), np.arange(64))
            np.testing.assert_array_equal(detectors.counts.read(),
                                          np.bincount(events["address"], minlength=64))
            np.testing.assert_array_equal(h5.root.user.fliss.collision.read(),
                                          events["collision"])
        finally:
            h5.close()
    np.testing.assert_array_equal(sync, cycles)
    np.testing.assert_array_equal(dtime, events["timestamp"])
    np.testing.assert_array_equal(channel, events["address"])


def test_events_out_of_order_at_a_run_edge_are_refused(tmp_path, monkeypatch):
    capture, _ = raw_capture(tmp_path / "r.h5", n=10)
    capture.events["pulse"][7] = capture.events["pulse"][6] - 1
    monkeypatch.setattr("fliss.host.formats.metadata.CHUNK_EVENTS", 7)
    with pytest.raises(FormatError) as error:
        export_capture(capture, tmp_path / "r.hdf5", "photon-hdf5")
    assert str(error.value) == (
        f"{tmp_path / 'r.h5'}: event 7 (laser cycle {capture.events['pulse'][7]}) comes "
        f"before event 6 (cycle {capture.events['pulse'][6]}): PTU and Photon-HDF5 hold "
        f"records in time order")
    assert not (tmp_path / "r.hdf5").exists()


@pytest.mark.parametrize("to, name", [("ptu", "f.ptu"), ("photon-hdf5", "f.hdf5")])
def test_a_capture_with_the_fine_tdcs_table_exports_and_reads_back(tmp_path, to, name):
    # A capture with the fine TDC holds its calibration table, an array: the export's JSON
    # metadata ended in a TypeError traceback.
    table = np.arange(1024, dtype=np.uint16) * 3
    capture, _ = raw_capture(tmp_path / "f.h5", n=20, configuration=dict(tdc_source=2),
                             attrs={"calibration_table": table})
    export_capture(capture, tmp_path / name, to)
    back = read_file(tmp_path / name)
    np.testing.assert_array_equal(back.calibration_table, table)
    np.testing.assert_array_equal(back.events["timestamp"], capture.events["timestamp"])
