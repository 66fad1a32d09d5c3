"""Formal harnesses of the keyed (Trivium) delay source (``hdl/delay/keyed.py``,
``hdl/delay/trivium.py``), its place in the delay core (``hdl/delay/core.py``) and its registers
(``hdl/regfile.py``: the key and IV).

- ``keyed.start``, ``keyed.interval``, ``keyed.pulses``: the delay core's proofs
  (``formal/delay_core.py``) with the keyed mode allowed, the key, IV and their write strobe free,
  and Trivium abstracted (``formal/_abstract.py``).
- ``keyed.key_hidden``: two register files, given the same commands but different keys,
  answer alike (``formal/_keyed_key.py``).
- ``keyed.iv_rule``: under one key, every initialisation of the keystream uses an IV above the
  one before, with no exception: the IV never wraps around (``formal/_keyed_iv.py``; two
  mutants: the register file's IV rule letting an equal IV through, and the stream wrapping
  around after the last IV as it did before).
- ``keyed.trivium_vectors``: Trivium's keystream from its load equals the published test vector (``formal/_keyed_vectors.py``).
"""

from .delay_core import CoreHarness
from ._keyed_iv import IvRuleHarness, _iv_at_or_above, _wrapping_stream
from ._keyed_key import KeyHiddenHarness, _reading_key
from ._keyed_vectors import VECTORS_DEPTH, TriviumVectorHarness, _mistapped_trivium
from ._mutants import _LateStartTrigger, _NoDelayScheduler, _RuntTrigger
from .runner import Proof


__all__ = ["PROOFS"]


def _core(check, depth, doc, swaps, *, fixed=False):
    return Proof(f"keyed.{check}", lambda: CoreHarness(check, fixed=fixed, keyed=True), "bmc",
                 depth, doc, mutant=lambda: CoreHarness(check, fixed=fixed, keyed=True,
                                                        swaps=swaps))


PROOFS = [
    _core("start", 30, "keyed mode allowed: the laser's rising edge and the TDC start are "
          "always in the same cycle", {"LaserTrigger": _LateStartTrigger}),
    _core("interval", 30, "keyed mode allowed: consecutive pulses exactly T + R apart, never "
          "closer than T", {"PulseScheduler": _NoDelayScheduler}, fixed=True),
    _core("pulses", 30, "keyed mode allowed: no runt, merged or doubled pulse: each exactly "
          "pulse_width cycles high, low at least one cycle between", {"LaserTrigger": _RuntTrigger}),
    Proof("keyed.key_hidden", lambda: KeyHiddenHarness(), "prove", 2,
          "the key is write-only: with different keys written, the register file's read data, "
          "errors, consistency, strobes and every setting but the key are the same",
          mutant=lambda: KeyHiddenHarness(mutate=_reading_key), cover_depth=12),
    Proof("keyed.iv_rule", lambda: IvRuleHarness(), "bmc", 20,
          "under one key, every initialisation of the keystream uses an IV above the one before "
          "(a WRITE of an IV not above the IV in use, without a key, is refused; after the last "
          "IV the stream is spent until a key is written, never wrapping around to IV 0)",
          mutant=(lambda: IvRuleHarness(mutate=_iv_at_or_above),
                  lambda: IvRuleHarness(mutate_stream=_wrapping_stream))),
    Proof("keyed.trivium_vectors", lambda: TriviumVectorHarness(), "bmc", VECTORS_DEPTH,
          "Trivium's keystream equals the published vector from its load",
          mutant=lambda: TriviumVectorHarness(mutate=_mistapped_trivium)),
]
