"""Whose is each peak of a capture: the victim's echo, the aggressor's, or unknown.

A histogram alone does not say which of its peaks is the victim's: with FLISS off the
aggressor's pulses keep a fixed time to the victim's, so its peak is as sharp as the victim's
echo, and either may be the taller. What can tell them apart:

* the user, by position (``--victim-tof``, ``--aggressor-tof``);
* the board's settings that the capture records (:func:`relation`): with the aggressor emitter
  off, every peak is the victim's laser's; when the victim's delays differ from the aggressor's
  (FLISS on), the aggressor's pulses come at random times to the victim's and are spread over
  the range, so a lone peak is the victim's echo (several peaks: other targets, or what is
  left of the aggressor; unknown). The one case this gets wrong: no victim's echo in the range
  and a single tooth of the aggressor's residue (it falls on a comb of clock-cycle steps)
  passing the significance test;
* captures of the same scene with FLISS off and on: the aggressor's peak stands only with FLISS
  off, what is left of it only with FLISS on, so the peak at the same time in both is the
  victim's (``fliss analyze`` says so when it is given both,
  :func:`fliss.host.commands.analyze.victim_hints`).

Where none of these tells, the roles are ``unknown`` and no suppression is worked out from a
guess. Library code: it raises :exc:`ValueError`, never prints.
"""

from dataclasses import dataclass
from typing import Mapping, Optional, Sequence

from ..analysis.peaks import Peak
from ..hdl.delay.modes import DelayMode, label as mode_label
from ..hdl.registers import AGGRESSOR_DELAY, VICTIM


__all__ = ["VICTIM_ROLE", "AGGRESSOR_ROLE", "UNKNOWN_ROLE", "OFF", "COHERENT", "SPREAD",
           "UNKNOWN", "Roles", "relation", "settings_text", "check_references", "assign"]

VICTIM_ROLE, AGGRESSOR_ROLE, UNKNOWN_ROLE = "victim", "aggressor", "unknown"

#: What :func:`relation` says of the aggressor's pulses against the victim's.
OFF, COHERENT, SPREAD, UNKNOWN = "off", "coherent", "spread", "unknown"


@dataclass(frozen=True)
class Roles:
    """The role of each peak (``roles``, in the order of the peaks), the victim's peak and the
    aggressor peaks when known, and ``reason``: how they were told apart, or why not."""
    roles: tuple
    victim: Optional[Peak]
    aggressors: tuple
    reason: str


def _fields(group, configuration):
    return {register.field: configuration.get(register.name) for register in group.members}


def settings_text(configuration: Mapping[str, int]) -> str:
    """The victim's delay mode and the aggressor of the registers a capture was taken with:
    ``"FLISS masked Wm=6, aggressor on"`` (``"FLISS off, ..."`` without delays); empty for a
    file that records no registers."""
    if not configuration:
        return ""
    victim = _fields(VICTIM, configuration)
    return (f"FLISS {mode_label(victim['mode'], **victim)}, "
            f"aggressor {'on' if configuration.get('aggressor') else 'off'}")


def relation(configuration: Mapping[str, int]) -> tuple:
    """``(kind, why)``: how the aggressor's pulses fall against the victim's TDC start, from
    the registers of a capture. ``kind`` is ``"off"`` (the aggressor emitter off),
    ``"coherent"`` (at a fixed time: both delay sources off at one period, or the aggressor
    repeating the victim's very delays), ``"spread"`` (at random times: the delays differ) or
    ``"unknown"`` (no registers recorded, or both off at different periods)."""
    if not configuration or "aggressor" not in configuration:
        return UNKNOWN, "the board's settings are not known (the file records none)"
    if not configuration["aggressor"]:
        return OFF, "the aggressor emitter was off"
    victim = _fields(VICTIM, configuration)
    aggressor = _fields(AGGRESSOR_DELAY, configuration)
    if any(value is None for value in (victim["mode"], aggressor["mode"], victim["period"],
                                       aggressor["period"])):
        return UNKNOWN, "the delay settings are not known"
    off = DelayMode.OFF.value
    if victim["mode"] == off and aggressor["mode"] == off:
        if victim["period"] == aggressor["period"]:
            return COHERENT, ("FLISS off: the aggressor's pulses keep a fixed time to the "
                              "victim's, so its peak looks like the victim's echo")
        return UNKNOWN, ("both delay sources off at different periods: the aggressor's pulses "
                         "drift against the victim's")
    same = all(victim[name] == aggressor[name] for name in ("mode", "length", "mask_width",
                                                            "seed", "period"))
    if same and not victim["grid"]:
        return COHERENT, ("the aggressor repeats the victim's delays (same source, seed and "
                          "period), so its peak looks like the victim's echo")
    return SPREAD, ("the victim's and the aggressor's delays differ: the aggressor's pulses "
                    "come at random times and spread over the range")


