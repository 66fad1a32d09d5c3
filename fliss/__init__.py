"""FLISS: LiDAR interference suppression with pseudorandom pulse delays.

Subpackages map onto the top-level folders of the repository:

* :mod:`fliss.hdl` (``hdl/``): Amaranth gateware;
* :mod:`fliss.sim` (``sim/``): bit-exact reference models and cocotb testbenches;
* :mod:`fliss.host` (``host/``): the ``fliss`` command;
* :mod:`fliss.boards` (``boards/``): board platforms.

The Python API of a board is here: ``fliss.connect(port)`` gives a :class:`~fliss.host.board.Board`
(settings with units, histograms and events as numpy arrays; README, "Python API").
"""

#: The version of the package, written here only: ``pyproject.toml`` reads it for the
#: distribution, the gateware reports it in its identity (:mod:`fliss.hdl.protocol`), and capture
#: files record it.
__version__ = "0.2.0"

#: The Python API (:mod:`fliss.host.board`), imported when first used: ``fliss.connect(port)``.
_API = {"connect": "board", "Board": "board", "Histogram": "board", "Histograms": "board",
        "Events": "board", "Images": "board", "DepthFrames": "board",
        "Settings": "settings", "RoundingWarning": "settings",
        "BoardError": "errors", "BoardLost": "errors",
        "BoardRefused": "errors", "PortError": "errors", "SettingsError": "errors"}

__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        import importlib

        return getattr(importlib.import_module(f"fliss.host.{_API[name]}"), name)
    raise AttributeError(f"module 'fliss' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_API])
