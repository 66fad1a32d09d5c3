"""The register map's rows (hdl/registers.py ROWS) as the host reads them: reset quantities
written once and said in units, every register with a display, and the range a smaller
maximum leaves checked before anything is written."""

import pytest

from fliss.hdl.register_rows import Hertz, Seconds
from fliss.hdl.registers import BY_NAME, REGISTERS, ROWS, defaults
from fliss.host.commands.config import describe
from fliss.host.errors import SettingsError
from fliss.host.settings import BY_OPTION, convert


@pytest.mark.parametrize("quantity, text, clock_hz, cycles", [
    (Seconds(10e-3), "10 ms", 80_000_000, 800_000),      # 10 ms of 12.5 ns cycles
    (Seconds(10e-3), "10 ms", 36_000_000, 360_000),
    (Seconds(75e-9), "75 ns", 80_000_000, 6),            # 6 cycles of 12.5 ns
    (Seconds(75e-9), "75 ns", 36_000_000, 3),            # 2.7 cycles of 27.8 ns -> 3
    (Seconds(2.5e-6), "2.5 µs", 80_000_000, 200),
    (Hertz(1e6), "1 MHz", 80_000_000, 80),               # 1 µs of 12.5 ns cycles
    (Hertz(1e6), "1 MHz", 36_000_000, 36),
    (Hertz(250e3), "250 kHz", 80_000_000, 320),
])
def test_reset_quantities(quantity, text, clock_hz, cycles):
    assert str(quantity) == text
    assert quantity(clock_hz) == cycles


def test_the_defaults_are_said_where_they_are_written():
    # 10 ms, 75 ns and 1 MHz: each written once, in its row, and said in the meaning and help
    assert BY_NAME["integration"].doc == "histogram integration time (10 ms by default)"
    assert BY_NAME["aggressor_offset"].doc.endswith("(75 ns by default)")
    assert BY_NAME["period"].doc == "nominal laser period T (1 MHz PRF by default)"
    assert "(10ms)" in BY_OPTION["integration"].help
    assert "(75ns)" in BY_OPTION["aggressor_offset"].help
    assert "(1MHz)" in BY_OPTION["prf"].help


def test_every_register_is_in_one_row_and_shown():
    assert sorted(row.name for row in ROWS) == sorted(r.name for r in REGISTERS)
    registers = defaults(80_000_000)
    for register in REGISTERS:
        assert isinstance(describe(register.name, registers[register.name], registers,
                                   80_000_000), str)


@pytest.mark.parametrize("name, value, shown", [
    ("integration", 800_000, "10 ms"),
    ("period", 80, "1 µs (1 MHz)"),
    ("fine_lsb", 1, "25ps"),
    ("tdc_input", 1, "oscillator"),
    ("delay_mode", 3, "keyed"),
    ("collisions", 1, "drop (counted)"),
    ("seed", 0xACE1, "0xace1"),
    ("key1", 0, "write-only"),
])
def test_config_shows_each_kind(name, value, shown):
    registers = {**defaults(80_000_000), name: value}
    assert describe(name, value, registers, 80_000_000) == shown


def test_a_choice_above_a_smaller_range_is_refused_before_writing():
    # The aggressor has no keyed source: its mode register goes to 2 (masked), though its
    # choices name every mode.
    with pytest.raises(SettingsError) as error:
        convert({"aggressor_mode": "keyed"}, 80_000_000, defaults(80_000_000), style="flag")
    assert str(error.value) == "Register aggressor_delay_mode takes values from 0 to 2, not 3"
