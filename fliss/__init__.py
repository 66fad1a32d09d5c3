"""FLISS: LiDAR interference suppression with pseudorandom pulse delays.

Subpackages map onto the top-level folders of the repository:

* :mod:`fliss.hdl` (``hdl/``): Amaranth gateware;
* :mod:`fliss.sim` (``sim/``): bit-exact reference models and cocotb testbenches;
* :mod:`fliss.host` (``host/``): the ``fliss`` command;
* :mod:`fliss.boards` (``boards/``): board platforms.
"""

try:
    from importlib.metadata import version as _version

    __version__ = _version("fliss")
except Exception:  # pragma: no cover - running from a tree that was never installed
    __version__ = "0.0.0+unknown"
