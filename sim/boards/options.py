"""The options of a board without hardware, defined once: ``fliss board`` (the virtual
board) and ``python -m fliss.sim.boards.model`` (the model board) take the same name for the
same setting: the scene's (``--target-m``, ``--ambient 100kHz``, ...), its detector's
(``--sensor-preset``, ``--dark-count 7kHz``, ...: :mod:`fliss.sim.scene.detector_options`) and
the build's and its loopback's (``--baud``, ``--fine-tdc``, ``--small``, ``--jumper``)."""

import argparse
import re

from ..scene import SCENE_NAMES, SENSOR_KINDS
from ..scene.detector_options import SETTINGS, DetectorSettingError, detector_from, preset_names


__all__ = ["add_scene_arguments", "add_detector_arguments", "add_build_arguments",
           "detector_from_args", "detector_note", "rate_hz", "baud_rate"]


_RATE = re.compile(r"\s*((?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?)\s*(hz|khz|mhz|ghz)\s*",
                   flags=re.IGNORECASE)
_SCALE = {"hz": 1, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}


def rate_hz(text, flag="--ambient"):
    """A photon rate in Hz from ``"100kHz"``, ``"1e5Hz"``, ``"0Hz"``: with its unit, as every
    frequency of ``fliss``; ``ValueError`` naming ``flag`` for anything else."""
    match = _RATE.fullmatch(str(text))
    if match is None:
        raise ValueError(f"{flag} {text}: give a rate with its unit, not negative: 100kHz, "
                         f"1e5Hz or 0Hz")
    return float(match.group(1)) * _SCALE[match.group(2).lower()]


_BAUD = re.compile(r"\s*(\d+\.?\d*|\.\d+)\s*(k|m)?(?:baud|bd)?\s*", flags=re.IGNORECASE)


def baud_rate(text, flag="--baud"):
    """A baud rate from ``"12M"``, ``"3Mbaud"``, ``"115200"``, as ``fliss``'s commands take it
    (:func:`fliss.host.units.parse_baud`, which the simulator does not import); ``ValueError``
    naming ``flag`` for anything else."""
    match = _BAUD.fullmatch(str(text))
    value = None if match is None else \
        float(match.group(1)) * {"": 1, "k": 1e3, "m": 1e6}[(match.group(2) or "").lower()]
    if value is None or not value >= 1 or value != int(value):
        raise ValueError(f"{flag} {text}: give a whole baud rate: 115200, 3M or 12Mbaud")
    return int(value)


def add_scene_arguments(parser, *, seed=None):
    """What the board's sensor sees, as options of an argparse ``parser``; ``seed`` is the
    default of ``--seed`` (None: a new one each run)."""
    group = parser.add_argument_group("scene", "what the board's sensor sees (the scene "
                                               "simulator: docs/scene.md)")
    group.add_argument("--target-m", type=float, default=4.0, metavar="M",
                       help="distance of the victim's target (the line scene's wall), metres")
    group.add_argument("--ambient", default="100kHz", metavar="HZ",
                       help="background photon rate at a pixel (ambient light, dark counts), "
                            "with its unit")
    group.add_argument("--signal", type=float, default=0.05, metavar="PHOTONS",
                       help="mean detected echo photons per victim pulse")
    group.add_argument("--aggressor-signal", type=float, default=0.05, metavar="PHOTONS",
                       help="mean detected photons per aggressor pulse")
    group.add_argument("--seed", type=int, default=seed, help="seed of the photon statistics")
    group.add_argument("--scene", choices=SCENE_NAMES, default="single",
                       help="single: one pixel looking at the target (the paper's bench); "
                            "line: a column of 60 pixels looking at a wall --target-m away "
                            "with an object --object-m away before pixels 20 to 39")
    group.add_argument("--sensor", choices=SENSOR_KINDS, default="column",
                       help="sensor of the line scene: column (the paper's: one event per "
                            "laser cycle, from the pixel that fired last, with a collision "
                            "flag) or per_pixel (one TDC per pixel)")
    group.add_argument("--object-m", type=float, default=2.5, metavar="M",
                       help="distance of the line scene's object, metres")
    add_detector_arguments(parser)


