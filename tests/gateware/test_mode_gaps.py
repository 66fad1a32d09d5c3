"""A delay core lacks the modes that need a key when it has no keyed source (the aggressor's; the
victim's in a build without ``keyed``). While those modes are the last, the ``mode`` register's
maximum refuses them; a mode that needs no key numbered after them would leave a gap below the
maximum, which the register checks (Python and gateware) must refuse by themselves.

No such mode exists, so a gap is made here by marking ``mseq`` (1) as needing a key: a core
without the keyed source then has ``off`` and ``masked`` (maximum 2) and lacks 1.
"""

import dataclasses

import pytest

from fliss.hdl.delay import modes
from fliss.hdl.delay.modes import MODES, DelayMode, delay_problems
from fliss.hdl.regfile import RegisterFile
from fliss.hdl.registers import BY_NAME, KEYING, defaults, problems
from simulation import simulate


CLOCK_HZ = 80_000_000

#: A delay core's settings that every check passes in mseq mode (seed below 2**5).
GOOD = dict(mode=DelayMode.MSEQ.value, length=5, mask_width=6, seed=17, period=40, grid=0,
            pulse_width=2)


@pytest.fixture
def gap(monkeypatch):
    """The table with mseq marked as needing a key (a gap at 1 for cores without one)."""
    monkeypatch.setitem(MODES, DelayMode.MSEQ,
                        dataclasses.replace(MODES[DelayMode.MSEQ], keyed=True))


def test_without_a_gap_no_mode_is_missing():
    # off, mseq and masked need no key, keyed (the last) does: nothing lies below a maximum
    assert modes.mode_maximum(keyed=True) == 3
    assert modes.mode_maximum(keyed=False) == 2
    assert modes.missing_modes(keyed=False) == modes.missing_modes(keyed=True) == ()
    assert BY_NAME["aggressor_delay_mode"].maximum == 2
    assert BY_NAME["delay_mode"].maximum == 3


def test_a_gap_is_missing_below_the_maximum(gap):
    assert [row.name for row in modes.core_modes(keyed=False)] == ["off", "masked"]
    assert modes.mode_maximum(keyed=False) == 2
    assert [row.name for row in modes.missing_modes(keyed=False)] == ["mseq"]
    assert modes.missing_modes(keyed=True) == ()


def test_the_python_checks_refuse_a_missing_mode(gap):
    assert delay_problems(GOOD, ranges=False) == []
    assert delay_problems(GOOD, ranges=False, keyed=False) == [
        "mode (1) is the mseq mode, which this delay core has not (it has no keyed source)"]
    # the register map: the aggressor never has it, the victim only in a build with the keyed
    # source
    values = {**defaults(CLOCK_HZ), "delay_mode": 2, "aggressor_delay_mode": 1,
              "aggressor_seed": 5}
    assert problems(values) == problems(values, keyed=False) == [
        "aggressor_delay_mode (1) is the mseq mode, which this delay core has not (it has no "
        "keyed source)"]
    values = {**defaults(CLOCK_HZ), "delay_mode": 1, "seed": 5}
    assert problems(values) == []
    assert problems(values, keyed=False) == [
        "delay_mode (1) is the mseq mode, which this delay core has not (it has no keyed "
        "source)"]


def _consistent(dut, writes):
    """Whether the register file finds each WRITE (start address, values) consistent."""
    results = []

    async def testbench(ctx):
        for address, values in writes:
            ctx.set(dut.begin, 1)
            await ctx.tick()
            ctx.set(dut.begin, 0)
            ctx.set(dut.start, 1)
            ctx.set(dut.start_address, address)
            await ctx.tick()
            ctx.set(dut.start, 0)
            for value in values:
                ctx.set(dut.value, value)
                await ctx.tick()
                ctx.set(dut.check, 1)
                await ctx.tick()
                ctx.set(dut.check, 0)
            await ctx.tick().repeat(5)
            assert not ctx.get(dut.error)
            results.append(bool(ctx.get(dut.consistent)))

    simulate(dut, testbench)
    return results


#: WRITEs of a delay core's mode, length, mask width and seed: the aggressor's in mseq and
#: masked, the victim's in mseq and masked.
WRITES = [(BY_NAME["aggressor_delay_mode"].address, [1, 6, 6, 5]),
          (BY_NAME["aggressor_delay_mode"].address, [2, 6, 6, 5]),
          (BY_NAME["delay_mode"].address, [1, 5, 6, 17]),
          (BY_NAME["delay_mode"].address, [2, 5, 6, 17])]

#: The maxima of a build without the keyed source: no key or IV, the victim's modes as the
#: aggressor's.
UNKEYED = {"delay_mode": 2, **{register.name: 0 for register in KEYING.members}}


@pytest.mark.parametrize("maxima, writes, expected", [
    # the victim has the keyed source: only the aggressor lacks mseq
    (None, WRITES, [False, True, True, True]),
    # neither core has it (the aggressor's WRITEs are left out: the victim's reset mode, mseq,
    # is missing here, so that they would be refused for it)
    (UNKEYED, WRITES[2:], [False, True]),
])
def test_the_register_file_refuses_a_missing_mode(gap, maxima, writes, expected):
    assert _consistent(RegisterFile(clock_hz=CLOCK_HZ, maxima=maxima), writes) == expected


def test_without_a_gap_the_register_file_takes_those_writes():
    # (the writes themselves are consistent: only the gap refuses them above)
    assert _consistent(RegisterFile(clock_hz=CLOCK_HZ, maxima=UNKEYED), WRITES) == [True] * 4
