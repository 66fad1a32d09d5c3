"""The virtual board through a real pseudo-terminal: the generated Verilog of the top level in
Icarus and Verilator, the software codec on the other side of the pty, the scene simulator on the
sensor pins.

A missing simulator skips its tests, or fails them when ``FLISS_REQUIRE_SIMULATORS`` is set.
"""

import os
import time

import numpy as np
import pytest

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.protocol import (EVENT_BYTES, PROTOCOL_VERSION, NakCode, PacketType, Identity,
                                ReadRequest, Status, registers_layout)
from fliss.hdl.registers import BY_NAME, REGISTERS
from fliss import protocol
from fliss.host.virtual import ENGINES, SIMULATORS, VirtualBoard
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.fileformat import read_capture
from fliss.sim import scene
from fliss.sim.benches.runner import simulator_available
from fliss.protocol.histograms import assemble
from fliss.protocol.packets import HISTOGRAM_TYPES
from fliss.sim.boards.sensor import SensorModel, StandInPins


BAUD = 12_000_000
TARGET_M = 4.0
SPEED_OF_LIGHT_M_S = 299_792_458.0
TDC_LSB_S = 50e-12
#: Laser cycles of the histogram and of the raw acquisition: Icarus simulates this design some
#: six times slower than Verilator.
PULSES = {"verilator": 2500, "icarus": 1250}
REPLY_TYPES = {PacketType.ACK, PacketType.NAK, PacketType.IDENTITY, PacketType.REGISTERS,
               PacketType.STATUS}


def _sensor(period, aggressor_cycles, starts, **scene_options):
    """The sensor model driven by hand: a start every ``period`` cycles, an aggressor edge
    ``aggressor_cycles`` after each, each window closed when its range is over; returns the
    events it would put on the bus."""
    options = dict(distance_m=TARGET_M, detections_per_pulse=0.1, background_hz=1e5,
                   aggressors=(scene.Aggressor(period_cycles=period, offset_s=0.0,
                                               detections_per_pulse=0.1),))
    options.update(scene_options)
    sensor = SensorModel(StandInPins(), scene.Scene(**options), seed=5)
    # What the coroutines see, in time order (in one cycle: starts, edges, then window ends).
    happenings = []
    for index in range(starts):
        cycle = 100 + index * period
        happenings.append((cycle, 0, sensor.on_start, cycle))
        if aggressor_cycles is not None:
            happenings.append((cycle + aggressor_cycles, 1, sensor.on_aggressor,
                               cycle + aggressor_cycles))
        happenings.append((cycle + sensor.window_cycles + 1, 2, sensor.on_window_end, cycle))
    for _, _, handler, cycle in sorted(happenings, key=lambda item: item[:2]):
        handler(cycle)
    return sensor, np.array([event[0] for window in sensor._queue for event in window])


def test_sensor_model_peaks():
    """Without a simulator: the echo at 2 z / c after each start, the aggressor's photons at its
    edge plus the same time of flight, at most one event per window."""
    sensor, stamps = _sensor(80, 6, 4000)
    tof_codes = 2 * TARGET_M / SPEED_OF_LIGHT_M_S / TDC_LSB_S
    aggressor_codes = 6 / DEFAULT_CLOCK_HZ / TDC_LSB_S + tof_codes
    counts = np.bincount(stamps >> 4, minlength=512)
    first = int(np.argmax(counts))
    rest = counts.copy()
    rest[max(first - 3, 0):first + 4] = 0
    peaks = sorted([first * 16 + 8, int(np.argmax(rest)) * 16 + 8])
    assert abs(peaks[0] - tof_codes) <= 24 and abs(peaks[1] - aggressor_codes) <= 24, peaks
    # About 0.1 photons per pulse from each source, less the dead time and the last-photon rule.
    assert 0.1 * 4000 < len(stamps) <= 4000 and sensor.late == 0


def test_sensor_model_records_only_windows():
    """Photons between TDC windows (here every aggressor photon, 40 cycles after the start) are
    recorded by nobody; a start before the range is over cuts the window."""
    sensor, stamps = _sensor(80, 40, 2000, detections_per_pulse=0.0, background_hz=0.0)
    assert len(stamps) == 0
    sensor, stamps = _sensor(80, None, 500, background_hz=0.0)
    assert len(stamps) > 10 and sensor.late == 0
    sensor, stamps = _sensor(20, None, 500, background_hz=0.0)
    assert sensor.late == 499 and len(stamps) > 10 and np.all(stamps < 20 * 250)


