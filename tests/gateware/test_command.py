"""Command processor in Amaranth's simulator against its model, packet by packet."""

import gc
import random
import warnings

import pytest
from amaranth.hdl import Module, ResetInserter, Signal, UnusedElaboratable

from fliss.hdl.finetdc.table import CalibrationTable, serve_registers
from fliss.hdl.link.command import CommandProcessor
from fliss.hdl.protocol import (PacketType, NakCode, STATUS_FIELDS, Identity, Nak, ReadRequest,
                                registers_layout)
from fliss.hdl.registers import REGISTERS, BY_NAME, TdcSource, defaults, problems
from fliss.hdl.top import FlissTop
from fliss.protocol.layout import pack, unpack
from fliss.sim.models.command import CommandModel
from simulation import simulate


CLOCK_HZ, BAUD = 80_000_000, 3_000_000


def group_settings(ctx, registers):
    """Every register's value as the register file's group ports carry it (each register is a
    field of one group), checked against its flat ``settings``."""
    values = {r.name: ctx.get(getattr(registers, r.group)[r.field]) for r in REGISTERS}
    assert values == {r.name: ctx.get(registers.settings[r.name]) for r in REGISTERS}
    return values


def run_commands(packets, *, link_errors=(), status=None, maxima=None, reset_before=None,
                 bank_bits=None):
    """Send ``(type, seq, payload)`` packets; return the replies ``(type, payload)`` and the
    settings after each command. ``reset_before``: the number of a packet before which the
    command processor is reset. ``bank_bits``: the histogram bank's (default: the
    processor's)."""
    dut = CommandProcessor(clock_hz=CLOCK_HZ, baud=BAUD, maxima=maxima,
                           **({} if bank_bits is None else {"bank_bits": bank_bits}))
    reset = Signal()
    replies, settings, updates = [], [], []

    async def sender(ctx):
        for number, (type, seq, payload) in enumerate(packets):
            if number == reset_before:
                ctx.set(reset, 1)
                await ctx.tick()
                ctx.set(reset, 0)
            if number in dict(link_errors):
                ctx.set(dut.link_error, 1)
                ctx.set(dut.link_error_code, dict(link_errors)[number])
                await ctx.tick()
                ctx.set(dut.link_error, 0)
            beats = [(True, None)] + [(False, byte) for byte in payload]
            for index, (first, byte) in enumerate(beats):
                ctx.set(dut.packets.valid, 1)
                ctx.set(dut.packets.p, {
                    "header": {"type": type, "seq": seq, "length": len(payload)},
                    "data": byte or 0, "first": first, "last": index == len(beats) - 1})
                await ctx.tick().until(dut.packets.ready)
            ctx.set(dut.packets.valid, 0)
            errors_so_far = len([n for n, _ in link_errors if n <= number])
            while len(replies) < number + 1 + errors_so_far:
                await ctx.tick()

    async def status_port(ctx):
        # The STATUS counters: `status`, with `commands` and `refused` counted here from the
        # strobes; a snapshot takes a random number of cycles.
        rng = random.Random(5)
        counts = {"commands": 0, "refused": 0}
        snapshot, busy = {}, 0
        ctx.set(dut.status.ready, 1)
        while True:
            _, _, capture, addr, commands, refused = await ctx.tick().sample(
                dut.status.capture, dut.status.addr, dut.tally.commands, dut.tally.refused)
            counts["commands"] += commands
            counts["refused"] += refused
            if capture:
                snapshot = {**(status or {}), **counts}
                busy = rng.randrange(1, 30)
            else:
                busy = max(busy - 1, 0)
            ctx.set(dut.status.ready, busy == 0)
            # (`addr` follows the register pointer during other replies)
            field = STATUS_FIELDS[addr] if addr < len(STATUS_FIELDS) else None
            ctx.set(dut.status.data, snapshot.get(field, 0))

    async def receiver(ctx):
        rng = random.Random(3)
        current = None
        while True:
            ready = rng.random() < 0.8
            ctx.set(dut.replies.ready, ready)
            if ctx.get(dut.update):
                updates.append(len(replies))
            if ready and ctx.get(dut.replies.valid):
                beat = ctx.get(dut.replies.p)
                if beat.first:
                    current = [beat.header.type, beat.header.length, bytearray()]
                else:
                    current[2].append(beat.data)
                if beat.last:
                    assert len(current[2]) == current[1]
                    replies.append((current[0], bytes(current[2])))
                    settings.append(group_settings(ctx, dut.registers))
            await ctx.tick()

    # The fine TDC's calibration table behind the register file, as in a build with the fine
    # TDC (one without it reads table_data as 0, as the model does)
    top = Module()
    top.submodules.dut = dut
    if dut.maxima["tdc_source"] >= TdcSource.FINE.value:
        top.submodules.table = table = CalibrationTable()
        serve_registers(top, table, dut.registers)
    simulate(ResetInserter({"sync": reset})(top), sender, background=[receiver, status_port],
             clock_hz=CLOCK_HZ)
    return replies, settings, updates


