"""Settings with units (host/settings.py): conversions against hand-worked values."""

import numpy as np
import pytest

from fliss.hdl.registers import BY_NAME, REGISTERS, defaults
from fliss.hdl.delay.modes import DelayMode
from fliss.host.errors import BoardError, SettingsError
from fliss.host.settings import OPTIONS, convert, describe


CLOCK_HZ = 80_000_000           # 12.5 ns a cycle
ICE_HZ = 36_000_000             # the iCEBreaker's clock: 27.78 ns a cycle


def changes(settings, clock_hz=CLOCK_HZ, **kw):
    result = convert(settings, clock_hz, defaults(clock_hz), **kw)
    return result.changes, result.notes


# Hand-worked: 80 ns / 12.5 ns = 6.4 -> 6 cycles = 75 ns; 20 ns / 12.5 ns = 1.6 -> 2 = 25 ns;
# 80 MHz / 3 MHz = 26.67 -> 27 cycles = 2.963 MHz; 10 ms = 800 000 cycles exactly.
@pytest.mark.parametrize("name, value, register, expected, note", [
    ("aggressor_offset", "80ns", "aggressor_offset", 6,
     "--aggressor-offset 80ns is 6.4 clock cycles of 12.5 ns: using 6 cycles, 75 ns"),
    ("pulse_width", "20ns", "pulse_width", 2,
     "--pulse-width 20ns is 1.6 clock cycles of 12.5 ns: using 2 cycles, 25 ns"),
    ("prf", "3MHz", "period", 27,
     "--prf 3MHz is a period of 26.67 clock cycles: using 27 cycles, 2.963 MHz"),
    ("integration", "10ms", "integration", 800_000, None),
    ("integration", "2.5 us", "integration", 200, None),
    ("integration", "800cycles", "integration", 800, None),
    ("integration", "800 cycles", "integration", 800, None),
    ("prf", "500kHz", "period", 160, None),
    ("prf", "250e3Hz", "period", 320, None),
    ("period_cycles", "0x50", "period", 80, None),
    ("aggressor_prf", "1.1MHz", "aggressor_period", 73,
     "--aggressor-prf 1.1MHz is a period of 72.73 clock cycles: using 73 cycles, 1.096 MHz"),
    # Sensor TDC codes are 50 ps: 100 ns = 2000 codes, 100.01 ns = 2000.2 -> 2000.
    ("gate_end", "100ns", "gate_end", 2000, None),
    ("gate_end", "100.01ns", "gate_end", 2000,
     "--gate-end 100.01ns is 2000 codes of 50 ps: using 2000 codes, 100 ns"),
    ("gate_start", "0ns", "gate_start", 0, None),
    ("gate_start", "37codes", "gate_start", 37, None),
    ("mode", "masked", "delay_mode", DelayMode.MASKED.value, None),
    ("mode", "MSEQ", "delay_mode", DelayMode.MSEQ.value, None),
    ("aggressor_mode", "off", "aggressor_delay_mode", DelayMode.OFF.value, None),
    ("readout", "raw", "acquisition", 1, None),
    ("scheduler", "grid", "grid", 1, None),
    ("tdc", "coarse", "tdc_source", 1, None),
    ("aggressor", "on", "aggressor", 1, None),
    ("mask_width", 5, "mask_width", 5, None),
    ("seed", "0x2b", "seed", 0x2B, None),
])
def test_conversion(name, value, register, expected, note):
    got, notes = changes({name: value}, style="flag")
    assert got == {register: expected}
    assert notes == ([note] if note else [])


def test_other_clock():
    # 36 MHz: 75 ns is 2.7 cycles -> 3 = 83.33 ns; 1 MHz is 36 cycles exactly.
    got, notes = changes({"aggressor_offset": "75ns", "prf": "1MHz", "integration": "10ms"},
                         ICE_HZ)
    assert got == {"aggressor_offset": 3, "period": 36, "integration": 360_000}
    assert notes == ["aggressor_offset='75ns' is 2.7 clock cycles of 27.78 ns: using 3 cycles, "
                     "83.33 ns"]


