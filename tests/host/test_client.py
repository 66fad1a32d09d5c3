"""Serial client (host/client.py, on the link of host/link.py) against the Python model board on a
real pty."""

import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

from fliss.hdl.protocol import HISTOGRAM_COUNT_BITS, STATUS_FIELDS
from fliss.hdl.protocol import PacketType, PROTOCOL_VERSION, EVENT_BYTES, NakCode
from fliss.hdl.registers import REGISTERS, defaults
from fliss.host.errors import UserError
from fliss.host.client import BoardClient
import fliss
from fliss.host.errors import GatewareVersionWarning
from fliss.host.errors import BoardError, BoardLost, BoardRefused, PortError, SettingsError
from fliss.host.stream import StreamAssembler, HistogramFrame, unpack_event_payload
from fliss.hdl.protocol import HistogramChunk, registers_layout
from fliss.protocol.frames import FrameDecoder, Packet
from fliss.protocol.events import unpack_events
from fliss.protocol.layout import pack, pack_words, unpack_from, unpack_words, byte_size
from fliss.protocol.events import EVENT_DTYPE
from fliss.sim.boards.model import model_board


CLOCK_HZ = 80_000_000


@pytest.fixture
def board_pair():
    with model_board() as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            yield model, board


# Commands

def test_identify(board_pair):
    model, board = board_pair
    identity = board.identify()
    assert identity.protocol == PROTOCOL_VERSION
    assert identity.clock_hz == CLOCK_HZ
    assert identity.registers == len(REGISTERS)
    assert identity.baud == model.baud
    # The gateware reports the package's whole version, written once in fliss/__init__.py.
    init = (Path(__file__).resolve().parents[2] / "fliss" / "__init__.py").read_text()
    assert identity.gateware_version == re.search(r'__version__ = "([^"]+)"', init).group(1)


def test_older_gateware_is_told_apart():
    with model_board(gateware_version="0.1.0") as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            with pytest.warns(GatewareVersionWarning) as record:
                identity = board.identify()
    assert identity.gateware_version == "0.1.0"
    assert [str(w.message) for w in record] == [
        f"the board runs gateware 0.1.0, this fliss is {fliss.__version__}: program the board "
        f"with this version's bitstream (make bitstream)"]


def test_older_protocol_is_told_before_the_identity_length():
    # A board of protocol 3 sent a shorter identity (no patch number): it is told to update
    # its gateware, not asked whether it is a FLISS board.
    with model_board(protocol_version=3) as model:
        model.identity_length = 13
        with BoardClient(model.path, timeout_s=2.0) as board:
            with pytest.raises(BoardError, match=f"^the board speaks protocol version 3, this "
                                                 f"fliss speaks version {PROTOCOL_VERSION}: "
                                                 f"update the gateware$"):
                board.identify()


def test_version_mismatch_is_refused():
    with model_board(protocol_version=PROTOCOL_VERSION + 1) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            with pytest.raises(BoardError, match=f"the board speaks protocol version "
                                                 f"{PROTOCOL_VERSION + 1}, this fliss speaks "
                                                 f"version {PROTOCOL_VERSION}: update the "
                                                 f"host tool"):
                board.identify()


def test_registers_round_trip(board_pair):
    model, board = board_pair
    assert board.read_registers() == defaults(CLOCK_HZ)
    new = board.write_registers({"delay_mode": 2, "mask_width": 5, "integration": 12345,
                                 "gate_end": 4000})
    read = board.read_registers()
    assert read == new == model.model.settings
    assert (read["delay_mode"], read["mask_width"], read["integration"], read["gate_end"]) == \
        (2, 5, 12345, 4000)
    assert board.read_registers(["seed", "integration"]) == {"seed": 1, "integration": 12345}


