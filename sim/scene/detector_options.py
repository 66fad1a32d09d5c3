"""The detector's settings as text with units, by name: one table (:data:`SETTINGS`) read by
the boards' command lines (``fliss board``, the model board: ``--dark-count 7kHz``) and the
sweeps' specs (``dark_count = "7kHz"``), so that a name means the same everywhere.

:func:`detector_from` makes the :class:`~fliss.sim.scene.detector.Detector` they describe: a
preset of :data:`~fliss.sim.scene.presets.PRESETS` (``sensor_preset``; none: the model's
default detector) with the settings given replacing its values. A value is text with its unit,
as every quantity of ``fliss`` (``1.4%``, ``40ns``, ``7kHz``); a bare number, a negative value,
a share over 100 %, an unknown preset, or a setting that would do nothing without another
(``--afterpulse-tau`` without ``--afterpulsing``) raise :exc:`DetectorSettingError`, one line
naming the setting as it was written.

The units are read here, not with :mod:`fliss.host.units`, because the simulator does not
import the host (the layers of the README); the same forms are taken.
"""

import math
import re
from dataclasses import dataclass
from decimal import Decimal

from .detector import Detector
from .presets import PRESETS


__all__ = ["Setting", "SETTINGS", "BY_NAME", "DetectorSettingError", "detector_from",
           "spell", "preset_names"]


class DetectorSettingError(ValueError):
    """A detector setting that cannot be taken; its message names the setting."""


@dataclass(frozen=True)
class Setting:
    """One detector setting: ``name`` (``dark_count``; the flag is ``--dark-count``), the
    :class:`~fliss.sim.scene.detector.Detector` field it sets, its kind (``"share"``: a
    percentage, ``"time"``, ``"times"``: one or more, comma-separated, ``"shares"``, ``"rate"``,
    ``"flag"``) and its help text."""
    name: str
    field: str
    kind: str
    help: str
    metavar: str = ""


#: Every detector setting, in the order of the help.
SETTINGS = (
    Setting("pdp", "pdp", "share", "photon detection probability: the share of the scene's "
            "photons (echo, aggressor, --ambient) a ready SPAD detects", "PERCENT"),
    Setting("dark_count", "dark_count_hz", "rate", "each pixel's dark count rate, added to "
            "--ambient and not thinned by --pdp", "HZ"),
    Setting("hot_pixels", "hot_fraction", "share", "share of hot pixels (each pixel hot "
            "with this probability, drawn once for the sensor)", "PERCENT"),
    Setting("hot_dark_count", "hot_dark_count_hz", "rate", "dark count rate of a hot "
            "pixel", "HZ"),
    Setting("dead_time", "dead_time_s", "time", "SPAD dead time after an avalanche",
            "TIME"),
    Setting("paralysable", "paralysable", "flag", "paralysable dead time: every photon "
            "restarts it, counted or not (default: non-paralysable)"),
    Setting("jitter", "jitter_fwhm_s", "time", "Gaussian timing jitter of SPAD and TDC, "
            "FWHM", "TIME"),
    Setting("jitter_tail", "tail_s", "time", "mean delay of the diffusion tail, an "
            "exponential after the Gaussian jitter (with --jitter-tail-share)", "TIME"),
    Setting("jitter_tail_share", "tail_fraction", "share", "share of the pulses' photons "
            "late by the diffusion tail", "PERCENT"),
    Setting("afterpulsing", "afterpulse_probability", "share", "probability that an "
            "avalanche releases an afterpulse (with --afterpulse-tau)", "PERCENT"),
    Setting("afterpulse_tau", "afterpulse_s", "times", "mean delay of an afterpulse: one "
            "time, or several comma-separated (a mixture of exponentials)", "TIME[,TIME]"),
    Setting("afterpulse_weights", "afterpulse_weights", "shares", "share of each of "
            "--afterpulse-tau's exponentials (default: equal)", "PERCENT[,PERCENT]"),
    Setting("crosstalk", "crosstalk_orthogonal", "share", "optical crosstalk: probability "
            "that an avalanche fires each orthogonal neighbour (pixel arrays)", "PERCENT"),
    Setting("crosstalk_diagonal", "crosstalk_diagonal", "share", "probability that an "
            "avalanche fires each diagonal neighbour (arrays of more than one column)",
            "PERCENT"),
)

BY_NAME = {setting.name: setting for setting in SETTINGS}

_NUMBER = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
# Units as powers of ten: the value is the decimal number given, rounded once (22ns is 22e-9)
_TIME = {"s": 0, "ms": -3, "us": -6, "µs": -6, "ns": -9, "ps": -12}
_RATE = {"hz": 0, "khz": 3, "mhz": 6, "ghz": 9}
_SHARE = {"%": -2}
_EXAMPLES = {"time": "40ns or 80ps", "rate": "7kHz or 25Hz", "share": "1.4%"}


def preset_names():
    return ", ".join(PRESETS)


def spell(name, style):
    """``--dark-count`` (``style`` ``"flag"``) or ``dark_count`` (``"key"``)."""
    return "--" + name.replace("_", "-") if style == "flag" else name