def test_gate_follows_the_tdc_source_given_with_it():
    # The coarse TDC counts clock cycles: 100 ns = 8 codes, whatever the order given.
    got, _ = changes({"gate_end": "100ns", "tdc": "coarse"})
    assert got == {"gate_end": 8, "tdc_source": 1}


def test_enum_members_are_taken():
    got, _ = changes({"mode": DelayMode.MASKED})
    assert got == {"delay_mode": DelayMode.MASKED.value}


@pytest.mark.parametrize("settings, flag, keyword", [
    ({"integration": 10}, "--integration 10: give a unit: 10ms, or 800cycles",
     "integration=10: give a unit: 10ms, or 800cycles"),
    ({"integration": "10"}, "--integration 10: give a unit: 10ms, or 800cycles",
     "integration='10': give a unit: 10ms, or 800cycles"),
    ({"pulse_width": 2.5e-8}, "--pulse-width 2.5e-08: give a unit: 10ms, or 800cycles",
     "pulse_width=2.5e-08: give a unit: 10ms, or 800cycles"),
    ({"gate_end": "100"}, "--gate-end 100: give a unit: 100ns, or 2000codes",
     "gate_end='100': give a unit: 100ns, or 2000codes"),
    ({"mask_width": 17}, "--mask-width 17: takes values from 1 to 16 bits",
     "mask_width=17: takes values from 1 to 16 bits"),
    ({"mask_width": True}, "--mask-width True: expected a whole number",
     "mask_width=True: expected a whole number"),
    ({"mode": "random"}, "--mode random: choose one of off, mseq, masked",
     "mode='random': choose one of off, mseq, masked"),
    ({"integration": "1ps"}, "--integration 1ps: shorter than one clock cycle (12.5 ns)",
     "integration='1ps': shorter than one clock cycle (12.5 ns)"),
    # 2**16 - 1 = 65535 cycles of pulse width at most: 819.2 µs.
    ({"pulse_width": "1ms"}, "--pulse-width 1ms: takes values from 1 cycles (12.5 ns) to "
     "65535 cycles (819.2 µs), not 80000 cycles (1 ms)", None),
    ({"prf": "100MHz"}, "--prf 100MHz: too high for the board's 80 MHz clock: the period must be "
     "at least 2 cycles", None),
    ({"prf": "1MHz", "period_cycles": 80}, "--prf and --period-cycles both set period: give one "
     "of them", "prf and period_cycles both set period: give one of them"),
    ({"mask_widht": 6}, None, "no setting named 'mask_widht'"),
    # 2 µs = 160 cycles against the default period of 80 cycles (1 µs).
    ({"pulse_width": "2us"}, "--pulse-width (2 µs, 160 cycles) must be shorter than --prf "
     "(1 µs, 80 cycles)", "pulse_width (2 µs, 160 cycles) must be shorter than prf "
     "(1 µs, 80 cycles)"),
    ({"pulse_width": "2us", "period_cycles": 100}, "--pulse-width (2 µs, 160 cycles) must be "
     "shorter than --period-cycles (1.25 µs, 100 cycles)", None),
    # 4000 codes of 50 ps = 200 ns after 2000 codes = 100 ns.
    ({"gate_start": "200ns", "gate_end": "100ns"}, "--gate-start (200 ns, 4000 codes) must not "
     "be after --gate-end (100 ns, 2000 codes)", "gate_start (200 ns, 4000 codes) must not be "
     "after gate_end (100 ns, 2000 codes)"),
    ({"mode": "mseq", "length": 4, "seed": 16}, "--seed must be below 2**length = 16 for the "
     "mseq source", None),
])
def test_refusals_name_the_setting(settings, flag, keyword):
    for style, message in (("flag", flag), ("keyword", keyword)):
        if message is None:
            continue
        with pytest.raises(SettingsError) as info:
            convert(settings, CLOCK_HZ, defaults(CLOCK_HZ), style=style)
        assert str(info.value).startswith(message)
        assert isinstance(info.value, BoardError) and isinstance(info.value, ValueError)


