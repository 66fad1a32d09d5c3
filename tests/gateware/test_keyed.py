"""The keyed delay source: Trivium in gateware against the published vectors and the model, the
keyed delays bit for bit, the start bound and the IV rule."""

import numpy as np
import pytest

from fliss.hdl.delay.source import DelayMode, DelaySource
from fliss.hdl.delay.settings import KEYED_START_CYCLES
from fliss.hdl.delay.trivium import TriviumCore
from fliss.sim.models import delay as model
from fliss.sim.models import trivium
from simulation import simulate


#: eSTREAM Trivium test vectors, set 1 vector 0 (key 80 00 … 00, IV 0): keystream bytes 0 to 15.
SET_1_VECTOR_0 = bytes.fromhex("38EB86FF730D7A9CAF8DF13A4420540D")


def keying(key, iv):
    words = {}
    for name, value in (("key", key), ("iv", iv)):
        for k in range(3):
            words[f"{name}{k}"] = (value >> (32 * k)) & 0xFFFFFFFF
    return words


async def write_keying(ctx, dut, restarts, key, iv):
    """Write ``key`` and ``iv`` into the source ``dut`` (a cycle of ``rekey``) and into the
    model's ``restarts``."""
    for name, value in keying(key, iv).items():
        ctx.set(dut.keying[name], value)
    ctx.set(dut.rekey, 1)
    await ctx.tick()
    ctx.set(dut.rekey, 0)
    restarts.write(key=key, iv=iv)


async def take_delay(ctx, dut):
    """Take the delay on offer: ``ready`` for one cycle, then one cycle without."""
    ctx.set(dut.delays.ready, 1)
    await ctx.tick()
    ctx.set(dut.delays.ready, 0)
    await ctx.tick()


async def load_trivium(ctx, dut, key, iv):
    ctx.set(dut.key, key)
    ctx.set(dut.iv, iv)
    ctx.set(dut.load, 1)
    await ctx.tick()
    ctx.set(dut.load, 0)
    cycles = 0
    while not ctx.get(dut.ready):
        await ctx.tick()
        cycles += 1
    return cycles


