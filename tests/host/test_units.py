"""Quantities with units (:mod:`fliss.host.units`): a number too large for a float is refused
with a ValueError of one line, as every other bad quantity (the new-user pass of issue 41:
``fliss prf-table --prf 1e400Hz`` ended in an OverflowError traceback)."""

import pytest

from fliss.host.cli import main
from fliss.host.units import parse_baud, parse_frequency, parse_time


@pytest.mark.parametrize("parse, text, what", [
    (parse_frequency, "1e400Hz", "frequency"),
    (parse_time, "1e400s", "time"),
    (parse_time, "-1e400ms", "time"),
    (parse_baud, "1e400", "baud rate"),
])
def test_a_number_beyond_floats_is_refused(parse, text, what):
    with pytest.raises(ValueError) as error:
        parse(text)
    assert str(error.value) == f"{what} {text!r} is beyond any number a computer holds"


def test_the_commands_refuse_it_in_one_line(capsys):
    assert main(["prf-table", "--prf", "1e400Hz"]) == 1
    out, err = capsys.readouterr()
    assert (out, err) == ("", "fliss: error: --prf 1e400Hz: frequency '1e400Hz' is beyond any "
                              "number a computer holds\n")
