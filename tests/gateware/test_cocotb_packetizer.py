"""The histogram readout's packets on the wire, against the model, on Icarus and Verilator; and
the host's decoder turns them into exactly the frames."""

from pathlib import Path

import numpy as np

from fliss.host.stream import HistogramFrame, StreamAssembler
from fliss.sim.benches.runner import run_cocotb, write_verilog
from fliss.protocol.frames import FrameDecoder, Packet
from fliss.sim.benches.histogram_link_top import HistogramLinkTop
from fliss.sim.benches.packetizer import readout_frames


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "histogram_link_top"


def test_histogram_packets(simulator, cocotb_counts):
    verilog = write_verilog(HistogramLinkTop(), "histogram_link_top",
                            BUILD / "histogram_link_top.v")
    wire = BUILD / simulator / "wire.bin"
    wire.parent.mkdir(parents=True, exist_ok=True)
    wire.unlink(missing_ok=True)
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="histogram_link_top",
        test_module="fliss.sim.benches.packetizer", build_dir=BUILD,
        extra_env={"FLISS_TB_PACKETIZER_OUT": str(wire)})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
    # The host: the gateware's bytes, decoded and assembled, are the frames exactly.
    decoder, assembler = FrameDecoder(synced=True), StreamAssembler()
    frames = []
    for item in decoder.feed(wire.read_bytes()):
        assert isinstance(item, Packet)
        frames += assembler.add(item, 0.0)
    want = readout_frames()
    assert assembler.counters.malformed == 0
    assert len(frames) == len(want)
    for number, (frame, (counts, settings)) in enumerate(zip(frames, want)):
        assert isinstance(frame, HistogramFrame) and frame.complete
        assert (frame.frame, frame.shift, frame.pixel_bits, frame.first_pixel) == \
            (number, settings["shift"], settings["pixel_bits"], settings["first_pixel"])
        assert np.array_equal(frame.counts, counts)
