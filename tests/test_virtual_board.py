"""The virtual board through a real pseudo-terminal: the generated Verilog of the top level in
Icarus and Verilator, the host codec on the other side of the pty, the scene simulator on the
sensor pins.

A missing simulator skips its tests, or fails them when ``FLISS_REQUIRE_SIMULATORS`` is set.
"""

import os
import struct
import time

import numpy as np
import pytest

from fliss.hdl import DEFAULT_CLOCK_HZ
from fliss.hdl.command import STATUS_FIELDS
from fliss.hdl.protocol import EVENT_BYTES, PROTOCOL_VERSION, NakCode, PacketType
from fliss.hdl.registers import BY_NAME, REGISTERS
from fliss.host import protocol as codec
from fliss.host.board import SIMULATORS, VirtualBoard
from fliss.sim.cocotb_runner import simulator_available


BAUD = 12_000_000
TARGET_M = 4.0
SPEED_OF_LIGHT_M_S = 299_792_458.0
TDC_LSB_S = 50e-12
REPLY_TYPES = {PacketType.ACK, PacketType.NAK, PacketType.IDENTITY, PacketType.REGISTERS,
               PacketType.STATUS}


class Link:
    """The host side of the pty: frames out with the codec, packets in."""

    def __init__(self, path):
        import serial
        self.port = serial.serial_for_url(path, baudrate=BAUD, timeout=0.05)
        self.encoder = codec.PacketEncoder()
        self.decoder = codec.FrameDecoder(synced=True)
        self.pending = []
        self.data = []
        self.reports = []

    def close(self):
        self.port.close()

    def _read(self):
        for item in self.decoder.feed(self.port.read(4096)):
            (self.pending if isinstance(item, codec.Packet) else self.reports).append(item)

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
            reply = self.command(PacketType.WRITE, struct.pack("<HI", BY_NAME[name].address,
                                                               value))
            assert reply.type == PacketType.ACK, (name, value, reply)

    def read(self, name, count=1):
        reply = self.command(PacketType.READ, struct.pack("<HB", BY_NAME[name].address, count))
        assert reply.type == PacketType.REGISTERS, reply
        address, *values = struct.unpack(f"<H{count}I", reply.payload)
        assert address == BY_NAME[name].address
        return values

    def status(self):
        reply = self.command(PacketType.GET_STATUS)
        assert reply.type == PacketType.STATUS
        return dict(zip(STATUS_FIELDS, struct.unpack(f"<{len(STATUS_FIELDS)}I", reply.payload)))


def check_ping_identify(link):
    for _ in range(3):
        seq = link.encoder.seq
        reply = link.command(PacketType.PING)
        assert (reply.type, reply.payload) == (PacketType.ACK, bytes([seq]))
    reply = link.command(PacketType.IDENTIFY)
    assert reply.type == PacketType.IDENTITY
    protocol, _major, _minor, registers, clock_hz, baud = struct.unpack("<BBBBII",
                                                                        reply.payload)
    assert (protocol, registers, clock_hz) == (PROTOCOL_VERSION, len(REGISTERS),
                                               DEFAULT_CLOCK_HZ)
    assert abs(baud - BAUD) <= BAUD * 0.02
    assert not link.reports


def check_register_round_trip(link):
    before = link.read("acquisition", len(REGISTERS))
    link.write(mask_width=11, gate_start=17, seed=0x2b)
    assert link.read("mask_width") == [11]
    assert link.read("gate_start", 2)[0] == 17
    assert link.read("seed") == [0x2b]
    # Refused: out of range, and nothing changes.
    reply = link.command(PacketType.WRITE, struct.pack("<HI", BY_NAME["mask_width"].address, 17))
    assert reply.type == PacketType.NAK
    assert reply.payload[1] == NakCode.OUT_OF_RANGE.value
    assert link.read("mask_width") == [11]
    # Put everything back as it was.
    link.write(**{register.name: value for register, value in zip(REGISTERS, before)
                  if register.name in ("mask_width", "gate_start", "seed")})
    assert link.read("acquisition", len(REGISTERS)) == before


def _frame(link, number, timeout_s):
    """Bins of histogram frame ``number``, from its chunks."""
    chunks = {}
    deadline = time.monotonic() + timeout_s
    while True:
        packet = link.next({PacketType.HISTOGRAM}, timeout_s=max(deadline - time.monotonic(), 0))
        frame, first_bin, shift, last = struct.unpack_from("<IHBB", packet.payload)
        if frame < number:
            continue
        assert frame == number, (frame, number)
        chunks[first_bin] = np.frombuffer(packet.payload[8:], dtype="<u2")
        if last:
            break
    bins = np.concatenate([chunks[first] for first in sorted(chunks)])
    return shift, bins


def check_histogram_with_aggressor(link):
    """A histogram through the pty: the victim's echo peaks at the time of flight of the
    target, the aggressor's photons at its offset plus the same time of flight."""
    shift = 5                         # 256 bins of 1.6 ns: two chunks per frame
    integration = 200_000             # 2.5 ms, 2500 laser cycles
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
    # 2500 pulses with 0.1 photons each: peaks far above the background.
    assert bins[top_two].min() > 10 * max(background, 1), (bins[top_two], background)
    assert status["events"] >= bins.sum() > 300
    assert not [report for report in link.reports if not isinstance(report, codec.SequenceGap)]


def check_raw_events(link):
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
    while status["pulses"] < 1500 and time.monotonic() < deadline:
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
    events = np.concatenate([codec.unpack_events(packet.payload) for packet in packets])
    link.write(acquisition=0)
    assert status["pulses"] >= 1500
    assert len(events) == status["events"] - before["events"] > 100
    assert status["dropped_fifo"] == status["dropped_overrun"] == 0
    pulses = events["pulse"].astype(np.int64)
    assert np.all(np.diff(pulses) > 0), pulses[:20]
    assert pulses[-1] < status["pulses"]
    tof_codes = 2 * TARGET_M / SPEED_OF_LIGHT_M_S / TDC_LSB_S
    counts = np.bincount(events["timestamp"] >> 4, minlength=512)   # 0.8 ns bins
    assert abs(np.argmax(counts) * 16 + 8 - tof_codes) <= 40, (np.argmax(counts), tof_codes)


@pytest.mark.parametrize("sim", SIMULATORS)
def test_virtual_board(sim):
    """One board per simulator (a build takes a minute, the start a few seconds), all checks
    in turn, each on a freshly opened port as a host tool would do."""
    if not simulator_available(sim):
        message = f"simulator {sim} is not installed"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)
    board = VirtualBoard(sim, baud=BAUD, target_m=TARGET_M, ambient_hz=1e5, signal=0.1,
                         aggressor_signal=0.1, seed=7)
    board.start()
    try:
        for check in (check_ping_identify, check_register_round_trip,
                      check_histogram_with_aggressor, check_raw_events):
            link = Link(board.path)
            try:
                check(link)
            finally:
                link.close()
        stats = board.stats()
        assert stats["bytes_to_board"] > 0 and stats["dropped"] == 0
        print(f"\n{sim}: {stats['cycles'] / stats['wall_s']:.0f} cycles/s simulated over "
              f"{stats['wall_s']:.1f} s, {stats['bytes_to_host']} bytes to the host")
    finally:
        board.stop()