def test_out_of_range_is_caught_before_sending(board_pair):
    model, board = board_pair
    before = model.model.commands
    with pytest.raises(SettingsError, match=r"^Register length takes values from 2 to 32 "
                                            r"bits, not 33$"):
        board.write_registers({"length": 33}, current=defaults(CLOCK_HZ))
    with pytest.raises(SettingsError, match=r"pulse_width \(80 cycles\) must be shorter "
                                            r"than period \(80 cycles\)"):
        board.write_registers({"pulse_width": 80}, current=defaults(CLOCK_HZ))
    with pytest.raises(SettingsError, match="no register named 'speed'"):
        board.write_registers({"speed": 1}, current=defaults(CLOCK_HZ))
    assert model.model.commands == before


def test_board_nak_is_reported(board_pair):
    model, board = board_pair
    # Bypass the host checks: a WRITE of a seed of zero, built by hand.
    payload = pack(registers_layout(1), address=0x04, values=[0])
    with pytest.raises(BoardError, match=r"the board refused WRITE: seed out of range "
                                         r"\(OUT_OF_RANGE\)"):
        board.command(PacketType.WRITE, payload, expect=lambda reply: False, what="WRITE")
    assert board.read_registers(["seed"]) == {"seed": 1}


def test_library_errors_are_board_errors_not_cli_errors(board_pair):
    # A script catches BoardError; the command line's UserError is not in the library's way.
    model, board = board_pair
    for error in (BoardLost, BoardRefused, PortError, SettingsError):
        assert issubclass(error, BoardError) and not issubclass(error, UserError)
    payload = pack(registers_layout(1), address=0x04, values=[0])
    with pytest.raises(BoardRefused) as refused:
        board.command(PacketType.WRITE, payload, expect=lambda reply: False, what="WRITE")
    assert (refused.value.command, refused.value.code, refused.value.detail,
            refused.value.register.name) == ("WRITE", NakCode.OUT_OF_RANGE, 0x04, "seed")


def test_smaller_build_refusal_is_explained():
    # A board whose build has no raw-event mode and a narrower period (as the iCEBreaker's):
    # values in the register map's range that it refuses get a message that says so, and
    # nothing changes.
    with model_board(maxima={"acquisition": 0, "period": (1 << 24) - 1}) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            for name, value in (("acquisition", 1), ("period", 1 << 24)):
                with pytest.raises(BoardError, match=rf"^the board refused WRITE: its build does "
                                                     rf"not take {name} = {value} \(a smaller "
                                                     rf"build"):
                    board.write_registers({name: value})
            assert board.read_registers() == defaults(CLOCK_HZ)
            board.write_registers({"period": (1 << 24) - 1})
            assert board.read_registers(["period"]) == {"period": (1 << 24) - 1}


def test_status_has_every_field(board_pair):
    model, board = board_pair
    status = board.status()
    assert list(status) == list(STATUS_FIELDS)
    assert status["running"] == 0
    board.start()
    status = board.status()
    assert status["running"] == 1
    assert status["commands"] == model.model.commands
    board.stop()


def test_silent_port_times_out_with_same_sequence_number():
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        board = BoardClient(path, timeout_s=0.1, retries=2)
        start = time.monotonic()
        with pytest.raises(BoardLost, match=rf"^the board on {path} does not answer \(IDENTIFY: "
                                            r"no reply in 3 attempts of 0.1 s\)"):
            board.identify()
        assert time.monotonic() - start < 10
        assert board.retransmissions == 2
        board.close()
        # What reached the board: the sync (delimiter, PING), then the same IDENTIFY 3 times.
        sent = os.read(master, 4096)
        decoder = FrameDecoder(synced=True)
        packets = [p for p in decoder.feed(sent) if isinstance(p, Packet)]
        identifies = [p for p in packets if p.type == PacketType.IDENTIFY]
        assert len(identifies) == 3
        assert len({p.seq for p in identifies}) == 1
    finally:
        os.close(master)
        os.close(slave)


def test_missing_port_and_permission():
    with pytest.raises(PortError, match=r"^no serial port '/nonexistent/tty' \(see "
                                        r"`fliss ports`\)$"):
        BoardClient("/nonexistent/tty")


