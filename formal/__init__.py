"""Formal proofs of the gateware's safety properties (``make formal``).

Each harness module here (``formal/<name>.py``) wraps blocks of :mod:`fliss.hdl` in a small
design with ``Assert``, ``Assume`` and ``Cover`` statements and lists its proofs in ``PROOFS``
(:class:`~fliss.formal.runner.Proof`). :mod:`fliss.formal.runner` runs them with SymbiYosys from
PyPI (the ``formal`` extra): ``python -m fliss.formal --help``. The harnesses are not part of the
synthesised design.
"""
