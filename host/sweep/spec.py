"""Sweep specifications: a TOML file naming a point function and a grid of its parameters.

The format is described in ``docs/sweeps.md``. :func:`load` reads and checks a file and returns
a :class:`Spec`; :meth:`Spec.points` expands its grid into points, each a flat dict of parameter
values, and :func:`point_key` and :func:`point_seed` give a point's identity (for resuming) and
its random streams (for determinism). Neither depends on the point's position in the grid, so
adding values to a spec leaves the other points' keys and results unchanged.
"""

import hashlib
import importlib
import itertools
import json
import math
from dataclasses import dataclass, field

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:                 # Python < 3.11
    import tomli as tomllib


__all__ = ["DEFAULT_MODEL", "SpecError", "Spec", "load", "parse", "load_model", "canonical",
           "point_key", "point_seed"]


#: The point function of a spec that names none.
DEFAULT_MODEL = "fliss.sim.studies.interference:evaluate"

_TOP_KEYS = {"description", "model", "seed", "frames", "parameters", "zip"}
_SCALARS = (bool, int, float, str)


class SpecError(ValueError):
    """A sweep specification that cannot be run; the message names the file and the key."""


@dataclass(frozen=True)
class Spec:
    """A checked sweep specification.

    Attributes
    ----------
    model : str
        Point function as ``"package.module:function"``.
    seed : int
        Root of every point's random streams (non-negative).
    axes : list of list of dict
        The grid: one entry per axis, each the list of partial points (one parameter for a plain
        list, several for a ``zip`` group) the axis takes. The points are their product.
    defaults : dict
        Parameters the model fills when a point omits them (its ``PARAMETERS``), or empty.
    description : str
    path : str
        File the spec came from, for messages.
    """
    model: str
    seed: int
    axes: list
    defaults: dict = field(default_factory=dict)
    description: str = ""
    path: str = "<spec>"

    def points(self):
        """Every point of the grid, in grid order, with the model's defaults filled in; a
        default of None (an optional setting, not given) is left out, so that a model's new
        optional parameter leaves the keys and seeds of the points before it unchanged."""
        points = []
        for parts in itertools.product(*self.axes):
            point = {name: value for name, value in self.defaults.items() if value is not None}
            for part in parts:
                point.update(part)
            points.append(point)
        return points

    def varied(self):
        """Names of the parameters that take more than one value."""
        return [name for axis in self.axes if len(axis) > 1 for name in axis[0]]


def _fail(path, key, message):
    raise SpecError(f"{path}: {key}: {message}")


def _scalar(path, key, value):
    if isinstance(value, float) and not math.isfinite(value):
        _fail(path, key, f"{value} is not a finite number")
    if not isinstance(value, _SCALARS):
        _fail(path, key, f"values must be numbers, strings or booleans, not "
                         f"{type(value).__name__}")
    return value


def _values(path, key, value, unique=True):
    """A parameter's values: a non-empty list of scalars, without repeats if ``unique`` (a
    scalar is a list of one)."""
    values = value if isinstance(value, list) else [value]
    if not values:
        _fail(path, key, "an empty list gives no points")
    values = [_scalar(path, key, item) for item in values]
    seen = set()
    for item in values if unique else ():
        marker = canonical(item)
        if marker in seen:
            _fail(path, key, f"{item!r} is listed twice")
        seen.add(marker)
    return values


def load_model(name):
    """Import the point function ``"package.module:function"``; :exc:`SpecError` if impossible."""
    module_name, _, attribute = str(name).partition(":")
    if not module_name or not attribute:
        raise SpecError(f"model {name!r} is not of the form 'package.module:function'")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise SpecError(f"model {name!r}: cannot import {module_name} ({error})") from None
    function = getattr(module, attribute, None)
    if not callable(function):
        raise SpecError(f"model {name!r}: {module_name} has no function {attribute}")
    return function


def _beside(model, name):
    """What the model's module defines as ``name`` (``PARAMETERS``, ``check_point``), or None."""
    return getattr(importlib.import_module(model.partition(":")[0]), name, None)