def test_lost_reply_is_retried():
    # Every reply frame is damaged once in three: commands still succeed by re-sending.
    with model_board(corrupt_every=3, corrupt_types={PacketType.ACK, PacketType.REGISTERS,
                                                     PacketType.IDENTITY}) as model:
        with BoardClient(model.path, timeout_s=0.2, retries=5) as board:
            for value in range(2, 8):
                board.write_registers({"length": value, "seed": 1})
                assert board.read_registers(["length"]) == {"length": value}
            assert board.retransmissions > 0
            assert board.link_counters()["dropped_frames"] == len(model.corrupted) > 0


# Stream assembly, on packets built here

def _chunk(frame, first, shift, last, counts):
    return Packet(PacketType.HISTOGRAM, 0,
                  pack(HistogramChunk, frame=frame, first_bin=first, shift=shift, last=last) +
                  pack_words(counts, HISTOGRAM_COUNT_BITS))


def _frame_packets(frame, counts, shift, per_chunk=128):
    bins = len(counts)
    return [_chunk(frame, first, shift, int(first + per_chunk >= bins),
                   counts[first:first + per_chunk]) for first in range(0, bins, per_chunk)]


def test_assembler_whole_frames_and_losses():
    rng = np.random.default_rng(5)
    shift = 3
    bins = 8192 >> shift
    frames = [rng.integers(0, 65536, bins) for _ in range(5)]
    packets = [_frame_packets(n + 40, counts, shift) for n, counts in enumerate(frames)]
    del packets[1][3]          # frame 41: a chunk in the middle is lost
    del packets[2][-1]         # frame 42: its last chunk is lost
    packets[3] = []            # frame 43: lost altogether
    assembler = StreamAssembler()
    out = []
    for packet in [p for frame in packets for p in frame]:
        out += assembler.add(packet, 1.0)
    out += assembler.flush(2.0)
    assert [f.frame for f in out] == [40, 41, 42, 44]
    assert [f.complete for f in out] == [True, False, False, True]
    np.testing.assert_array_equal(out[0].counts, frames[0])
    np.testing.assert_array_equal(out[3].counts, frames[4])
    expected = frames[1].copy()
    expected[3 * 128:4 * 128] = 0
    np.testing.assert_array_equal(out[1].counts, expected)
    assert out[1].missing_bins == 128 and out[2].missing_bins == 128
    c = assembler.counters
    assert (c.frames, c.incomplete_frames, c.lost_frames, c.missing_bins) == (4, 2, 1, 256)


def test_assembler_refuses_malformed_chunks():
    assembler = StreamAssembler()
    assert assembler.add(_chunk(0, 8100, 0, 1, np.ones(128)), 0.0) == []   # past the last bin
    assert assembler.add(_chunk(0, 0, 14, 1, np.ones(1)), 0.0) == []       # shift too large
    assert assembler.add(Packet(PacketType.HISTOGRAM, 0, b"\x01\x02\x03"), 0.0) == []
    assert assembler.add(Packet(PacketType.EVENTS, 0, b"\x00" * (EVENT_BYTES + 1)), 0.0) == []
    assert assembler.counters.malformed == 4
    assert assembler.flush() == []


def test_event_payload_matches_codec():
    rng = np.random.default_rng(9)
    events = np.zeros(37, dtype=EVENT_DTYPE)
    events["timestamp"] = rng.integers(0, 1 << 13, 37)
    events["address"] = rng.integers(0, 64, 37)
    events["collision"] = rng.integers(0, 2, 37)
    events["pulse"] = rng.integers(0, 1 << 32, 37, dtype=np.uint64)
    # Payload built by hand from the layout: timestamp, address, collision, pulse, LSB first.
    words = [int(e["timestamp"]) | int(e["address"]) << 13 | int(e["collision"]) << 19 |
             int(e["pulse"]) << 20 for e in events]
    payload = b"".join(word.to_bytes(EVENT_BYTES, "little") for word in words)
    np.testing.assert_array_equal(unpack_event_payload(payload), events)
    np.testing.assert_array_equal(unpack_events(payload), events)


# Streaming through the pty