def test_settings_read_back_in_units():
    registers = dict(defaults(CLOCK_HZ), delay_mode=2, period=27, integration=12345,
                     aggressor_offset=6, gate_end=2000, bin_shift=2, grid=1)
    shown = describe(registers, CLOCK_HZ)
    assert shown["mode"] == "masked"
    assert shown["prf"] == "2.96296296296 MHz"            # 80 MHz / 27
    assert shown["integration"] == "154.3125 µs"          # 12345 x 12.5 ns
    assert shown["aggressor_offset"] == "75 ns"
    assert shown["gate_end"] == "100 ns"
    assert shown["scheduler"] == "grid"
    assert set(shown) == {option.name for option in OPTIONS if option.shown}
    # One setting per register, but the key (write-only, never shown) and the IV (one setting
    # for its three registers).
    assert len(shown) == len([register for register in REGISTERS if not register.write_only
                              and register.name not in ("iv1", "iv2")])
    # bin_shift 2: bins of 4 codes of 50 ps, centres at 100 ps, 300 ps, ...
    assert shown.bins == 2048 and shown.bin_s == pytest.approx(200e-12)
    np.testing.assert_allclose(shown.time_s[:3], [100e-12, 300e-12, 500e-12])
    assert shown.integration_s == pytest.approx(154.3125e-6)


@pytest.mark.parametrize("clock_hz", [CLOCK_HZ, ICE_HZ, 100_000_000])
def test_settings_convert_back_to_the_same_registers(clock_hz):
    rng = np.random.default_rng(clock_hz)
    for _ in range(200):
        registers = defaults(clock_hz)
        for name in ("period", "aggressor_period", "integration", "aggressor_offset"):
            register = BY_NAME[name]
            registers[name] = int(rng.integers(max(register.minimum, 2), 1 << 31))
        registers["pulse_width"] = int(rng.integers(1, 1 << 16))
        registers["period"] = max(registers["period"], registers["pulse_width"] + 1)
        registers["tdc_source"] = int(rng.integers(0, 2))
        registers["gate_start"], registers["gate_end"] = sorted(rng.integers(0, 8192, 2).tolist())
        result = convert(describe(registers, clock_hz), clock_hz, defaults(clock_hz))
        assert result.notes == []
        assert result.registers == registers


def test_key_and_iv_are_one_setting_each():
    current = defaults(CLOCK_HZ)
    result = convert({"key": "80 00 00 00 00 00 00 00 00 00", "iv": "0x1_0000_0005"}, CLOCK_HZ,
                     current)
    # 80-bit values in 32-bit words, least significant first
    assert result.changes == {"key0": 0, "key1": 0, "key2": 0x8000, "iv0": 5, "iv1": 1, "iv2": 0}
    randoms = [convert({"key": "random"}, CLOCK_HZ, current).changes for _ in range(2)]
    assert randoms[0] != randoms[1] and set(randoms[0]) == {"key0", "key1", "key2"}
    with pytest.raises(SettingsError) as error:
        convert({"key": "zz"}, CLOCK_HZ, current)
    assert str(error.value) == ("key='zz': A Trivium key is 20 hex digits (80 bits, as the test "
                                "vectors print it) or random, not 'zz'")
    # Under one key the IV only goes up; the IV in use again writes nothing.
    in_use = dict(current, iv0=7)
    assert convert({"iv": "7"}, CLOCK_HZ, in_use).changes == {}
    with pytest.raises(SettingsError, match=r"^iv: the IV \(0x00000000000000000006\) must be "
                                            r"above the IV in use"):
        convert({"iv": "6"}, CLOCK_HZ, in_use)
    assert convert({"iv": "6", "key": "0" * 19 + "1"}, CLOCK_HZ, in_use).changes["iv0"] == 6
    assert "key" not in describe(dict(current, key0=1), CLOCK_HZ)