def parse(data, path="<spec>", *, defaults=None):
    """Check a spec given as the dict TOML gives; returns a :class:`Spec`.

    ``defaults`` overrides the model's ``PARAMETERS`` (which are looked up when it is ``None``
    and the model can be imported); parameter names not among them are refused. When the
    model's module also has ``check_point(point)``, every point is checked by it here, so that a
    bad value is refused before any work starts.
    """
    for key in data:
        if key not in _TOP_KEYS:
            _fail(path, key, f"unknown key (known: {', '.join(sorted(_TOP_KEYS))})")
    model = data.get("model", DEFAULT_MODEL)
    if not isinstance(model, str):
        _fail(path, "model", "must be a string 'package.module:function'")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        _fail(path, "seed", f"must be a non-negative integer, not {seed!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        _fail(path, "description", "must be a string")
    parameters = data.get("parameters", {})
    if not isinstance(parameters, dict):
        _fail(path, "parameters", "must be a table of name = value or name = [values]")
    parameters = dict(parameters)
    if "frames" in data:
        if "frames" in parameters:
            _fail(path, "frames", "given both at the top and in [parameters]")
        parameters["frames"] = data["frames"]
    axes, names = [], set()
    for name, value in parameters.items():
        if isinstance(value, dict):
            _fail(path, f"parameters.{name}", "must be a value or a list, not a table")
        axes.append([{name: item} for item in _values(path, f"parameters.{name}", value)])
        names.add(name)
    groups = data.get("zip", {})
    if not isinstance(groups, dict):
        _fail(path, "zip", "must be a table of groups, [zip.NAME] with equal-length lists")
    for group, columns in groups.items():
        where = f"zip.{group}"
        if not isinstance(columns, dict) or not columns:
            _fail(path, where, "must be a table of name = [values] with equal lengths")
        lengths = set()
        for name, value in columns.items():
            if name in names:
                _fail(path, f"{where}.{name}", "parameter given twice")
            if not isinstance(value, list) or not value:
                _fail(path, f"{where}.{name}", "must be a non-empty list")
            lengths.add(len(value))
            names.add(name)
        if len(lengths) != 1:
            _fail(path, where, f"lists of different lengths ({sorted(lengths)})")
        rows = zip(*(_values(path, f"{where}.{name}", value, False) for name, value in columns.items()))
        axis = [dict(zip(columns, row)) for row in rows]
        if len({canonical(part) for part in axis}) != len(axis):
            _fail(path, where, "a combination is listed twice")
        axes.append(axis)
    if defaults is None:
        try:
            load_model(model)
        except SpecError as error:
            _fail(path, "model", str(error))
        defaults = _beside(model, "PARAMETERS")
        defaults = dict(defaults) if isinstance(defaults, dict) else {}
        check = _beside(model, "check_point")
    else:
        check = None
    if defaults:
        for name in sorted(names):
            if name not in defaults:
                where = f"parameters.{name}" if name in parameters else "zip"
                _fail(path, where, f"unknown parameter of {model} (known: "
                                   f"{', '.join(sorted(defaults))})")
    spec = Spec(model=model, seed=seed, axes=axes, defaults=dict(defaults),
                description=description, path=str(path))
    if callable(check):                     # the model checks its points before any work
        for point in spec.points():
            try:
                check(point)
            except ValueError as error:
                given = {name: point[name] for name in sorted(names)}
                raise SpecError(f"{path}: point {canonical(given)}: {error}") from None
    return spec


def load(path, *, defaults=None):
    """Read and check the TOML spec at ``path``; :exc:`SpecError` names the file and key."""
    try:
        with open(path, "rb") as file:
            data = tomllib.load(file)
    except OSError as error:
        raise SpecError(f"{path}: cannot read ({error.strerror or error})") from None
    except tomllib.TOMLDecodeError as error:
        raise SpecError(f"{path}: not valid TOML ({error})") from None
    except UnicodeDecodeError as error:
        raise SpecError(f"{path}: not valid TOML (not UTF-8 text: byte {error.start})") from None
    return parse(data, path, defaults=defaults)


def canonical(value):
    """A point (or value) as canonical JSON text: sorted keys, no spaces, ints kept apart from
    floats. Equal points give equal text whatever order their keys were written in."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


def point_key(model, seed, point):
    """Hex key of one result: the model, the spec's seed and the point's parameters."""
    text = canonical({"model": model, "seed": seed, "point": point})
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def point_seed(seed, point):
    """The point's :class:`numpy.random.SeedSequence`: from the spec's seed and the point's
    parameters only (not its position in the grid nor the order points finish in)."""
    digest = hashlib.sha256(canonical(point).encode()).digest()
    words = [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4)]
    return np.random.SeedSequence([seed, *words])
