"""What the models, the scene, the study and the files say of a delay mode comes from its row of
the mode table (:data:`fliss.hdl.delay.modes.MODES`): changing a row changes them, and with the
table as it is they say what each mode is (worked out here from the modes' definitions)."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from fliss.hdl.delay.modes import MODES, DelayMode
from fliss.hdl.registers import defaults
from fliss.host.formats.metadata import settings as file_settings
from fliss.sim.models import delay as model
from fliss.sim.studies import interference


CLOCK_HZ = 80_000_000

#: The victim's registers of a capture: mseq L=5 seed 17 in the defaults, Wm 7, IV 0x1234.
REGISTERS = {**defaults(CLOCK_HZ), "length": 5, "mask_width": 7, "seed": 17, "iv0": 0x1234}


def _described(mode):
    """The delay settings a file's metadata gives for a capture in ``mode``."""
    capture = SimpleNamespace(configuration={**REGISTERS, "delay_mode": mode}, mode="raw",
                              clock_hz=CLOCK_HZ, code_s=50e-12, shift=0, attrs={}, path="x.h5")
    described = file_settings(capture)
    return {key: described[key] for key in described
            if key in ("delay_mode", "length", "mask_width", "seed", "iv")}


def test_files_describe_each_mode_by_what_it_reads():
    # off reads nothing; mseq L and its seed; masked Wm and its seed; keyed Wm and its IV
    # (never the key); a value that is no mode is unknown
    assert _described(0) == {"delay_mode": "off"}
    assert _described(1) == {"delay_mode": "mseq", "length": 5, "seed": 17}
    assert _described(2) == {"delay_mode": "masked", "mask_width": 7, "seed": 17}
    assert _described(3) == {"delay_mode": "keyed", "mask_width": 7,
                             "iv": "0x00000000000000001234"}


def test_files_follow_the_table(monkeypatch):
    # a masked source that took no seed would be described without one
    monkeypatch.setitem(MODES, DelayMode.MASKED,
                        dataclasses.replace(MODES[DelayMode.MASKED], seed_bits=None))
    assert _described(2) == {"delay_mode": "masked", "mask_width": 7}


def test_the_study_takes_every_mode_and_draws_seeds_as_wide_as_each_takes():
    assert interference.SCHEMES == ("off", "mseq", "masked", "keyed")
    point = interference.check_point({"length": 9, "mask_width": 4})
    # mseq: a state of its L-bit register; keyed: an 80-bit key; the others a 32-bit seed
    bits = {scheme: interference._seed_bits({**point, "scheme": scheme})
            for scheme in interference.SCHEMES}
    assert bits == {"off": 32, "mseq": 9, "masked": 32, "keyed": 80}


def test_the_study_follows_the_table(monkeypatch):
    # a masked source seeded with a Wm-bit state would have Wm-bit seeds drawn
    monkeypatch.setitem(MODES, DelayMode.MASKED,
                        dataclasses.replace(MODES[DelayMode.MASKED], seed_bits="mask_width"))
    point = interference.check_point({"scheme": "masked", "mask_width": 4, "victim_seed": 3})
    assert interference._seed_bits(point) == 4


@pytest.mark.parametrize("size", ["length", "mask_width"])
def test_the_study_refuses_sizes_out_of_the_tables_range(size):
    low = {"length": 2, "mask_width": 1}[size]
    high = {"length": 32, "mask_width": 16}[size]
    for bad in (low - 1, high + 1):
        with pytest.raises(ValueError, match=f"{size} must be an integer from {low} to {high}"):
            interference.check_point({size: bad})


@pytest.mark.parametrize("mode", list(DelayMode))
def test_the_scenes_delay_blocks_are_the_models_delays(mode):
    # The scene takes each source's delays block by block (a whole period at once when it is
    # short): the same sequence as the model's delays from the load.
    settings = dict(length=7, mask_width=5, seed=45, key=0x0123456789ABCDEF0123, iv=9)
    count = 3000
    stream = model.block_stream(mode, 700, **settings)
    if stream.table is not None:
        got = np.resize(stream.table, count)
    else:
        got = np.concatenate([stream.block() for _ in range(count // 700 + 1)])[:count]
    expected = model.delays(mode, count, **{name: settings[name] for name in
                                            ("length", "mask_width", "seed", "key", "iv")})
    assert np.array_equal(got, expected)