@pytest.mark.parametrize("rounds", [1, 16, 64])
def test_trivium_core_published_vector(rounds):
    dut = TriviumCore(rounds=rounds)
    bits, waits = [], []

    async def testbench(ctx):
        waits.append(await load_trivium(ctx, dut, 0x80000000000000000000, 0))
        ctx.set(dut.next, 1)
        for _ in range(8 * len(SET_1_VECTOR_0) // rounds):
            z = ctx.get(dut.z)
            bits.extend((z >> i) & 1 for i in range(rounds))
            await ctx.tick()

    simulate(dut, testbench)
    assert np.packbits(bits, bitorder="little").tobytes() == SET_1_VECTOR_0
    assert waits == [1152 // rounds]


def test_trivium_core_against_model_with_pauses():
    # Random keys and IVs, `next` from a PRBS, a reload in the middle of a stream.
    dut = TriviumCore(rounds=16)
    rng = np.random.default_rng(14)
    errors, compared = [], [0]

    async def testbench(ctx):
        for _ in range(4):
            key, iv = (int.from_bytes(rng.bytes(10), "big") for _ in range(2))
            await load_trivium(ctx, dut, key, iv)
            expected = trivium.Trivium(key, iv)
            for _ in range(40):
                step = bool(rng.integers(0, 2))
                ctx.set(dut.next, step)
                if step:
                    z = ctx.get(dut.z)
                    want = expected.bits(16)
                    compared[0] += 16
                    if [(z >> i) & 1 for i in range(16)] != want.tolist():
                        errors.append((key, iv))
                await ctx.tick()
            ctx.set(dut.next, 0)

    simulate(dut, testbench)
    assert errors == [] and compared[0] > 1000


def test_trivium_core_bad_rounds(construction_error):
    assert construction_error(lambda: TriviumCore(rounds=5)) == \
        "Trivium rounds per cycle must be a divisor of 1152 from 1 to 64, not 5"


def test_keyed_source_against_model():
    # Every mask width; transfers as close as the scheduler makes them (every other cycle) or
    # from a PRBS; a key or IV write (`rekey`) or a used stream makes a load initialise again
    # with the IV the model's restart rule gives, and `busy` is high for the bound and no more.
    dut = DelaySource()
    rng = np.random.default_rng(0x14)
    restarts = model.KeyedRestarts()
    errors, compared, waits = [], [0], []

    async def testbench(ctx):
        key, iv = 0x80000000000000000000, 0
        for case in range(24):
            width = case % 16 + 1
            if case % 3 == 0:
                key, iv = (int.from_bytes(rng.bytes(10), "big") for _ in range(2))
                await write_keying(ctx, dut, restarts, key, iv)
            ctx.set(dut.settings.mode, DelayMode.KEYED)
            ctx.set(dut.settings.mask_width, width)
            for _ in range(2 if case % 4 == 1 else 1):  # (a second load finds it fresh)
                ctx.set(dut.load, 1)
                initialises = restarts.load()
                await ctx.tick()
                ctx.set(dut.load, 0)
                busy = 0            # cycles from the load to the first not busy
                while ctx.get(dut.busy):
                    busy += 1
                    await ctx.tick()
                busy += busy > 0
                waits.append(busy)
                if initialises != (busy > 0):
                    errors.append(("busy", case, busy))
            if ctx.get(dut.iv) != restarts.iv:
                errors.append(("iv", case, ctx.get(dut.iv), restarts.iv))
            expected = model.delays("keyed", 300, mask_width=width, key=key, iv=restarts.iv)
            dense = case % 2 == 0
            await ctx.tick()
            for index in range(300):
                if ctx.get(dut.busy) or ctx.get(dut.delays.payload.value) != expected[index]:
                    errors.append(("delay", case, index))
                zero = ctx.get(dut.delays.payload.zero)
                if index and zero != (expected[index] == 0):
                    errors.append(("zero", case, index))
                compared[0] += 1
                await take_delay(ctx, dut)
                if not dense:
                    for _ in range(int(rng.integers(0, 3))):
                        await ctx.tick()
            restarts.take(300)

    simulate(dut, testbench, clock_hz=100e6)
    assert errors == []
    assert compared[0] == 24 * 300
    # The load that initialises and the `KEYED_START_CYCLES - 1` after it; none without one.
    assert sorted(set(waits)) == [0, KEYED_START_CYCLES]


def test_keyed_source_never_wraps_the_iv():
    # From the IV 2**80 - 2: one initialisation with it, one with the last IV; the load after
    # delays were taken from the last IV's keystream does not initialise (with IV 0, reused
    # under the key) but leaves the source spent: `busy` for good in keyed mode, no delay, the
    # IV in use stays the last. A load in another mode keeps it spent, and so does one in keyed
    # mode again; a new key (`rekey`) ends it, and the next load initialises with its IV. A
    # load in another mode after the last IV's keystream was used spends the source too.
    # Each step against the model's restarts (`spent`, IV in use, initialisation) and delays.
    dut = DelaySource()
    restarts = model.KeyedRestarts()
    last = (1 << 80) - 1
    errors, compared = [], [0]

    async def write(ctx, key, iv):
        await write_keying(ctx, dut, restarts, key, iv)

    async def load(ctx, step, mode):
        ctx.set(dut.settings.mode, mode)
        ctx.set(dut.load, 1)
        initialises = restarts.load(keyed=mode == DelayMode.KEYED)
        await ctx.tick()
        ctx.set(dut.load, 0)
        busy = 0                    # cycles busy in the 200 after the load
        for _ in range(200):
            busy += ctx.get(dut.busy)
            await ctx.tick()
        keyed_now = mode == DelayMode.KEYED
        expected_busy = (200 if restarts.spent else
                         KEYED_START_CYCLES - 1 if initialises else 0) if keyed_now else 0
        state = (busy, ctx.get(dut.spent), ctx.get(dut.iv))
        if state != (expected_busy, int(restarts.spent), restarts.iv):
            errors.append((step, state, (expected_busy, restarts.spent, restarts.iv)))

    async def take(ctx, step, count=20):
        expected = model.delays("keyed", count, mask_width=4, key=restarts.key, iv=restarts.iv)
        for index in range(count):
            if ctx.get(dut.delays.payload.value) != expected[index]:
                errors.append(("delay", step, index))
            compared[0] += 1
            await take_delay(ctx, dut)
        restarts.take(count)

    async def testbench(ctx):
        ctx.set(dut.settings.mask_width, 4)
        ctx.set(dut.settings.seed, 1)
        ctx.set(dut.settings.length, 5)
        await write(ctx, 0x0123456789ABCDEF0123, last - 1)
        await load(ctx, "last - 1", DelayMode.KEYED)
        await take(ctx, "last - 1")
        await load(ctx, "last", DelayMode.KEYED)
        await take(ctx, "last")
        await load(ctx, "spent", DelayMode.KEYED)
        await load(ctx, "spent, masked", DelayMode.MASKED)
        await load(ctx, "spent, keyed again", DelayMode.KEYED)
        await write(ctx, 0x42, 7)
        if ctx.get(dut.spent) or restarts.spent:
            errors.append(("spent after a new key", ctx.get(dut.spent), restarts.spent))
        await load(ctx, "new key", DelayMode.KEYED)
        await take(ctx, "new key")
        await write(ctx, 0x43, last)
        await load(ctx, "last, new key", DelayMode.KEYED)
        await take(ctx, "last, new key")
        await load(ctx, "spent by a masked load", DelayMode.MASKED)
        await load(ctx, "spent, keyed", DelayMode.KEYED)

    simulate(dut, testbench, clock_hz=100e6)
    assert errors == []
    assert compared[0] == 4 * 20
    assert restarts.spent and restarts.iv == last and restarts.key == 0x43


def test_keyed_mode_name():
    assert model.parse_mode("keyed") == DelayMode.KEYED
    with pytest.raises(ValueError, match=r"^The keyed delay source needs a key and an IV$"):
        model.check_settings("keyed", mask_width=4)
    with pytest.raises(ValueError, match=r"^A Trivium key must be an 80-bit integer "
                                         r"\(0 to 2\*\*80 - 1\), not 0x100000000000000000000$"):
        model.check_settings("keyed", mask_width=4, key=1 << 80, iv=0)


CORE_FIELDS = ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width")


def run_core(first, updates, cycles):
    """A :class:`DelayCore` enabled from cycle 0 with settings ``first`` (key and IV written,
    ``rekey``, the cycle before), then ``updates`` ``(cycle, Settings)`` (a new key or IV
    written in the cycle before its update): the pulses fired ``(cycle, delay, index)`` and
    ``spent`` at the end; and the model's pulses and :class:`KeyedRestarts` after them."""
    from fliss.hdl.delay.core import DelayCore
    from fliss.sim.models.scheduler import LATENCY, simulate as schedule
    dut = DelayCore()
    pulses, spent = [], []

    def present(ctx, settings):
        for name in CORE_FIELDS:
            ctx.set(dut.settings[name], getattr(settings, name))
        for name, value in keying(settings.key, settings.iv).items():
            ctx.set(dut.keying[name], value)

    async def testbench(ctx):
        present(ctx, first)
        ctx.set(dut.rekey, 1)
        await ctx.tick()
        ctx.set(dut.rekey, 0)
        by_cycle = dict(updates)
        current = first
        for cycle in range(cycles):
            ctx.set(dut.enable, 1)
            ctx.set(dut.update, cycle in by_cycle)
            ctx.set(dut.rekey, 0)
            if cycle in by_cycle:
                present(ctx, by_cycle[cycle])
            if cycle + 1 in by_cycle:
                new = by_cycle[cycle + 1]
                if (new.key, new.iv) != (current.key, current.iv):
                    for name, value in keying(new.key, new.iv).items():
                        ctx.set(dut.keying[name], value)
                    ctx.set(dut.rekey, 1)
                current = new
            if ctx.get(dut.fire):
                pulses.append((cycle, ctx.get(dut.fire_delay), ctx.get(dut.pulse_index)))
            await ctx.tick()
        spent.append(ctx.get(dut.spent))

    simulate(dut, testbench, clock_hz=80e6)
    restarts = model.KeyedRestarts()
    restarts.write(key=first.key, iv=first.iv)
    expected = [(f, d, i) for f, d, _, i in schedule(first, cycles - 1 - LATENCY, enable=0,
                                                     updates=updates, restarts=restarts)]
    return pulses, spent[0], expected, restarts


def test_delay_core_keyed_updates_against_model():
    # Random updates, half of them keyed, some with a new key or IV (written, `rekey`, in the
    # cycle before the update): every pulse's fire cycle, delay and index against the model,
    # which stops a run while the keystream initialises and starts it again.
    import random
    from fliss.sim.models.scheduler import Settings
    rng = random.Random(1414)
    key, iv = 0x0123456789ABCDEF0123, 0x00000000000000000007
    first = Settings(mode=DelayMode.KEYED, mask_width=4, period=12, pulse_width=2, key=key,
                     iv=iv).check()
    updates, cycle = [], 0
    for _ in range(60):
        cycle += rng.randrange(2, 600)
        mode = rng.choice([DelayMode.KEYED] * 3 + [DelayMode.OFF, DelayMode.MSEQ,
                                                   DelayMode.MASKED])
        if rng.random() < 0.3:
            key, iv = rng.getrandbits(80), rng.getrandbits(80)
        updates.append((cycle, Settings(
            mode=mode, length=rng.choice([3, 4]), mask_width=rng.randrange(1, 8),
            seed=rng.randrange(1, 8), period=rng.randrange(2, 40), grid=False,
            pulse_width=1, key=key, iv=iv).check()))
    pulses, _, expected, _ = run_core(first, updates, cycle + 400)
    assert pulses[:len(expected)] == expected
    assert len(expected) > 500, len(expected)


def test_delay_core_stops_at_the_last_iv():
    # Keyed updates without a new key move the IV on by one: from 2**80 - 3 to the last, then
    # the next finds no IV left and the run stops (no pulse, no IV 0 again under the key); an
    # update to masked mode runs, one back to keyed stops again, and a new key starts it; the
    # pulses against the model, cycle for cycle, and `spent` with it.
    from fliss.sim.models.scheduler import Settings
    key, last = 0x0123456789ABCDEF0123, (1 << 80) - 1

    def keyed(key=key, iv=last - 2):
        return Settings(mode=DelayMode.KEYED, mask_width=3, period=9, pulse_width=1, key=key,
                        iv=iv).check()

    masked = Settings(mode=DelayMode.MASKED, mask_width=3, seed=5, period=9, pulse_width=1,
                      key=key, iv=last - 2).check()
    steps = [keyed(), keyed(), keyed(), masked, keyed(), keyed(key=0x42, iv=3)]
    updates = [(400 * (k + 1), settings) for k, settings in enumerate(steps)]
    pulses, spent, expected, restarts = run_core(keyed(), updates, 400 * (len(steps) + 1))
    assert pulses == expected
    assert (spent, restarts.spent) == (0, False)
    # (a pulse may fire in an update's cycle, none after it until the run starts again)
    fired = [sum(1 for f, _, _ in pulses if 400 * k < f <= 400 * (k + 1))
             for k in range(len(steps) + 1)]
    # IVs last - 2, last - 1, last: pulses; then none; masked: pulses; none; the new key: pulses
    assert [n > 20 for n in fired] == [True, True, True, False, True, False, True], fired
    assert [n == 0 for n in fired] == [False, False, False, True, False, True, False], fired
    assert restarts.key == 0x42 and restarts.iv == 3
    # Ended while spent: `spent` high, as in the model
    pulses, spent, expected, restarts = run_core(keyed(), updates[:3], 400 * 4)
    assert pulses == expected
    assert (spent, restarts.spent, restarts.iv) == (1, True, last)


def test_key_write_only_and_iv_rule(monkeypatch):
    # The command processor with an IV in use of 0x1234 (from a keyed source): the key reads 0,
    # the IV reads the IV in use; an IV written without the key must go above it; with a key,
    # any IV goes. The model (and the Python rule) say the same.
    import test_command
    from fliss.hdl.link.command import CommandProcessor
    from fliss.hdl.protocol import PacketType, ReadRequest, registers_layout
    from fliss.hdl.registers import BY_NAME, iv_problem
    from fliss.protocol.layout import pack, unpack

    in_use = 0x1234

    class KeyedCommandProcessor(CommandProcessor):
        def elaborate(self, platform):
            m = super().elaborate(platform)
            m.d.comb += self.registers.iv.eq(in_use)
            return m

    monkeypatch.setattr(test_command, "CommandProcessor", KeyedCommandProcessor)
    iv0, key0 = BY_NAME["iv0"].address, BY_NAME["key0"].address
    writes = [
        (test_command._write(iv0, 0x1234, 0, 0), False),                    # = in use
        (test_command._write(iv0, 0x1233, 0, 0), False),                    # below
        (test_command._write(iv0, 0, 1, 0), True),                          # above
        (test_command._write(iv0, 7, 0, 0, 0xDEAD, 0xBEEF, 0x80), True),    # with a key
        (test_command._write(iv0 + 2, 0), False),                           # high word only
        (test_command._write(key0 + 1, 5), True),                           # key alone
    ]
    packets = [(PacketType.WRITE.value, n, payload) for n, (payload, _) in enumerate(writes)]
    packets.append((PacketType.READ.value, 9, pack(ReadRequest, address=iv0, count=6)))
    replies, settings, _ = test_command.run_commands(packets)
    assert [type == PacketType.ACK.value for type, _ in replies[:-1]] == \
        [accepted for _, accepted in writes]
    values = unpack(registers_layout(6), replies[-1][1])["values"]
    assert values == [0x1234, 0, 0, 0, 0, 0]
    assert [settings[-1][f"key{k}"] for k in range(3)] == [0xDEAD, 5, 0x80]
    # The Python rule, on the same writes
    names = [r.name for r in sorted(BY_NAME.values(), key=lambda r: r.address)]
    for payload, accepted in writes:
        decoded = unpack(registers_layout(0), payload[:2])
        words = [int.from_bytes(payload[2 + 4 * k:6 + 4 * k], "little")
                 for k in range((len(payload) - 2) // 4)]
        written = names[decoded["address"]:decoded["address"] + len(words)]
        values = {**dict.fromkeys(names, 0), **dict(zip(written, words))}
        assert (iv_problem(written, values, in_use) is None) == accepted, written
