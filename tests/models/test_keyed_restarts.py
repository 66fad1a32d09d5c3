"""The keyed source's restarts in the model: the IV counts up and never wraps around to 0 under
one key; after the last IV's keystream was used the source is spent (no delay, no pulse, STATUS
``ivs_used_up``) until a key is written. Expected values are worked out here from the rule, not
read from the model."""

import pytest

from fliss.hdl.protocol import PacketType, Status
from fliss.hdl.registers import BY_NAME
from fliss.protocol.layout import pack, unpack
from fliss.hdl.protocol import registers_layout
from fliss.sim.models import delay
from fliss.sim.models.command import CommandModel
from fliss.sim.models.scheduler import Settings, simulate


LAST = 2**80 - 1
KEY = 0x0123456789ABCDEF0123


@pytest.mark.parametrize("iv, following", [(0, 1), (41, 42), (2**32 - 1, 2**32),
                                           (LAST - 1, LAST), (LAST, None)])
def test_next_iv_never_wraps(iv, following):
    assert delay.next_iv(iv) == following


def test_restarts_stop_at_the_last_iv():
    restarts = delay.KeyedRestarts()
    restarts.write(key=KEY, iv=LAST - 1)
    steps = []
    for _ in range(3):
        initialises = restarts.load()
        steps.append((initialises, restarts.iv, restarts.spent))
        restarts.take(5)
    # LAST - 1 from the write, LAST from the IV in use plus one, then none: spent, the IV kept
    assert steps == [(True, LAST - 1, False), (True, LAST, False), (False, LAST, True)]
    assert (restarts.load(), restarts.load(keyed=False), restarts.spent) == (False, False, True)
    restarts.write(key=KEY + 1)        # a new key (the IV registers as they were)
    assert not restarts.spent
    assert (restarts.load(), restarts.iv, restarts.spent) == (True, LAST - 1, False)


def test_a_load_in_another_mode_spends_the_last_iv():
    # The board loads its source in every cycle while stopped, whatever its mode
    restarts = delay.KeyedRestarts()
    restarts.write(key=KEY, iv=LAST)
    assert restarts.load() and restarts.iv == LAST
    assert (restarts.load(keyed=False), restarts.spent) == (False, False)   # not used yet
    restarts.take(1)
    assert (restarts.load(keyed=False), restarts.spent) == (False, True)


def test_no_pulse_from_a_spent_source():
    # A run with the last IV fires; the next run under the same key fires nothing (not the
    # keystream of IV 0 again); one under a new key fires as a fresh source does.
    settings = Settings(mode="keyed", mask_width=3, period=10, key=KEY, iv=LAST).check()
    restarts = delay.KeyedRestarts()
    first = simulate(settings, 2000, restarts=restarts)
    assert len(first) > 100
    restarts.load()                     # stopped: the board loads its source
    assert restarts.spent
    assert simulate(settings, 2000, restarts=restarts) == []
    renewed = Settings(mode="keyed", mask_width=3, period=10, key=KEY + 1, iv=LAST).check()
    assert simulate(renewed, 2000, restarts=restarts) == \
        simulate(renewed, 2000, restarts=delay.KeyedRestarts())


def _write(name, *values):
    return PacketType.WRITE.value, 0, pack(registers_layout(len(values)),
                                           address=BY_NAME[name].address, values=list(values))


def _status(model):
    type, payload = model.command(PacketType.GET_STATUS.value, 0, b"")
    return unpack(Status, payload)["ivs_used_up"]


def test_command_model_reports_the_ivs_used_up():
    model = CommandModel(80_000_000, 3_000_000, keyed_source=True)
    words = [(LAST >> (32 * k)) & (2**32 - 1) for k in range(3)]
    key = [(KEY >> (32 * k)) & (2**32 - 1) for k in range(3)]
    assert model.command(*_write("iv0", *words, *key))[0] == PacketType.ACK
    assert model.command(*_write("delay_mode", 3))[0] == PacketType.ACK
    assert _status(model) == 0          # the last IV, not used yet
    for command in (PacketType.START, PacketType.STOP):
        assert model.command(command.value, 0, b"")[0] == PacketType.ACK
    assert _status(model) == 1
    assert model.no_pulses
    # No IV is above the last: an IV alone is refused; a key ends it
    assert model.command(*_write("iv0", 5, 0, 0))[0] == PacketType.NAK
    assert _status(model) == 1
    assert model.command(*_write("key0", 7))[0] == PacketType.ACK
    assert (_status(model), model.no_pulses) == (0, False)