def _write(address, *values):
    return pack(registers_layout(len(values)), address=address, values=list(values))


def random_packets(rng, count):
    packets = []
    for seq in range(count):
        kind = rng.random()
        seq &= 0xff
        if kind < 0.45:
            register = rng.choice(REGISTERS)
            values = []
            for _ in range(rng.choice([1, 1, 1, 2, 3])):
                r = rng.random()
                if r < 0.6:
                    values.append(rng.randint(register.minimum, min(register.maximum, 200)))
                elif r < 0.8:
                    values.append(rng.choice([0, min(register.maximum + 1, (1 << 32) - 1),
                                              register.minimum,
                                              register.maximum, (1 << 32) - 1]))
                else:
                    values.append(rng.getrandbits(32))
            address = register.address if rng.random() < 0.95 else rng.choice([0x40, 0xffff])
            packets.append((PacketType.WRITE.value, seq, _write(address, *values)))
        elif kind < 0.6:
            address = rng.randrange(0, len(REGISTERS) + 2)
            packets.append((PacketType.READ.value, seq,
                            pack(ReadRequest, address=address, count=rng.randrange(0, 8))))
        elif kind < 0.7:
            packets.append((rng.choice([PacketType.START.value, PacketType.STOP.value]), seq, b""))
        elif kind < 0.8:
            packets.append((rng.choice([PacketType.PING.value, PacketType.IDENTIFY.value,
                                        PacketType.GET_STATUS.value]), seq,
                            b"" if rng.random() < 0.8 else b"\x01"))
        elif kind < 0.9:
            # Wrong lengths for READ and WRITE
            packets.append((rng.choice([PacketType.READ.value, PacketType.WRITE.value]), seq,
                            bytes(rng.getrandbits(8) for _ in range(rng.choice([0, 1, 2, 4, 7])))))
        else:
            packets.append((rng.choice([0x00, 0x7f, PacketType.ACK.value, PacketType.EVENTS.value,
                                        0x42]), seq, b""))
    return packets


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_against_model(seed):
    rng = random.Random(seed)
    packets = random_packets(rng, 120)
    status = {name: rng.getrandbits(32) for name in STATUS_FIELDS}
    replies, settings, _ = run_commands(packets, status=status)
    model = CommandModel(CLOCK_HZ, BAUD)
    assert len(replies) == len(packets)
    kinds = set()
    for number, ((type, seq, payload), (got_type, got_payload), got_settings) in enumerate(
            zip(packets, replies, settings)):
        want_type, want_payload = model.command(type, seq, payload, status=status)
        assert (got_type, got_payload) == (want_type.value, want_payload), (number, type, payload)
        assert got_settings == model.settings, number
        kinds.add((want_type, want_payload[1] if want_type == PacketType.NAK else None))
    # The run covered acceptance and each refusal.
    for code in (NakCode.BAD_PAYLOAD, NakCode.BAD_ADDRESS, NakCode.OUT_OF_RANGE,
                 NakCode.UNKNOWN_TYPE):
        assert (PacketType.NAK, code.value) in kinds, code
    assert (PacketType.ACK, None) in kinds and (PacketType.REGISTERS, None) in kinds


