"""The link block (fliss.hdl.link.link.Link) in Amaranth's simulator: commands in, replies and
data packets out, through the UART or byte streams, decoded by the host codec and compared
with the command processor's model."""

import pytest

from fliss import protocol
from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.link.link import Link
from fliss.hdl.protocol import PacketType, NakCode, LINK_FIELDS, ReadRequest
from fliss.protocol.layout import pack
from fliss.sim.models import uart as uart_model
from fliss.sim.models.command import CommandModel
from simulation import simulate, stream_put


CLOCK_HZ, BAUD = DEFAULT_CLOCK_HZ, 10_000_000      # (8 cycles a bit)

#: Commands from the host, as ``(type, seq, payload)``: a PING, a READ of two registers, the
#: identity, a type the board does not know; then a PING whose frame is damaged.
COMMANDS = [
    (PacketType.PING.value, 5, b""),
    (PacketType.READ.value, 6, pack(ReadRequest, address=1, count=2)),
    (PacketType.IDENTIFY.value, 7, b""),
    (0x7f, 8, b""),
]
DAMAGED = bytearray(protocol.encode_frame(PacketType.PING, 9))
DAMAGED[2] ^= 0x10
FRAMES = [protocol.encode_frame(*command) for command in COMMANDS] + [bytes(DAMAGED)]

#: The data packet offered on the link's ``packets[0]`` once the replies have gone: type and
#: payload.
DATA = (PacketType.EVENTS, bytes(range(1, 13)))


def data_beats():
    """:data:`DATA` as PacketBeat values: the header beat, then a beat per payload byte."""
    type, payload = DATA
    header = {"type": type.value, "seq": 0, "length": len(payload)}
    yield {"header": header, "data": 0, "first": 1, "last": 0}
    for index, byte in enumerate(payload):
        yield {"header": header, "data": byte, "first": 0, "last": int(index == len(payload) - 1)}


def expected():
    """The command model's replies to :data:`FRAMES`, then :data:`DATA`, numbered from 0 by
    the link; and the counts of its commands and refusals."""
    model = CommandModel(CLOCK_HZ, BAUD)
    replies = [model.command(*command) for command in COMMANDS]
    replies.append(model.link_error(NakCode.BAD_CRC))
    replies.append(DATA)
    packets = [protocol.Packet(protocol.packet_type(type), seq, bytes(payload))
               for seq, (type, payload) in enumerate(replies)]
    return packets, model.commands, model.refused


def run_link(uart):
    """The packets the link sends for :data:`FRAMES` and :data:`DATA`, as the host decodes
    them, and the cycles in which each strobe of its tally was high."""
    dut = Link(clock_hz=CLOCK_HZ, baud=BAUD, sources=1, uart=uart)
    sent = bytearray()
    tx_line = []
    strobes = {name: 0 for name, _ in dut.tally.shape()}
    done = []

    async def host(ctx):
        if uart:
            for level, cycles in uart_model.line_runs(b"".join(FRAMES), CLOCK_HZ, BAUD):
                ctx.set(dut.rx, level)
                await ctx.tick().repeat(cycles)
        else:
            for byte in b"".join(FRAMES):
                await stream_put(ctx, dut.rx, byte)
        # The data packet once the three replies have left the arbiter
        await ctx.tick().repeat(3000 if uart else 300)
        for beat in data_beats():
            await stream_put(ctx, dut.packets[0], beat)
        await ctx.tick().repeat(3000 if uart else 300)
        done.append(True)

    async def watch(ctx):
        if uart:
            async for _, _, tx, tally in ctx.tick().sample(dut.tx, dut.tally):
                tx_line.append(tx)
                count(tally)
        else:
            ctx.set(dut.tx.ready, 1)
            async for _, _, valid, byte, tally in ctx.tick().sample(dut.tx.valid,
                                                                     dut.tx.payload, dut.tally):
                if valid:
                    sent.append(byte)
                count(tally)

    def count(tally):
        for name in strobes:
            strobes[name] += tally[name]

    simulate(dut, host, background=[watch], clock_hz=CLOCK_HZ)
    assert done
    if uart:
        received, framing_errors = uart_model.receive(tx_line, CLOCK_HZ, BAUD)
        assert framing_errors == []
        sent = bytes(byte for _, byte in received)
    decoder = protocol.FrameDecoder(synced=True)
    return decoder.feed(bytes(sent)), strobes


@pytest.mark.parametrize("uart", [False, True], ids=["streams", "uart"])
def test_link_answers_commands_then_sends_data(uart):
    packets, strobes = run_link(uart)
    want, commands, refused = expected()
    assert packets == want
    assert (commands, refused) == (4, 1)
    counted = {name: 0 for name in strobes}
    counted.update(commands=commands, refused=refused, bad_crc=1)
    assert strobes == counted
    assert set(strobes) == ({"uart_framing_errors", "uart_overruns"} if uart else set()) | \
        set(LINK_FIELDS) | {"commands", "refused"}


@pytest.mark.parametrize("kwargs, exception, message", [
    (dict(sources=-1), TypeError, "Source count must be a non-negative integer, not -1"),
    (dict(sources=1.0), TypeError, "Source count must be a non-negative integer, not 1.0"),
    (dict(uart=1), TypeError, "uart must be True or False, not 1"),
    (dict(baud=21_000_000), ValueError,
     "Baud rate 21000000 cannot be met within 2% from a 80000000 Hz clock: the closest is "
     "20000000 baud (-4.8%), as a bit lasts at least 4 cycles"),
])
def test_link_refuses(construction_error, kwargs, exception, message):
    assert construction_error(lambda: Link(**kwargs), exception) == message


def test_link_without_uart_takes_any_baud(construction_error):
    # (the baud rate is only reported in the identity then)
    assert construction_error(lambda: Link(baud=21_000_000, uart=False)) is None
