"""The delay modes, in one table: per mode, the settings it needs, its largest delay, the period
and mean of its delay sequence, and its name in labels.

The register checks read it (:func:`fliss.hdl.registers.problems`, and the gateware's, which
:class:`~fliss.hdl.regfile.RegisterFile` generates from it per delay core), and so do the models
(:mod:`fliss.sim.models.delay`), the formal harnesses and the host's commands and plots, the
files' metadata (:func:`fliss.host.formats.metadata.settings`), the scene simulator and the
interference study; which delay cores have a mode (:func:`core_modes`) sets the largest value of
each core's ``mode`` register. The delays themselves come from the delay source (:mod:`.source`)
and its model (:mod:`fliss.sim.models.delay`). A new mode is a member of :class:`DelayMode` and a
row of :data:`MODES` here, a block of the source, and its model.

A definitions module: it imports no gateware.
"""

from dataclasses import dataclass
from fractions import Fraction
from typing import Callable, Optional, Union

from amaranth.lib import enum

from .settings import MASKED_LENGTH, MAX_LENGTH, MAX_MASK_WIDTH, MIN_LENGTH


__all__ = ["DelayMode", "Size", "SIZES", "Mode", "MODES", "mode_row", "label", "core_modes",
           "mode_maximum", "missing_modes", "delay_problems"]


class DelayMode(enum.Enum, shape=2):
    """Source of the pseudorandom delay ``T_rnd``, in clock cycles (:data:`MODES`)."""
    #: No delay: the laser fires on the nominal schedule.
    OFF    = 0
    #: Complete m-sequence of an ``L``-bit register, one state per pulse; delay ``R = state - 1``,
    #: so ``R`` runs over ``0 … 2**L - 2`` once per period (equation 9 and Table 2 of the paper).
    MSEQ   = 1
    #: The ``Wm`` least significant bits of a 32-bit register that takes ``MASKED_STEPS`` steps per
    #: pulse; delay from ``0`` to ``2**Wm - 1``.
    MASKED = 2
    #: The Trivium keystream of an 80-bit key and IV (:mod:`fliss.sim.models.trivium`): pulse
    #: ``k``'s delay is the ``Wm``-bit integer whose bit ``j`` is keystream bit
    #: ``z(k Wm + j + 1)``; delay from ``0`` to ``2**Wm - 1``, as ``MASKED``.
    KEYED  = 3


@dataclass(frozen=True)
class Size:
    """A setting that sizes a mode's delays: its symbol in labels (``L`` in ``"mseq L=6"``),
    what it is, and its range as the models check it (the register's may be wider)."""
    symbol: str
    what: str
    noun: str
    minimum: int
    maximum: int


#: The settings that size a mode's delays, by name.
SIZES = {
    "length":     Size("L", "a register length L", "LFSR length", MIN_LENGTH, MAX_LENGTH),
    "mask_width": Size("Wm", "a mask width Wm", "Mask width", 1, MAX_MASK_WIDTH),
}


@dataclass(frozen=True)
class Mode:
    """One delay mode.

    Its delays run from 0 to ``2**n - less`` cycles, ``n`` being the value of its ``size``
    setting (one of :data:`SIZES`); without ``size`` they are all zero. ``seed_bits``: the seed
    is a non-zero state of a register of this many bits, or of as many as the setting of that
    name says (the register checks refuse a seed above it); None: the seed is not used.
    (A number of bits is the seed register's 32, which its range checks.) ``keyed``: it needs
    the key and IV, and so the keyed source: only a delay core built with it has the mode (the
    aggressor's core has none, :func:`core_modes`). ``period`` and ``mean`` give, of ``n``, the
    number of pulses after which the sequence repeats (None: unknown, beyond any run) and the
    mean delay over one whole period, in cycles. (The gateware's consistency check builds ``2**n - 1`` and
    ``2**n - 2``: ``less`` is 1 or 2.)
    """
    mode: DelayMode
    size: Optional[str] = None
    less: int = 1
    seed_bits: Union[int, str, None] = None
    keyed: bool = False
    period: Callable[[int], Optional[int]] = lambda n: 1
    mean: Callable[[int], Fraction] = lambda n: Fraction(0)

    def __post_init__(self):
        assert self.size is None or self.size in SIZES, self
        assert self.less in (1, 2), self
        assert self.seed_bits in (None, MAX_LENGTH) or self.seed_bits in SIZES, self

    @property
    def name(self):
        """``"mseq"``: the mode's name in labels, settings and files."""
        return self.mode.name.lower()

    @property
    def needs(self):
        """The settings the mode reads, besides the scheduler's."""
        return ((self.size,) if self.size else ()) + \
            (("seed",) if self.seed_bits is not None else ()) + \
            (("key", "iv") if self.keyed else ())

    def max_delay(self, **settings):
        """Largest delay in cycles, with ``settings`` by name (those it does not need are
        ignored)."""
        return 0 if self.size is None else (1 << settings[self.size]) - self.less

    def sequence_period(self, **settings):
        """Pulses after which the delays repeat; None if unknown (beyond any run)."""
        return self.period(settings.get(self.size))

    def mean_delay(self, **settings):
        """Mean delay over one whole period, in cycles, as an exact fraction."""
        return self.mean(settings.get(self.size))

    def label(self, **settings):
        """The mode and its size, as plots and tables name it: ``"mseq L=6"``, ``"off"``."""
        if self.size is None:
            return self.name
        return f"{self.name} {SIZES[self.size].symbol}={settings.get(self.size)}"


