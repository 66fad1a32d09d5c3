"""Public names of a package, imported from their modules when first asked for (PEP 562).

The register map (:mod:`fliss.hdl.registers`) imports the delay core's definitions, and the
blocks import the register map: a package that imported its blocks to offer them by name would
make a circle. :func:`lazy_names` gives such a package its ``__getattr__`` and ``__dir__``.
"""

import importlib
import sys


__all__ = ["lazy_names"]


def lazy_names(package, public):
    """``(__getattr__, __dir__)`` for the package named ``package``: each name of ``public``
    (``{name: relative module}``) is imported from its module when first asked for."""
    def get(name):
        if name not in public:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(public[name], package), name)

    def names():
        return sorted(set(vars(sys.modules[package])) | set(public))

    return get, names