def check_references(victim_s: Optional[float], aggressors_s: Sequence[float],
                     tolerance_s: float) -> None:
    """Raise :exc:`ValueError` when an aggressor position is the victim's (within
    ``tolerance_s``): one peak cannot be both."""
    if victim_s is None:
        return
    for position in aggressors_s:
        if abs(position - victim_s) <= tolerance_s:
            raise ValueError(f"--aggressor-tof {position * 1e9:g}ns is within "
                             f"{tolerance_s * 1e9:g} ns of --victim-tof {victim_s * 1e9:g}ns: "
                             f"one peak cannot be the victim's and the aggressor's")


def _ns(peaks):
    return ", ".join(f"{peak.position_s * 1e9:.1f}" for peak in peaks) + " ns"


def assign(peaks: Sequence[Peak], configuration: Mapping[str, int], *,
           victim_s: Optional[float] = None, aggressors_s: Sequence[float] = (),
           tolerance_s: float = 1.5e-9) -> Roles:
    """The roles of ``peaks`` (highest first) of a capture taken with the registers
    ``configuration``, told apart by the positions given (``victim_s``, ``aggressors_s``) or
    else by :func:`relation`; ``unknown`` where they cannot be told."""
    def near(peak, positions):
        return any(abs(peak.position_s - position) <= tolerance_s for position in positions)

    kind, why = relation(configuration)
    if victim_s is not None:
        victim = next((peak for peak in peaks if near(peak, [victim_s])), None)
        if victim is None:
            return _roles(peaks, None, [], f"no peak within {tolerance_s * 1e9:g} ns of "
                                           f"--victim-tof {victim_s * 1e9:g}ns")
        others = [peak for peak in peaks if peak is not victim]
        if aggressors_s:
            return _roles(peaks, victim, [peak for peak in others if near(peak, aggressors_s)],
                          "victim and aggressor by --victim-tof and --aggressor-tof")
        if kind in (COHERENT, SPREAD):
            return _roles(peaks, victim, others, "victim by --victim-tof; with the aggressor "
                                                 "on, the other peaks are the aggressor's")
        return _roles(peaks, victim, [], "victim by --victim-tof"
                      + (f"; {why}" if kind == OFF else ""))
    if aggressors_s:
        aggressors = [peak for peak in peaks if near(peak, aggressors_s)]
        rest = [peak for peak in peaks if peak not in aggressors]
        if kind == SPREAD and len(peaks) == 1 and aggressors:
            return _roles(peaks, None, [], f"--aggressor-tof names the one peak, but {why}: "
                                           f"a lone peak is the victim's; check --aggressor-tof")
        if len(rest) == 1:
            return _roles(peaks, rest[0], aggressors,
                          "victim: the one peak not at --aggressor-tof")
        return _roles(peaks, None, aggressors, (
            "every peak is at --aggressor-tof: none is left for the victim" if not rest else
            f"{len(rest)} peaks ({_ns(rest)}) are not at --aggressor-tof: give --victim-tof"))
    if not peaks:
        return _roles(peaks, None, [], why)
    if kind == OFF:
        return Roles((VICTIM_ROLE,) * len(peaks), peaks[0], (),
                     f"{why}: every peak is the victim's laser's")
    if kind == SPREAD and len(peaks) == 1:
        return _roles(peaks, peaks[0], [], f"{why}; the one peak is the victim's echo")
    if kind == SPREAD:
        why = (f"{why}, yet {len(peaks)} peaks stand: other targets or what is left of the "
               f"aggressor")
    return _roles(peaks, None, [], f"unknown: {why}; give --victim-tof (the peak that stays "
                                   f"with FLISS on)")


def _roles(peaks, victim, aggressors, reason):
    roles = tuple(VICTIM_ROLE if peak is victim else
                  AGGRESSOR_ROLE if any(peak is other for other in aggressors) else UNKNOWN_ROLE
                  for peak in peaks)
    return Roles(roles, victim, tuple(aggressors), reason)
