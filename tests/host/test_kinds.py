"""The kinds of data (fliss.host.kinds): one slice per kind, found through one registry.

* No module outside the registry tells kinds apart by their names (read with :mod:`ast`).
* Every kind of data packet has its assembler, every readout its model-board producer.
* A kind added to the registry alone is captured, read back, given blank rows and refused by
  the exports, with no other module changed.
"""

import ast
from pathlib import Path

import h5py
import numpy as np
import pytest

from fliss.hdl.registers import AcquisitionMode
from fliss.host.errors import FormatError
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.formats import export_capture
from fliss.host.kinds import KINDS, DataKind, for_mode, kind_of, mode_of
from fliss.host.rows import FrameRows
from fliss.protocol.packets import KIND as PACKET_KIND
from fliss.sim.boards.producers import PRODUCERS

import imager_frames as scene


ROOT = Path(__file__).resolve().parents[2]

#: Modules whose strings equal a kind's name for another reason: the self-test's checks and
#: their advice (one of them is called "histogram").
OTHER_MEANINGS = {"host/selftest.py", "host/checklist.py"}


def _kind_names_compared(path):
    """Lines of ``path`` that compare a value with a kind's name (``mode == "depth"``,
    ``readout in ("histogram", "image")``)."""
    names = set(KINDS)
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if not isinstance(node, ast.Compare):
            continue
        for operand in [node.left, *node.comparators]:
            values = operand.elts if isinstance(operand, (ast.Tuple, ast.List, ast.Set)) \
                else [operand]
            if any(isinstance(value, ast.Constant) and value.value in names
                   for value in values):
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_no_module_outside_the_registry_tests_a_kind_name():
    paths = [path for folder in ("host", "sim/boards", "protocol")
             for path in sorted((ROOT / folder).rglob("*.py"))
             if "kinds" not in path.relative_to(ROOT).parts
             and path.relative_to(ROOT).as_posix() not in OTHER_MEANINGS]
    assert len(paths) > 50
    found = [line for path in paths for line in _kind_names_compared(path)]
    assert found == []


def test_every_data_packet_has_its_assembler_and_every_readout_its_producer():
    assert {kind.packet for kind in KINDS.values()} == set(PACKET_KIND.values())
    assert {kind.readout for kind in KINDS.values()} == set(AcquisitionMode)
    assert set(PRODUCERS) == set(AcquisitionMode)
    assert list(KINDS) == ["histogram", "image", "depth", "raw"]


def test_the_readout_and_the_pixels_give_the_mode():
    assert mode_of(AcquisitionMode.HISTOGRAM) == "histogram"
    assert mode_of(AcquisitionMode.HISTOGRAM, pixel_bits=2) == "image"
    assert mode_of("histogram", pixel_bits=2, image=False) == "histogram"
    assert mode_of("histogram", image=True) == "image"
    assert mode_of(AcquisitionMode.DEPTH, pixel_bits=3) == "depth"
    assert mode_of(AcquisitionMode.RAW, pixel_bits=3, image=True) == "raw"
    assert for_mode("sweep") is KINDS["histogram"]
    with pytest.raises(ValueError, match=r"^no kind of data 'sweep'; the kinds are histogram, "
                                         r"image, depth, raw$"):
        kind_of("sweep")


class Tally:
    """An item of the made-up kind below: a frame number and one count."""

    def __init__(self, frame, count):
        self.frame, self.count = frame, count


def _create(file, configuration, code_s):
    group = file.create_group("tally")
    group.create_dataset("frame", shape=(0,), maxshape=(None,), dtype=np.uint32, chunks=(64,))
    group.create_dataset("count", shape=(0,), maxshape=(None,), dtype=np.int64, chunks=(64,))
    return None


def _append(file, index, items, state, completes):
    group = file["tally"]
    for name in ("frame", "count"):
        group[name].resize(index + len(items), axis=0)
        group[name][index:] = [getattr(item, name) for item in items]


def _read(file, group_of, rows_of, problems):
    group = group_of(file, "tally")
    return {"frames": rows_of(group["frame"], problems),
            "histograms": rows_of(group["count"], problems)}


TALLY = DataKind(
    name="tally", rank=9, readout=AcquisitionMode.HISTOGRAM, packet="histogram",
    assembler=None, item=Tally, rows="tallies", format_version=3, what="tallies",
    counted=True, imager=False, read=_read, tally=None, replay=None, seen=None,
    create=_create, append=_append, blank=lambda number, configuration: Tally(number, -1),
    refusal="a tally capture is its own format")


def test_a_new_kind_is_one_registry_entry(tmp_path, monkeypatch):
    # The capture file, its blank rows and the exports take a kind that no module names.
    monkeypatch.setitem(KINDS, "tally", TALLY)
    path = tmp_path / "tally.h5"
    with CaptureWriter(str(path), mode="tally", identity=scene.identity(),
                       configuration=scene.configuration()) as writer:
        rows = FrameRows(writer, 5, 10, scene.configuration(), "tally")
        assert rows.add(Tally(10, 7)) == 1
        assert rows.add(Tally(12, 9)) == 2        # frame 11 lost: a blank row before it
        rows.lose_made(5)                         # 13 and 14 made, never arrived
        assert (rows.saved, rows.lost, rows.done) == (5, 3, True)
    with h5py.File(path, "r") as f:
        assert f.attrs["mode"] == "tally" and f.attrs["format_version"] == 3
        assert "image" not in f and "depth" not in f and "counts" not in f["histograms"]
    capture = read_capture(path)
    assert capture.mode == "tally"
    assert capture.frames.tolist() == [10, 11, 12, 13, 14]
    assert capture.histograms.tolist() == [7, -1, 9, -1, -1]
    with pytest.raises(FormatError, match=r"tally.h5: a tally capture is its own format$"):
        export_capture(capture, tmp_path / "out.ptu", "ptu")
