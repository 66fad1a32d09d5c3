"""Fixtures of the board tests."""

import pytest

from fliss.boards import fliss_top_up5k


@pytest.fixture(scope="module")
def up5k_maxima():
    """The iCEBreaker build's register maxima (at 80 MHz)."""
    return fliss_top_up5k(80_000_000).register_maxima()
