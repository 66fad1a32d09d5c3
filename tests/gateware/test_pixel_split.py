"""The histogram's pixel split: the register file (gateware) refuses a split that does not fit
the build's bank, or pixels past the sensor's last address, exactly as
:func:`fliss.hdl.registers.problems` says (and the command model, and so the host); IDENTITY
reports the bank."""

import gc
import warnings

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.hdl.link.command import CommandProcessor
from fliss.hdl.protocol import CONSISTENCY, Identity, NakCode, Nak, PacketType
from fliss.hdl.regfile import RegisterFile
from fliss.hdl.registers import BY_NAME, defaults, problems, split_problems
from fliss.hdl.top import FlissTop, SMALL
from fliss.protocol.layout import pack, unpack
from fliss.sim.models.command import CommandModel

from test_command import BAUD, CLOCK_HZ, _write, run_commands


def split_writes():
    """WRITEs of bin_shift … first_pixel (0x13 … 0x17): every shift and pixel_bits, with the
    first pixel at 0, at the last that fits and one past it."""
    first = BY_NAME["bin_shift"].address
    assert [BY_NAME[name].address - first for name in
            ("integration", "collisions", "pixel_bits", "first_pixel")] == [1, 2, 3, 4]
    writes = []
    for shift in range(14):
        for pixel_bits in range(7):
            for first_pixel in {0, 64 - (1 << pixel_bits), min(65 - (1 << pixel_bits), 63)}:
                writes.append((shift, pixel_bits, first_pixel))
    return first, writes


@pytest.mark.parametrize("bank_bits", [13, 14, 16])
def test_split_checks_match_python(bank_bits):
    first, writes = split_writes()
    packets = [(PacketType.IDENTIFY.value, 0, b"")]
    packets += [(PacketType.WRITE.value, (n + 1) & 0xff,
                 _write(first, shift, 1000, 0, pixel_bits, first_pixel))
                for n, (shift, pixel_bits, first_pixel) in enumerate(writes)]
    replies, _, _ = run_commands(packets, bank_bits=bank_bits)
    assert unpack(Identity, replies[0][1])["bank_bits"] == bank_bits
    model = CommandModel(CLOCK_HZ, BAUD, bank_bits=bank_bits)
    refused = 0
    for (type, seq, payload), reply, (shift, pixel_bits, first_pixel) in \
            zip(packets[1:], replies[1:], writes):
        want_type, want_payload = model.command(type, seq, payload)
        assert reply == (want_type.value, want_payload), (shift, pixel_bits, first_pixel)
        # independently of the register map's code: the bank holds the split, and the
        # pixels are addresses 0 … 63
        fits = pixel_bits + 13 - shift <= bank_bits and first_pixel + 2**pixel_bits <= 64
        assert (reply[0] == PacketType.ACK.value) == fits, (shift, pixel_bits, first_pixel)
        if not fits:
            refused += 1
            assert reply[1] == pack(Nak, seq=seq, code=NakCode.OUT_OF_RANGE, detail=CONSISTENCY)
    assert 50 < refused < len(writes) - 50


def test_split_messages():
    values = {**defaults(CLOCK_HZ), "pixel_bits": 4, "bin_shift": 2, "first_pixel": 50}
    assert split_problems(values, 14) == [
        "pixel_bits (4) and bin_shift (2) ask for 16 pixels of 2048 bins, more than this "
        "board's histogram bank holds (16384 bins, bank_bits 14): pixel_bits + 13 - bin_shift "
        "must be at most 14",
        "first_pixel (50) plus 16 pixels (pixel_bits 4) goes past the last pixel address (63): "
        "first_pixel + 2**pixel_bits must be at most 64"]
    assert problems({**values, "first_pixel": 48}) == []          # the default bank: 16 bits
    values.update(first_pixel=48, bin_shift=0)                      # 16 pixels of 8192 bins
    assert problems(values, 17) == [] and len(problems(values)) == 1


def test_builds_report_their_bank():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)     # built, never elaborated
        banks = [FlissTop().bank_bits, FlissTop(**SMALL).bank_bits,
                 FlissTop(histogram_ram="single").bank_bits,
                 CommandProcessor(bank_bits=19).bank_bits]
        gc.collect()
    assert banks == [16, 14, 14, 19]


@pytest.mark.parametrize("bank_bits", [12, 20, "16"])
def test_bank_too_small_for_the_reset_split(bank_bits, construction_error):
    message = ("Histogram bank address width must be an integer from 13 to 19 bits, "
               f"not {bank_bits!r}")
    assert construction_error(lambda: FlissTop(bank_bits=bank_bits)) == message
    assert construction_error(lambda: RegisterFile(bank_bits=bank_bits)) == message


def test_host_checks_the_split_with_the_boards_bank():
    # The host learns the bank from IDENTITY and refuses, before sending, a split the board
    # would refuse; a WRITE that fits the ULX3S bank but not the iCEBreaker's is refused there
    # (here a model board told it has 14 bits).
    from fliss.host.client import BoardClient
    from fliss.host.errors import SettingsError
    from fliss.sim.boards.model import model_board

    with model_board() as model, BoardClient(model.path, timeout_s=2.0) as board:
        assert board.identify().bank_bits == 16
        current = board.read_registers()
        before = model.model.commands
        with pytest.raises(SettingsError, match=r"^pixel_bits \(6\) and bin_shift \(0\) ask for "
                                                r"64 pixels of 8192 bins, .*bank_bits 16\)"):
            board.write_registers({"pixel_bits": 6}, current=current)
        assert model.model.commands == before       # nothing sent
        written = board.write_registers({"pixel_bits": 2, "bin_shift": 0}, current=current)
        assert board.read_registers(["pixel_bits"]) == {"pixel_bits": 2}
        model.model.bank_bits = 14
        assert board.identify().bank_bits == 14
        with pytest.raises(SettingsError, match=r"must be at most 14$"):
            board.write_registers({"pixel_bits": 2, "bin_shift": 0}, current=written)
        board.write_registers({"pixel_bits": 1}, current=written)
        assert board.read_registers(["pixel_bits"]) == {"pixel_bits": 1}