def _line_sensor(sensor_kind, starts=3000, **options):
    """The sensor model of the line scene (a wall at 4 m, an object at 2.5 m before pixels 20
    to 39) driven by hand, a start every 80 cycles; returns the model and its windows."""
    pixels = scene.line_pixels(sensor=sensor_kind)
    settings = dict(detections_per_pulse=0.05, background_hz=1e4, pixels=pixels,
                    aggressors=(scene.Aggressor(period_cycles=80, offset_s=0.0,
                                                detections_per_pulse=0.0),))
    settings.update(options)
    sensor = SensorModel(StandInPins(), scene.Scene(**settings), seed=7, record=True)
    for index in range(starts):
        cycle = 100 + index * 80
        sensor.on_start(cycle)
        sensor.on_window_end(cycle)
    return sensor, list(sensor._queue)


@pytest.mark.parametrize("sensor_kind", ["column", "per_pixel"])
def test_sensor_model_of_the_line_scene(sensor_kind):
    """Without a simulator: the events the model reads out carry each pixel's address, at its
    own time of flight (object 2.5 m, wall 4 m); the column gives at most one per window, the
    per-pixel sensor one per pixel that fired, in address order, never a collision."""
    sensor, windows = _line_sensor(sensor_kind)
    events = [event for window in windows for event in window]
    assert events == sensor.fed
    stamps, addresses, collisions = (np.array(column) for column in zip(*events))
    assert set(addresses) <= set(range(60))
    for low, high, distance in ((20, 40, 2.5), (0, 20, 4.0), (40, 60, 4.0)):
        chosen = (addresses >= low) & (addresses < high)
        tof_codes = 2 * distance / SPEED_OF_LIGHT_M_S / TDC_LSB_S
        assert chosen.sum() > 100
        # The peak (the column also records late background: the last photon wins)
        peak = np.argmax(np.bincount(stamps[chosen] >> 4)) * 16 + 8
        assert abs(peak - tof_codes) <= 24, (low, peak, tof_codes)
    if sensor_kind == "column":
        assert max(len(window) for window in windows) == 1
        assert collisions.sum() > 0
    else:
        assert max(len(window) for window in windows) > 3 and not collisions.any()
        assert all(np.all(np.diff([event[1] for event in window]) > 0) for window in windows)


