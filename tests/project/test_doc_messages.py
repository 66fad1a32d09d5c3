"""The messages of ``fliss`` the docs quote, each printed as quoted by the command that prints
it, against a model board; and the numbers the ``--help`` texts and the demo's description give
(reset values, the aggressor's rate), against a board just powered on and the delay sequence."""

import contextlib
import io
import re

import pytest

from doc_examples import DOCS, ROOT
from fliss.host.board import connect as fliss_connect
from fliss.host.cli import main
from fliss.host.commands.demo import effective_period
from fliss.host.settings import BY_OPTION, OPTIONS
from fliss.sim.boards.model import model_board


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A fresh folder to run in, no port from the environment."""
    monkeypatch.delenv("FLISS_PORT", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


#: Each message of ``fliss`` the docs quote: the command that prints it (ports as in the docs),
#: the options of the model board it runs against, and its exit status.
QUOTED = {
    "fliss: warning: --aggressor-offset 80ns is 6.4 clock cycles of 12.5 ns: using 6 cycles, "
    "75 ns": (["config", "--port", "/dev/pts/N", "--aggressor-offset", "80ns"], {}, 0),
    "fliss: error: --line-errors must be from 0 to 1, not 1.5":
        (["board", "--line-errors", "1.5"], None, 1),
    "fliss: error: --afterpulsing 140%: a share is from 0 to 100 %":
        (["board", "--afterpulsing", "140%"], None, 1),
    "fliss: error: the board on /dev/pts/3 was reset during the capture: its STATUS (sequence "
    "number 0) shows it stopped; its IDENTITY reads protocol 5, gateware 0.2.0; saved what was "
    "received (30 histograms) to run.h5":
        (["capture", "--port", "/dev/pts/3", "--integration", "0.2ms", "--acquisitions", "100",
          "-o", "run.h5"], {"reset_after": 30}, 1),
    "fliss: warning: the board runs gateware 0.1.0, this fliss is 0.2.0: program the board "
    "with this version's bitstream (make bitstream)":
        (["config", "--port", "/dev/pts/N"], {"gateware_version": "0.1.0"}, 0),
}


def quoted_messages():
    """(file:line, message) of every ``fliss: error: ...`` or ``fliss: warning: ...`` the docs
    quote (in a code span, or on a line of a fenced block)."""
    found = []
    for path in DOCS:
        text = path.read_text()
        for match in re.finditer(r"`(fliss: (?:error|warning): [^`]+)`|^ *(fliss: (?:error|"
                                 r"warning): .+)$", text, flags=re.MULTILINE):
            message = " ".join((match.group(1) or match.group(2)).split())
            line = text.count("\n", 0, match.start()) + 1
            found.append((f"{path.relative_to(ROOT).as_posix()}:{line}", message))
    return found


def test_every_quoted_message_is_checked():
    assert sorted(message for _, message in quoted_messages()) == sorted(QUOTED)


@pytest.mark.parametrize("message", [message for _, message in quoted_messages()],
                         ids=[where for where, _ in quoted_messages()])
def test_quoted_message(message, workdir, capsys):
    argv, board_options, status = QUOTED[message]
    port = argv[argv.index("--port") + 1] if "--port" in argv else None
    with contextlib.ExitStack() as stack:
        if board_options is not None:
            board = stack.enter_context(model_board(**board_options))
            argv = [board.path if token == port else token for token in argv]
            message = message.replace(port, board.path)
        code = main(argv)
        err = capsys.readouterr().err
    assert code == status
    assert message in err.splitlines()


def test_help_gives_reset_values():
    """``(after reset: 1 cycle, 12.5 ns at 80 MHz)`` in a setting's help is what a board just
    powered on holds."""
    said = {option.name: re.search(r"after reset: (\d+) cycles?, ([\d.]+) ns at 80 MHz",
                                   option.help) for option in OPTIONS}
    said = {name: match for name, match in said.items() if match}
    assert {"pulse_width", "aggressor_width"} <= set(said)
    with model_board() as model, fliss_connect(model.path) as board:
        registers = board.registers
    for name, match in said.items():
        cycles = int(match.group(1))
        assert registers[BY_OPTION[name].register] == cycles, name
        assert float(match.group(2)) == cycles * 12.5, name      # 12.5 ns cycles at 80 MHz


def test_demo_aggressor_at_the_victims_effective_prf():
    """The demo's aggressor runs at the victim's mean pulse interval (measured here from the
    victim's fire times), as the README and the demo say, with the frequencies they give."""
    times = []
    code = 0
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["sequence", "--mode", "masked", "--mask-width", "6", "--seed", "0xACE1",
                     "--times", "--count", "20001"])
    assert code == 0
    times = [int(value) for value in out.getvalue().split()]
    mean_interval = (times[-1] - times[0]) / (len(times) - 1)
    assert abs(effective_period(80, mask_width=6) - mean_interval) < 1
    assert effective_period(80) == 80                    # FLISS off: no delays
    # the README's figures: the clock over those periods
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert (f"at the victim's effective PRF (its mean pulse rate, to a whole clock cycle: "
            f"1 MHz with FLISS off, "
            f"{80e6 / effective_period(80, mask_width=6) / 1e3:.1f} kHz with masked delays)"
            ) in readme