def test_consistency_checks_match_python():
    # Writes that are each in range but leave inconsistent settings are refused whole.
    cases = [
        _write(BY_NAME["pulse_width"].address, 80),                       # width = period
        _write(BY_NAME["period"].address, 1, 1),                          # period out of range
        _write(BY_NAME["delay_mode"].address, 1, 3, 6, 9),                # seed 9 >= 2**3
        _write(BY_NAME["delay_mode"].address, 1, 3, 6, 7),                # fine
        _write(BY_NAME["grid"].address, 1),                               # 6 + 1 < 80: fine
        _write(BY_NAME["length"].address, 7, 6, 127),                     # grid: 126 + 1 >= 80
        _write(BY_NAME["gate_start"].address, 100, 99),                   # start after end
        _write(BY_NAME["aggressor_period"].address, 5, 6, 5),             # width 5 = period 5
    ]
    packets = [(PacketType.WRITE.value, n, p) for n, p in enumerate(cases)]
    replies, settings, _ = run_commands(packets)
    accepted = [type == PacketType.ACK.value for type, _ in replies]
    assert accepted == [False, False, False, True, True, False, False, False]
    # Independently: the Python consistency rules say the same of the accepted ones.
    assert problems(settings[-1]) == []
    assert settings[-1]["length"] == 3 and settings[-1]["seed"] == 7 and settings[-1]["grid"] == 1


def test_update_strobe_only_while_running():
    packets = [
        (PacketType.WRITE.value, 0, _write(BY_NAME["period"].address, 100)),
        (PacketType.START.value, 1, b""),
        (PacketType.WRITE.value, 2, _write(BY_NAME["period"].address, 120)),
        (PacketType.WRITE.value, 3, _write(BY_NAME["period"].address, 0)),   # refused
        (PacketType.STOP.value, 4, b""),
        (PacketType.WRITE.value, 5, _write(BY_NAME["period"].address, 90)),
    ]
    replies, settings, updates = run_commands(packets)
    assert [t for t, _ in replies] == [PacketType.ACK.value] * 3 + [PacketType.NAK.value] + \
        [PacketType.ACK.value] * 2
    assert updates == [2]   # only the accepted write while running
    assert [s["period"] for s in settings] == [100, 100, 120, 120, 120, 90]


def test_link_errors_are_answered():
    packets = [(PacketType.PING.value, 7, b""), (PacketType.PING.value, 8, b"")]
    replies, _, _ = run_commands(packets, link_errors=[(1, NakCode.BAD_CRC)])
    assert replies[0] == (PacketType.ACK.value, bytes([7]))
    # The NAK of the dropped frame goes out once the processor is free: before or after the
    # reply to a packet that arrived at the same time.
    assert sorted(replies[1:]) == sorted([
        (PacketType.NAK.value, pack(Nak, seq=0, code=NakCode.BAD_CRC, detail=0)),
        (PacketType.ACK.value, bytes([8]))])


def test_identity():
    replies, _, _ = run_commands([(PacketType.IDENTIFY.value, 1, b"")])
    identity = unpack(Identity, replies[0][1])
    assert (identity["registers"], identity["clock_hz"], identity["baud"]) == \
        (len(REGISTERS), CLOCK_HZ, BAUD)


def test_lowered_maximum():
    # A build without the aggressor's delay source refuses its modes but off, like the model.
    maxima = {"aggressor_delay_mode": 0}
    address = BY_NAME["aggressor_delay_mode"].address
    packets = [(PacketType.WRITE.value, seq, _write(address, mode))
               for seq, mode in enumerate([1, 0, 2, 3])]
    packets.append((PacketType.WRITE.value, 9, _write(address - 1, 5, 1)))   # with a neighbour
    replies, _, _ = run_commands(packets, maxima=maxima)
    model = CommandModel(CLOCK_HZ, BAUD, maxima=maxima)
    assert replies == [(t.value, p) for t, p in (model.command(*packet) for packet in packets)]
    out_of_range = (PacketType.NAK.value, pack(Nak, seq=0, code=NakCode.OUT_OF_RANGE,
                                               detail=address))
    assert replies[0] == out_of_range and replies[1] == (PacketType.ACK.value, bytes([1]))