def test_missing_simulator(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert main(["board", "--sim", "icarus"]) == 1
    error = capsys.readouterr().err.strip().splitlines()
    assert error == ["fliss: error: simulator icarus is not installed: install Icarus Verilog "
                     "12 (apt install iverilog), or use --sim verilator"]


class Link:
    """The host side of the pty: frames out with the codec, packets in."""

    def __init__(self, path):
        import serial
        self.port = serial.serial_for_url(path, baudrate=BAUD, timeout=0.05)
        self.encoder = protocol.PacketEncoder()
        self.decoder = protocol.FrameDecoder(synced=True)
        self.pending = []
        self.data = []
        self.reports = []

    def close(self):
        self.port.close()

    def _read(self):
        for item in self.decoder.feed(self.port.read(4096)):
            (self.pending if isinstance(item, protocol.Packet) else self.reports).append(item)

    def next(self, types, timeout_s=30):
        deadline = time.monotonic() + timeout_s
        while True:
            while self.pending:
                packet = self.pending.pop(0)
                if packet.type in types:
                    return packet
                self.data.append(packet)
            if time.monotonic() > deadline:
                raise AssertionError(f"no {sorted(t.name for t in types)} packet from the board "
                                     f"within {timeout_s} s")
            self._read()

    def command(self, type, payload=b""):
        seq = self.encoder.seq
        self.port.write(self.encoder.frame(type, payload))
        reply = self.next(REPLY_TYPES)
        if reply.type in (PacketType.ACK, PacketType.NAK):
            assert reply.payload[0] == seq, (type, reply)
        return reply

    def write(self, **values):
        for name, value in values.items():
            reply = self.command(PacketType.WRITE, protocol.pack(
                registers_layout(1), address=BY_NAME[name].address, values=[value]))
            assert reply.type == PacketType.ACK, (name, value, reply)

    def read(self, name, count=1):
        reply = self.command(PacketType.READ, protocol.pack(ReadRequest,
                                                         address=BY_NAME[name].address,
                                                         count=count))
        assert reply.type == PacketType.REGISTERS, reply
        fields = protocol.unpack(registers_layout(count), reply.payload)
        assert fields["address"] == BY_NAME[name].address
        return fields["values"]

    def status(self):
        reply = self.command(PacketType.GET_STATUS)
        assert reply.type == PacketType.STATUS
        return protocol.unpack(Status, reply.payload)


def check_ping_identify(link, pulses):
    for _ in range(3):
        seq = link.encoder.seq
        reply = link.command(PacketType.PING)
        assert (reply.type, reply.payload) == (PacketType.ACK, bytes([seq]))
    reply = link.command(PacketType.IDENTIFY)
    assert reply.type == PacketType.IDENTITY
    identity = protocol.unpack(Identity, reply.payload)
    version, registers, clock_hz, baud = (identity["protocol"], identity["registers"],
                                           identity["clock_hz"], identity["baud"])
    assert (version, registers, clock_hz) == (PROTOCOL_VERSION, len(REGISTERS),
                                               DEFAULT_CLOCK_HZ)
    assert abs(baud - BAUD) <= BAUD * 0.02
    assert not link.reports


def check_register_round_trip(link, pulses):
    before = link.read("acquisition", len(REGISTERS))
    link.write(mask_width=11, gate_start=17, seed=0x2b)
    assert link.read("mask_width") == [11]
    assert link.read("gate_start", 2)[0] == 17
    assert link.read("seed") == [0x2b]
    # Refused: out of range, and nothing changes.
    reply = link.command(PacketType.WRITE, protocol.pack(
        registers_layout(1), address=BY_NAME["mask_width"].address, values=[17]))
    assert reply.type == PacketType.NAK
    assert reply.payload[1] == NakCode.OUT_OF_RANGE.value
    assert link.read("mask_width") == [11]
    # Put everything back as it was.
    link.write(**{register.name: value for register, value in zip(REGISTERS, before)
                  if register.name in ("mask_width", "gate_start", "seed")})
    assert link.read("acquisition", len(REGISTERS)) == before


def _frame(link, number, timeout_s):
    """Shift and bins of histogram frame ``number``, from its chunks (full or compact, whichever
    the board found shorter)."""
    packets = []
    deadline = time.monotonic() + timeout_s
    while True:
        packet = link.next(HISTOGRAM_TYPES, timeout_s=max(deadline - time.monotonic(), 0))
        packets.append((packet.type, packet.payload))
        got = assemble(packets).get(number)
        if got is not None and got[2]:
            chunk, counts, _ = got
            return chunk.shift, counts


def check_histogram_with_aggressor(link, pulses):
    """A histogram through the pty: the victim's echo peaks at the time of flight of the
    target, the aggressor's photons at its offset plus the same time of flight."""
    shift = 5                         # 256 bins of 1.6 ns: two chunks per frame
    integration = pulses * 80         # 1 µs laser period: 2.5 ms on Verilator
    offset_cycles = 6
    link.command(PacketType.STOP)
    link.write(acquisition=0, delay_mode=0, aggressor=1, aggressor_offset=offset_cycles,
               aggressor_delay_mode=0, bin_shift=shift, integration=integration,
               gate_start=0, gate_end=(1 << 13) - 1, tdc_source=0)
    assert link.command(PacketType.START).type == PacketType.ACK
    got_shift, bins = _frame(link, 0, timeout_s=90)
    link.command(PacketType.STOP)
    status = link.status()
    assert got_shift == shift
    assert len(bins) == (1 << 13) >> shift
    # Worked out here from the distance: 2 z / c, in bins of 2**shift codes of 50 ps.
    tof_s = 2 * TARGET_M / SPEED_OF_LIGHT_M_S
    victim_bin = tof_s / TDC_LSB_S / (1 << shift)
    aggressor_bin = (offset_cycles / DEFAULT_CLOCK_HZ + tof_s) / TDC_LSB_S / (1 << shift)
    first = int(np.argmax(bins))
    rest = bins.copy()
    rest[max(first - 4, 0):first + 5] = 0
    top_two = sorted([first, int(np.argmax(rest))])
    background = np.median(bins)
    assert abs(top_two[0] - victim_bin) <= 2, (top_two, victim_bin, bins[:80])
    assert abs(top_two[1] - aggressor_bin) <= 2, (top_two, aggressor_bin, bins[:80])
    # 0.1 photons per pulse from each source: peaks far above the background.
    assert bins[top_two].min() > 10 * max(background, 1), (bins[top_two], background)
    assert status["events"] >= bins.sum() > pulses // 10
    assert not [report for report in link.reports if not isinstance(report, protocol.SequenceGap)]


def check_raw_events(link, pulses):
    """Raw events through the pty: at most one per laser cycle, tagged with increasing laser
    cycle indices, the victim's echo at its time of flight, every accepted event delivered."""
    link.command(PacketType.STOP)
    link.write(acquisition=1, delay_mode=2, mask_width=6, aggressor=1, aggressor_delay_mode=0,
               bin_shift=0, tdc_source=0)
    link.data.clear()
    before = link.status()
    assert link.command(PacketType.START).type == PacketType.ACK
    deadline = time.monotonic() + 60
    status = link.status()
    while status["pulses"] < pulses and time.monotonic() < deadline:
        time.sleep(0.5)
        status = link.status()
    link.command(PacketType.STOP)
    status = link.status()
    # Raw events outrun the UART at these rates: the FIFO drains after the stop.
    deadline = time.monotonic() + 60
    while True:
        link._read()
        packets = [packet for packet in link.data + link.pending
                   if packet.type == PacketType.EVENTS]
        received = sum(len(packet.payload) for packet in packets) // EVENT_BYTES
        if received >= status["events"] - before["events"] or time.monotonic() > deadline:
            break
    events = np.concatenate([protocol.unpack_events(packet.payload) for packet in packets])
    link.write(acquisition=0)
    assert status["pulses"] >= pulses
    assert len(events) == status["events"] - before["events"] > 100
    assert status["dropped_fifo"] == status["dropped_overrun"] == 0
    tags = events["pulse"].astype(np.int64)
    assert np.all(np.diff(tags) > 0), tags[:20]
    assert tags[-1] < status["pulses"]
    tof_codes = 2 * TARGET_M / SPEED_OF_LIGHT_M_S / TDC_LSB_S
    counts = np.bincount(events["timestamp"] >> 4, minlength=512)   # 0.8 ns bins
    assert abs(np.argmax(counts) * 16 + 8 - tof_codes) <= 40, (np.argmax(counts), tof_codes)


#: Icarus runs the virtual board some six times slower than Verilator: several minutes for this
#: test, so it runs only when FLISS_SLOW_TESTS is set. Verilator runs with each engine.
_BOARD_SIMULATORS = [pytest.param(sim, engine, id=f"{sim}-{engine}", marks=pytest.mark.skipif(
    sim == "icarus" and not os.environ.get("FLISS_SLOW_TESTS"),
    reason="the virtual board on Icarus takes minutes: set FLISS_SLOW_TESTS=1"))
    for sim in SIMULATORS for engine in ENGINES if sim == "verilator" or engine == "cocotb"]


@pytest.mark.parametrize("sim, engine", _BOARD_SIMULATORS)
def test_virtual_board(sim, engine):
    """One board per simulator and engine (a build takes a minute or more, the start a few
    seconds), all checks in turn, each on a freshly opened port as a host tool would do."""
    if not simulator_available(sim):
        message = f"simulator {sim} is not installed"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)
    board = VirtualBoard(sim, engine=engine, baud=BAUD, target_m=TARGET_M, ambient_hz=1e5,
                         signal=0.1, aggressor_signal=0.1, seed=7)
    board.start()
    try:
        for check in (check_ping_identify, check_register_round_trip,
                      check_histogram_with_aggressor, check_raw_events):
            link = Link(board.path)
            try:
                check(link, PULSES[sim])
            finally:
                link.close()
        stats = board.stats()
        assert stats["bytes_to_board"] > 0 and stats["dropped"] == 0
        print(f"\n{sim}, {engine} engine: {stats['cycles'] / stats['wall_s']:.0f} cycles/s "
              f"simulated over {stats['wall_s']:.1f} s, {stats['bytes_to_host']} bytes to the host")
    finally:
        board.stop()


