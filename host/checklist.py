"""The self-test's result: its checks, one line each, and the verdict they add up to
(:mod:`fliss.host.selftest` runs them). A skipped check is not a pass: a self-test with one
is ``"incomplete"``, never ``"pass"``."""

from dataclasses import dataclass, field
from typing import List, Optional

from .calibration import Calibration


__all__ = ["CHECKS", "Check", "SelfTest", "SelfTestInterrupted", "advice"]


#: The checks, in order.
CHECKS = ("same time", "delays", "histogram", "calibration", "link")


def advice(check, has_aggressor):
    """What would run ``check`` on a build (with an aggressor emitter or not) when the loopback
    cannot (the start of a sentence), or why nothing would."""
    if check == "delays":
        if has_aggressor:
            return ": loop the aggressor's trigger to the photon input (--jumper aggressor)"
        return " (this build has no aggressor emitter, whose trigger shows them)"
    if check == "histogram":
        return ": loop the laser output to the photon input (--jumper laser)"
    return ""


@dataclass(frozen=True)
class Check:
    """One line of the self-test: ``name``, ``outcome`` (``"pass"``, ``"fail"`` or
    ``"skipped"``) and what it found (or why it was skipped)."""
    name: str
    outcome: str
    detail: str


@dataclass
class SelfTest:
    """The self-test's result: its checks in order, and the loopback: ``"internal"``,
    ``"laser"`` or ``"aggressor"`` (a jumper), or ``"none"``."""
    loop: str
    checks: List[Check] = field(default_factory=list)
    elapsed_s: float = 0.0
    #: The loopback's delay (less the aggressor's offset) and its RMS jitter, if measured (the
    #: jitter None with the coarse TDC when every hit fell in one code: below its bin).
    delay_s: Optional[float] = None
    jitter_s: Optional[float] = None
    calibration: Optional[Calibration] = None
    #: The board's seconds per second of the host's (:mod:`fliss.host.pace`).
    pace: Optional[float] = None

    @property
    def passed(self) -> bool:
        """Every check ran and passed: a full self-test (a skipped check is not a pass)."""
        return self.verdict == "pass"

    @property
    def verdict(self) -> str:
        """``"fail"`` if a check failed, else ``"incomplete"`` if one was skipped (or the test
        was cut short), else ``"pass"``."""
        outcomes = {check.outcome for check in self.checks}
        if "fail" in outcomes:
            return "fail"
        if "skipped" in outcomes or len(self.checks) < len(CHECKS):
            return "incomplete"
        return "pass"

    def summary(self) -> str:
        """One line: ``passed 1 of 5, 4 skipped: not a full self-test``, ``failed: delays``."""
        counts = {outcome: sum(check.outcome == outcome for check in self.checks)
                  for outcome in ("pass", "fail", "skipped")}
        said = f"passed {counts['pass']} of {len(CHECKS)}"
        if counts["fail"]:
            failed = [check.name for check in self.checks if check.outcome == "fail"]
            return f"failed: {', '.join(failed)} ({said})"
        if counts["skipped"]:
            return f"{said}, {counts['skipped']} skipped: not a full self-test"
        if len(self.checks) < len(CHECKS):
            return f"{said}, {len(CHECKS) - len(self.checks)} not run: not a full self-test"
        return said

    def table(self) -> str:
        """The checks as a table, one line each."""
        width = max(len(name) for name in CHECKS)
        lines = [f"{'check':<{width}}  result   detail"]
        lines += [f"{check.name:<{width}}  {check.outcome:<7}  {check.detail}"
                  for check in self.checks]
        return "\n".join(lines)


class SelfTestInterrupted(KeyboardInterrupt):
    """The self-test was interrupted (Ctrl-C); :attr:`result` holds the checks finished."""

    def __init__(self, result: SelfTest):
        super().__init__("self-test interrupted")
        self.result = result
