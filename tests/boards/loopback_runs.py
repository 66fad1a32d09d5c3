"""What the tests of ``fliss selftest`` and ``fliss calibrate`` on the model board with a loopback
share: the modelled fine TDC line, the command run with its output, the checks' outcomes,
and progress displays that interrupt or kill."""

import os
import signal

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.host.cli import main
from fliss.sim.models.finetdc import Line


CLOCK_HZ = DEFAULT_CLOCK_HZ
LINE = Line()
#: The line's input delay: in every fine timestamp (the table leaves it out).
INPUT_S = LINE.offset_s
#: The time from the line's input to its first tap: in every calibrated fine timestamp.
FIRST_TAP_S = LINE.thresholds_s[0]


def fliss(capsys, *argv):
    status = main([*argv, "--timeout", "2"])
    out, err = capsys.readouterr()
    return status, out, err


def outcomes(result):
    return [check.outcome for check in result.checks]


def line_of(result, name):
    return next(check for check in result.checks if check.name == name)




class _InterruptAfter:
    """A progress display whose ``update`` raises KeyboardInterrupt (Ctrl-C) at its n-th
    call."""

    def __init__(self, calls):
        self.calls = calls

    def update(self, done, extra=""):
        self.calls -= 1
        if self.calls == 0:
            raise KeyboardInterrupt

    def close(self):
        pass


class _KillAfter(_InterruptAfter):
    """A progress display that sends this process SIGTERM (`kill`) at its n-th update."""

    def update(self, done, extra=""):
        self.calls -= 1
        if self.calls == 0:
            os.kill(os.getpid(), signal.SIGTERM)