def _require_verilator():
    if not simulator_available("verilator"):
        message = "simulator verilator is not installed"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)


def test_reset_mid_capture(tmp_path, capsys):
    """`fliss capture` against a virtual board whose gateware is reset after 8 histograms (one
    chunk each): the capture ends with the one-line reset message, and the file keeps those 8
    histograms, whole."""
    _require_verilator()
    reset_after = 8
    output = tmp_path / "reset.h5"
    board = VirtualBoard("verilator", baud=BAUD, target_m=TARGET_M, signal=0.1, seed=3,
                         reset_after=reset_after)
    path = board.start()
    try:
        with BoardClient(path, timeout_s=5.0) as client:
            client.write_registers({"bin_shift": 6})        # 128 bins: one chunk
        status = main(["-q", "capture", "--port", path, "--integration", "0.2ms",
                       "--acquisitions", "40", "-o", str(output)])
        err = capsys.readouterr().err
        # (the board reports its stats about once a second: wait for the report after the reset)
        deadline = time.monotonic() + 3
        while board.stats().get("resets", 0) < 1 and time.monotonic() < deadline:
            time.sleep(0.1)
        stats = board.stats()
    finally:
        board.stop()
    assert status == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"fliss: error: the board on {path} was reset during the "
                               f"capture: its STATUS (sequence number "), lines
    assert lines[0].endswith(f"; saved what was received ({reset_after} histograms) to "
                             f"{output}"), lines
    capture = read_capture(output)
    assert capture.attrs["end_reason"].startswith("board reset: ")
    assert not capture.attrs["complete"]
    assert list(capture.frames) == list(range(reset_after)) and capture.complete.all()
    assert capture.histograms.shape[1] == 128 and (capture.histograms.sum(axis=1) > 0).all()
    assert stats["resets"] == 1