def add_detector_arguments(parser):
    """The detector's settings (:data:`fliss.sim.scene.detector_options.SETTINGS`) as options
    of an argparse ``parser``: ``--sensor-preset NAME`` and one option per effect, each value
    with its unit."""
    group = parser.add_argument_group(
        "detector", "the SPAD pixels' physics (docs/scene.md, The detector): a preset, and "
                    "each setting given replaces the preset's; values with their unit")
    # (not given: no attribute, and no "(default: None)" in the help: the preset's value)
    group.add_argument("--sensor-preset", default=argparse.SUPPRESS, metavar="NAME",
                       help=f"a detector with published figures: {preset_names()} (default: "
                            f"the model's, as paper: 20 ns non-paralysable dead time, 100 ps "
                            f"jitter, nothing else)")
    for setting in SETTINGS:
        flag = "--" + setting.name.replace("_", "-")
        if setting.kind == "flag":
            group.add_argument(flag, action="store_true", default=argparse.SUPPRESS,
                               help=setting.help)
        else:
            group.add_argument(flag, default=argparse.SUPPRESS, metavar=setting.metavar,
                               help=setting.help)


def detector_from_args(args):
    """The :class:`~fliss.sim.scene.detector.Detector` the options of
    :func:`add_detector_arguments` describe; ``ValueError`` naming the flag (also for
    crosstalk asked of the single pixel, which has no neighbours)."""
    settings = {setting.name: getattr(args, setting.name, None) for setting in SETTINGS}
    detector = detector_from(getattr(args, "sensor_preset", None), settings)
    if getattr(args, "scene", None) == "single":
        for name in ("crosstalk", "crosstalk_diagonal"):
            if settings[name] is not None:
                raise DetectorSettingError(
                    f"--{name.replace('_', '-')} {settings[name]}: crosstalk needs "
                    f"neighbours: the pixel array of --scene line, not the single pixel")
    return detector


def detector_note(args, detector):
    """A note when the detector has an effect the scene cannot show (a preset's crosstalk on
    the single pixel, which has no neighbours), or None."""
    if getattr(args, "scene", None) == "single" and detector.crosstalk:
        return (f"the detector's crosstalk ({100 * detector.crosstalk_orthogonal:g} % "
                f"orthogonal, {100 * detector.crosstalk_diagonal:g} % diagonal) needs "
                f"neighbours: the single pixel has none (--scene line has)")
    return None


def add_build_arguments(parser, *, where=""):
    """The build of the board and its loopback, as options of an argparse ``parser``;
    ``where`` ends each build's help (what runs it)."""
    from ...hdl.clock import DEFAULT_CLOCK_HZ
    from .loopback import JUMPER_DELAY_S
    parser.add_argument("--baud", default="12M", help="UART baud rate of the gateware")
    parser.add_argument("--fine-tdc", action="store_true",
                        help="the top level with the fine TDC (the on-chip oscillator, the "
                             "internal loopback of the trigger outputs' pads, and a jumper with "
                             "--jumper: `fliss selftest` and `fliss calibrate` run on it)" + where)
    parser.add_argument("--small", action="store_true",
                        help="the top level with the iCEBreaker's options (histograms only: "
                             "no raw events, no aggressor emitter, no keyed mode), at "
                             f"{DEFAULT_CLOCK_HZ / 1e6:g} MHz" + where)
    parser.add_argument("--jumper", choices=("laser", "aggressor"), default=None,
                        help="a jumper wire from the laser output or the aggressor's trigger "
                             f"to the photon input, {JUMPER_DELAY_S * 1e9:g} ns after the "
                             "trigger's clock edge: the coarse TDC's pin, and with --fine-tdc "
                             "the fine TDC's line (`fliss selftest --jumper` runs on it)" + where)