def test_stream_corruption_is_counted_and_never_accepted():
    with model_board(corrupt_every=5, corrupt_types={PacketType.HISTOGRAM}) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            # (full chunks of 128 bins: each lost chunk is 128 missing bins)
            board.write_registers({"integration": 80_000, "bin_shift": 2, "full_readout": 1})
            board.reset_counters()
            board.start()
            frames = []
            for item in board.stream():
                if isinstance(item, HistogramFrame):
                    frames.append(item)
                if len(frames) >= 6:
                    break
            board.stop()
            frames += [f for f in board.drain() if isinstance(f, HistogramFrame)]
            link = board.link_counters()
    # What the board sent, reassembled here from its own record, chunk by chunk.
    sent = {}
    for _type, _seq, payload in model.sent:
        chunk = unpack_from(HistogramChunk, payload)
        frame, first = chunk["frame"], chunk["first_bin"]
        sent.setdefault(frame, np.zeros(2048, dtype=np.int64))[first:first + 128] = \
            unpack_words(payload, HISTOGRAM_COUNT_BITS, offset=byte_size(HistogramChunk))
    corrupted = {seq for type, seq in model.corrupted}
    assert len(corrupted) >= 10
    assert link["dropped_frames"] == len(model.corrupted)
    # A lost packet shows as missing when a later one comes: the board's last packet, when it
    # is the corrupted one, has none after it (its loss is in dropped_frames all the same)
    lost = len(model.corrupted)
    last_lost = model.sent[-1][1] in corrupted
    assert link["missing_packets"] in ({lost, lost - 1} if last_lost else {lost})
    for frame in frames:
        truth = sent[frame.frame]
        if frame.complete:
            np.testing.assert_array_equal(frame.counts, truth)
        else:
            # Missing chunks are zero, everything else is exactly what was sent.
            differs = frame.counts != truth
            assert np.all(frame.counts[differs] == 0)
    assert sum(not f.complete for f in frames) > 0
    assert sum(f.missing_bins for f in frames) == 128 * len(model.corrupted)


def test_damaged_commands_are_refused_and_resent():
    # The board answers a damaged command with a link-error NAK; the client re-sends it.
    with model_board(corrupt_commands_every=3) as model:
        with BoardClient(model.path, timeout_s=0.3, retries=3) as board:
            for value in range(2, 10):
                board.write_registers({"length": value, "seed": 1})
                assert board.read_registers(["length"]) == {"length": value}
            status = board.status()
    assert model.corrupted_commands > 3
    assert board.link_naks > 0 and board.retransmissions >= board.link_naks
    assert status["bad_crc"] + status["truncated"] + status["bad_length"] > 0
    assert model.model.settings["length"] == 9


def test_socket_url_reaches_the_same_board():
    # A TCP bridge to the model board's pty: the client opens socket://, nothing else changes.
    import socket
    import threading
    import tty

    with model_board() as model:
        fd = os.open(model.path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        server = socket.create_server(("127.0.0.1", 0))
        port = server.getsockname()[1]

        def bridge():
            connection, _ = server.accept()
            connection.setblocking(False)
            import select
            while True:
                readable, _, _ = select.select([connection, fd], [], [], 0.05)
                try:
                    if connection in readable:
                        data = connection.recv(4096)
                        if not data:
                            return
                        os.write(fd, data)
                    if fd in readable:
                        connection.sendall(os.read(fd, 4096))
                except OSError:
                    return

        thread = threading.Thread(target=bridge, daemon=True)
        thread.start()
        try:
            with BoardClient(f"socket://127.0.0.1:{port}") as board:
                assert board.identify().clock_hz == CLOCK_HZ
                board.write_registers({"mask_width": 3})
                assert model.model.settings["mask_width"] == 3
        finally:
            thread.join(timeout=2)
            server.close()
            os.close(fd)


def test_loop_url_opens_but_nobody_answers():
    with BoardClient("loop://", timeout_s=0.05, retries=0) as board:
        with pytest.raises(BoardLost, match=r"^the board on loop:// does not answer"):
            board.identify()