#: The files `fliss demo` writes in its folder, and the shortest demo that makes them all.
DEMO_FILES = ("fliss-off.h5", "fliss-on.h5", "demo.png", "imager-off.h5", "imager-on.h5",
              "imager.png", "attack.txt", "attack.png")
DEMO_ARGV = ["demo", "--integration", "0.5ms", "--acquisitions", "1", "--depth-frames", "1"]


def _run_demo(folder, capsys):
    """One short `fliss demo` into ``folder``; returns the mtimes of its files."""
    assert main([*DEMO_ARGV, "--out", str(folder)]) == 0
    summary = capsys.readouterr().out.split("== Summary")[-1]
    assert summary.count("victim peak") == 2, summary
    return {name: (folder / name).stat().st_mtime_ns for name in DEMO_FILES}


def test_demo_replaces_its_files(tmp_path, capsys):
    """`make demo` over the files of an earlier run replaces them instead of stopping: one run,
    the short version of test_demo_runs_again (which `make test-long` runs)."""
    _require_verilator()
    for name in DEMO_FILES:
        (tmp_path / name).write_bytes(b"an earlier run's file")
    _run_demo(tmp_path, capsys)
    for name in DEMO_FILES:
        assert (tmp_path / name).read_bytes() != b"an earlier run's file", name
    assert read_capture(tmp_path / "fliss-on.h5").histograms.shape[0] == 1


@pytest.mark.long
def test_demo_runs_again(tmp_path, capsys):
    """`make demo` twice: the second run replaces the demo's own files instead of stopping."""
    _require_verilator()
    written = [_run_demo(tmp_path, capsys) for _ in range(2)]
    assert all(written[1][name] > written[0][name] for name in written[0])


def test_line_scene_through_the_launcher():
    """`VirtualBoard(scene="line", sensor="per_pixel")` reaches the simulation: raw events come
    from the 60 pixels, the object's (pixels 20 to 39) at 2.5 m and the wall's at 4 m."""
    _require_verilator()
    board = VirtualBoard("verilator", baud=BAUD, target_m=4.0, ambient_hz=1e4, signal=0.05,
                         seed=5, scene="line", sensor="per_pixel", object_m=2.5)
    path = board.start()
    try:
        with BoardClient(path, timeout_s=5.0) as client:
            client.write_registers({"acquisition": 1, "period": 2400})
            client.start()
            events = []
            deadline = time.monotonic() + 60
            while sum(map(len, events)) < 300 and time.monotonic() < deadline:
                client.poll(0.5)
                events += [item.events for item in client.take_data()
                           if hasattr(item, "events")]
            client.stop()
        stats = board.stats()
    finally:
        board.stop()
    events = np.concatenate(events)
    addresses = events["address"].astype(int)
    assert len(events) >= 300 and len(set(addresses)) > 40 and not events["collision"].any()
    for low, high, distance in ((20, 40, 2.5), (0, 20, 4.0), (40, 60, 4.0)):
        chosen = (addresses >= low) & (addresses < high)
        tof_codes = 2 * distance / SPEED_OF_LIGHT_M_S / TDC_LSB_S
        assert abs(np.median(events["timestamp"][chosen]) - tof_codes) < 40, (low, distance)
    assert stats.get("busy_drops", 0) == 0