def _quantity(text, kind, said):
    """One value of ``kind`` (``"time"``, ``"rate"``, ``"share"``) from ``text``."""
    units = {"time": _TIME, "rate": _RATE, "share": _SHARE}[kind]
    if not isinstance(text, str):
        raise DetectorSettingError(f"{said}: give it as text with its unit: "
                                   f"{_EXAMPLES[kind]}")
    match = re.fullmatch(_NUMBER + r"\s*([a-zµ%]*)", text.strip(), flags=re.IGNORECASE)
    if match is not None and not match.group(2):
        raise DetectorSettingError(f"{said}: give a unit: {_EXAMPLES[kind]}")
    if match is None or match.group(2).lower() not in units:
        raise DetectorSettingError(f"{said}: cannot read it as a {kind} (for example "
                                   f"{_EXAMPLES[kind]})")
    value = float(Decimal(match.group(1)).scaleb(units[match.group(2).lower()]))
    if not math.isfinite(value) or value < 0:
        raise DetectorSettingError(f"{said}: must be a finite {kind}, not negative")
    if kind == "share" and value > 1:
        raise DetectorSettingError(f"{said}: a share is from 0 to 100 %")
    return value


def _value(setting, text, style):
    said = f"{spell(setting.name, style)} {text}" if style == "flag" else \
        f"{setting.name} = {text!r}"
    if setting.kind == "flag":
        if not isinstance(text, bool):
            raise DetectorSettingError(f"{said}: must be true or false")
        return text
    if setting.kind in ("times", "shares"):
        if not isinstance(text, str) or not text.strip():
            raise DetectorSettingError(f"{said}: give one or more values with their unit, "
                                       f"comma-separated")
        return tuple(_quantity(part, setting.kind[:-1], said) for part in text.split(","))
    return _quantity(text, setting.kind, said)


def detector_from(preset=None, settings=None, *, style="flag"):
    """The :class:`~fliss.sim.scene.detector.Detector` of the preset named ``preset`` (None:
    the model's default detector) with ``settings`` (a dict by :data:`SETTINGS` name of the
    values as given: text with units, True for ``paralysable``; None values are not given).
    ``style`` spells the settings in messages: ``"flag"`` (``--dark-count 7kHz``) or ``"key"``
    (``dark_count = '7kHz'``). Raises :exc:`DetectorSettingError`."""
    given = {name: value for name, value in (settings or {}).items() if value is not None}
    for name in given:
        if name not in BY_NAME:
            raise DetectorSettingError(f"unknown detector setting {name!r} (known: "
                                       f"{', '.join(BY_NAME)})")
    if preset is None or preset == "":
        base = Detector()
    elif preset in PRESETS:
        base = PRESETS[preset]
    else:
        said = f"{spell('sensor_preset', style)} {preset}" if style == "flag" else \
            f"sensor_preset = {preset!r}"
        raise DetectorSettingError(f"{said}: unknown preset (known: {preset_names()})")
    fields = {BY_NAME[name].field: _value(BY_NAME[name], value, style)
              for name, value in given.items()}
    if fields.get("paralysable") is False:
        del fields["paralysable"]           # (a flag not given keeps the preset's)
    _check_together(base, fields, given, style)
    try:
        return base.replace(**fields)
    except ValueError as error:
        names = ", ".join(spell(name, style) for name in given) or spell("sensor_preset", style)
        raise DetectorSettingError(f"{names}: {error}") from None


def _check_together(base, fields, given, style):
    """Refuse a setting that would do nothing, or that needs another one."""
    def now(field):
        return fields.get(field, getattr(base, field))

    def refuse(name, message):
        value = given[name]
        said = spell(name, style) + ("" if value is True else f" {value}") \
            if style == "flag" else f"{name} = {value!r}"
        raise DetectorSettingError(f"{said}: {message}")

    pairs = (("jitter_tail_share", "tail_fraction", "jitter_tail", "tail_s"),
             ("afterpulsing", "afterpulse_probability", "afterpulse_tau", "afterpulse_s"),
             ("hot_pixels", "hot_fraction", "hot_dark_count", "hot_dark_count_hz"))
    for share_name, share, size_name, size in pairs:
        if share_name in given and now(share) > 0 and not now(size):
            refuse(share_name, f"needs {spell(size_name, style)}")
        if size_name in given and now(share) == 0:
            refuse(size_name, f"does nothing without {spell(share_name, style)}")
    if "afterpulse_weights" in given:
        if len(fields["afterpulse_weights"]) != len(now("afterpulse_s")):
            refuse("afterpulse_weights", f"give one share per time of "
                                         f"{spell('afterpulse_tau', style)} "
                                         f"({len(now('afterpulse_s'))})")
        if now("afterpulse_probability") == 0:
            refuse("afterpulse_weights", f"does nothing without "
                                         f"{spell('afterpulsing', style)}")
    if "afterpulse_tau" in given and "afterpulse_weights" not in given and \
            len(fields["afterpulse_s"]) != len(base.afterpulse_weights):
        fields["afterpulse_weights"] = (1.0,) * len(fields["afterpulse_s"])
    if "pdp" in given and fields["pdp"] == 0:
        refuse("pdp", "a SPAD that detects nothing: give more than 0 %")
    if "afterpulsing" in given and fields["afterpulse_probability"] >= 1:
        refuse("afterpulsing", "must be below 100 % (an afterpulse can afterpulse again)")