def _masked_mean(width):
    # Over the 2**32 - 1 non-zero states of the register, each non-zero value of its low Wm
    # bits comes 2**(32 - Wm) times and zero 2**(32 - Wm) - 1 times.
    per_value = 1 << (MASKED_LENGTH - width)
    total = per_value * ((1 << width) - 1) * (1 << width) // 2
    return Fraction(total, (1 << MASKED_LENGTH) - 1)


#: Every delay mode, by :class:`DelayMode`, in value order.
MODES = {row.mode: row for row in (
    Mode(DelayMode.OFF),
    # the states 1 … 2**L - 1 once each per period: R averages 2**(L-1) - 1
    Mode(DelayMode.MSEQ, size="length", less=2, seed_bits="length",
         period=lambda n: (1 << n) - 1, mean=lambda n: Fraction((1 << n) - 2, 2)),
    Mode(DelayMode.MASKED, size="mask_width", seed_bits=MASKED_LENGTH,
         period=lambda n: (1 << MASKED_LENGTH) - 1, mean=_masked_mean),
    # the mean of uniform Wm-bit delays (an ideal keystream's); Trivium's period is unknown,
    # and far beyond any run (288 bits of state)
    Mode(DelayMode.KEYED, size="mask_width", keyed=True,
         period=lambda n: None, mean=lambda n: Fraction((1 << n) - 1, 2)),
)}

assert list(MODES) == list(DelayMode)


def mode_row(mode):
    """The row of ``mode`` (a :class:`DelayMode` or its value), or None if there is none."""
    try:
        return MODES[DelayMode(mode)]
    except ValueError:
        return None


def core_modes(keyed=True):
    """The rows of the modes a delay core has, in value order: every mode with its keyed source
    (``keyed``), those that need no key without it (the aggressor's core; the victim's in a
    build without ``keyed``)."""
    return tuple(row for row in MODES.values() if keyed or not row.keyed)


def mode_maximum(keyed=True):
    """The largest value of a mode of :func:`core_modes`: the maximum of the core's ``mode``
    register."""
    return max(row.mode.value for row in core_modes(keyed))


def missing_modes(keyed=True):
    """The rows of the modes below :func:`mode_maximum` that a core of :func:`core_modes` has
    not, which its register's range lets through: the register checks refuse them
    (:func:`delay_problems`). None while the modes that need a key are the last."""
    have = core_modes(keyed)
    return tuple(row for row in MODES.values()
                 if row not in have and row.mode.value < mode_maximum(keyed))


def label(mode, /, **settings):
    """:meth:`Mode.label` of ``mode`` (a :class:`DelayMode` or its value), ``"?"`` for a value
    that is no mode."""
    row = mode_row(mode)
    return "?" if row is None else row.label(**settings)


#: Fields of a delay core's settings, in order (:class:`~fliss.hdl.registers.DelaySettings`).
_FIELDS = ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width")


def delay_problems(settings, *, names=None, ranges=True, keyed=True):
    """What is wrong with a delay core's settings, as messages (none: the core takes them).

    ``settings`` maps each field of :class:`~fliss.hdl.registers.DelaySettings` (``mode``,
    ``length``, ``mask_width``, ``seed``, ``period``, ``grid``, ``pulse_width``) to its value;
    ``names`` gives the name a message uses for a field (a register's), by default the field's.
    With ``ranges``, each value is checked against its own limits first; then the settings
    together: a mode the core has (``keyed``: it has the keyed source, :func:`core_modes`), the
    pulse shorter than the period, the largest delay plus the pulse shorter than the period in
    ``grid`` mode, and an ``mseq`` seed below ``2**length``.
    """
    missing = [name for name in _FIELDS if name not in settings]
    if missing:
        return [f"missing delay settings: {', '.join(missing)}"]
    name = {field: field for field in _FIELDS}
    name.update(names or {})
    v = settings
    mode = mode_row(v["mode"])
    if ranges:
        limits = {"length": (SIZES["length"].minimum, SIZES["length"].maximum),
                  "mask_width": (SIZES["mask_width"].minimum, SIZES["mask_width"].maximum),
                  "seed": (1, (1 << MAX_LENGTH) - 1), "period": (2, (1 << 32) - 1),
                  "grid": (0, 1), "pulse_width": (1, (1 << 16) - 1)}
        found = [] if mode is not None else [f"{name['mode']} ({v['mode']!r}) is no delay mode"]
        found += [f"{name[field]} must be an integer from {low} to {high}, not {v[field]!r}"
                  for field, (low, high) in limits.items()
                  if not isinstance(v[field], int) or not low <= v[field] <= high]
        if found:
            return found
    found = []
    if mode in missing_modes(keyed):
        found.append(f"{name['mode']} ({v['mode']}) is the {mode.name} mode, which this delay "
                     f"core has not (it has no keyed source)")
    if v["pulse_width"] >= v["period"]:
        found.append(f"{name['pulse_width']} ({v['pulse_width']} cycles) must be shorter than "
                     f"{name['period']} ({v['period']} cycles)")
    if v["grid"] and mode.max_delay(**v) + v["pulse_width"] >= v["period"]:
        found.append(f"grid mode needs the largest delay plus {name['pulse_width']} to be "
                     f"shorter than {name['period']}")
    bits = mode.seed_bits
    if isinstance(bits, str) and v["seed"] >> v[bits]:
        found.append(f"{name['seed']} must be below 2**{name[bits]} = "
                     f"{1 << v[bits]} for the {mode.name} source")
    return found
