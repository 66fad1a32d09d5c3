"""The sub-commands of ``fliss``, one module per command (:mod:`fliss.host.cli` loads them).

Each module provides ``register(subparsers, formatter)``, which adds its parser and sets
``run(args)`` as its ``run`` default. Commands sit above the library (:mod:`fliss.host`) and do
not import each other; what several share is in :mod:`.common` (progress lines, signals),
:mod:`.port_options` and :mod:`.setting_options` (the options that reach a board and set it).
"""