@pytest.mark.parametrize("maxima, message", [
    ({"nonsense": 0}, "Unknown register 'nonsense' in the register maxima"),
    ({"aggressor_delay_mode": 3},
     "Maximum of register aggressor_delay_mode must be an integer from its reset value or "
     "minimum to 2, not 3"),
    ({"period": 1},
     "Maximum of register period must be an integer from its reset value or minimum to "
     "4294967295, not 1"),
])
def test_refuses_bad_maxima(construction_error, maxima, message):
    assert construction_error(lambda: CommandProcessor(maxima=maxima)) == message


def test_reset_restores_the_registers():
    # Registers written, then a reset: READ gives the reset values again, as the settings are.
    writes = [(PacketType.WRITE.value, seq, _write(BY_NAME[name].address, value))
              for seq, (name, value) in enumerate([("period", 1234), ("seed", 77),
                                                   ("period", 999), ("gate_end", 4000)])]
    read_all = (PacketType.READ.value, 9, pack(ReadRequest, address=0, count=len(REGISTERS)))
    packets = writes + [read_all, read_all]
    replies, settings, _ = run_commands(packets, reset_before=len(writes) + 1)
    model = CommandModel(CLOCK_HZ, BAUD)
    for packet in writes + [read_all]:
        model.command(*packet)
    assert replies[len(writes)] == (PacketType.REGISTERS.value, model.command(*read_all)[1])
    fresh = CommandModel(CLOCK_HZ, BAUD)
    assert replies[-1] == (PacketType.REGISTERS.value, fresh.command(*read_all)[1])
    assert replies[-1] != replies[len(writes)]
    assert settings[-1] == defaults(CLOCK_HZ)


@pytest.mark.parametrize("name, refused", [("tdc_source", (2, 3)), ("fine_lsb", (1, 2)),
                                           ("tdc_input", (2, 1)), ("table_data", (1, 4095))])
def test_builds_without_the_fine_tdc_refuse_it(name, refused):
    # A build without the fine TDC takes tdc_source 0 and 1, and its registers 0 only, like the
    # model; the full register map takes them.
    maxima = FlissTop().register_maxima()
    assert not {"tdc_source", "fine_lsb"} & set(FlissTop(fine_tdc=True).register_maxima())
    address = BY_NAME[name].address
    values = [refused[0], 0, refused[1], 1 if name == "tdc_source" else 0]
    packets = [(PacketType.WRITE.value, seq, _write(address, value))
               for seq, value in enumerate(values)]
    replies, _, _ = run_commands(packets, maxima=maxima)
    model = CommandModel(CLOCK_HZ, BAUD, maxima=maxima)
    assert replies == [(t.value, p) for t, p in (model.command(*packet) for packet in packets)]
    out_of_range = [(PacketType.NAK.value, pack(Nak, seq=seq, code=NakCode.OUT_OF_RANGE,
                                                detail=address)) for seq in (0, 2)]
    assert [replies[0], replies[2]] == out_of_range
    assert [replies[1], replies[3]] == [(PacketType.ACK.value, bytes([seq])) for seq in (1, 3)]


def test_a_top_made_for_its_maxima_draws_no_warning():
    # A top level collected at some later time would warn in the middle of other output (a
    # command's stderr): asking it for its maxima is a use; one never asked still warns.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        FlissTop(fine_tdc=True).register_maxima()
        FlissTop()
        gc.collect()
    assert [w.category for w in caught] == [UnusedElaboratable]


def test_fine_tdc_without_the_aggressor_refuses_its_pad():
    # The internal loopback reads the aggressor's pad as tdc_input 3: a build with the fine
    # TDC and no aggressor refuses it, and takes the laser's pad (2), like the model
    maxima = FlissTop(fine_tdc=True, aggressor=False).register_maxima()
    address = BY_NAME["tdc_input"].address
    packets = [(PacketType.WRITE.value, seq, _write(address, value))
               for seq, value in enumerate((3, 2))]
    replies, _, _ = run_commands(packets, maxima=maxima)
    model = CommandModel(CLOCK_HZ, BAUD, maxima=maxima)
    assert replies == [(t.value, p) for t, p in (model.command(*packet) for packet in packets)]
    assert replies == [(PacketType.NAK.value, pack(Nak, seq=0, code=NakCode.OUT_OF_RANGE,
                                                   detail=address)),
                       (PacketType.ACK.value, bytes([1]))]
