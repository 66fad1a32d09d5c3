"""The checks and helpers of the register map (:mod:`fliss.hdl.registers`) that need none of its
tables: a group's values, the key and IV as words, the IV rule, a delay core's settings and the
histogram's pixel split. :func:`fliss.hdl.registers.problems` gathers the checks.

A definitions module: it imports no gateware.
"""

from .event import ADDRESS_BITS, TIMESTAMP_BITS
from .delay.modes import delay_problems
from .delay.settings import BANK_BITS, LAST_IV


__all__ = ["words_of", "value_of", "iv_problem", "group_values", "delay_group_problems",
           "split_problems"]

_U32 = (1 << 32) - 1


def words_of(value, prefix):
    """The registers (``prefix`` 0, 1, 2: ``"key"`` or ``"iv"``) of an 80-bit key or IV."""
    return {f"{prefix}{k}": (value >> (32 * k)) & _U32 for k in range(3)}


def value_of(values, prefix):
    """The 80-bit key or IV of its registers (``prefix`` ``"key"`` or ``"iv"``) in ``values``."""
    return sum(values[f"{prefix}{k}"] << (32 * k) for k in range(3))


def iv_problem(written, values, iv_in_use):
    """The IV rule, as a message or None: a WRITE of the registers named in ``written`` that
    writes the IV (to ``values``) and no key must put the IV above ``iv_in_use``. (None is above
    the last IV, ``2**80 - 1``: after it only a new key goes.)"""
    writes = set(written)
    if not writes & {"iv0", "iv1", "iv2"} or writes & {"key0", "key1", "key2"}:
        return None
    iv = value_of(values, "iv")
    if iv > iv_in_use:
        return None
    if iv_in_use == LAST_IV:
        return (f"the IV in use is the last ({iv_in_use:#022x}): no IV is above it, so only a "
                f"new key can go with a new IV: under one key no IV is used twice")
    return (f"the IV ({iv:#022x}) must be above the IV in use ({iv_in_use:#022x}) unless a "
            f"new key is written with it: under one key no IV is used twice")


def group_values(group, values):
    """The fields of ``group`` from ``values`` (register name -> value), fixed ones included."""
    return {**group.fixed, **{r.field: values[r.name] for r in group.members}}


def delay_group_problems(group, values, keyed=True):
    """The checks of one delay core's settings (its register ``group``) together, as messages
    naming its registers (each register is checked on its own); ``keyed``: whether its core
    has the keyed source."""
    return delay_problems(group_values(group, values),
                          names={r.field: r.name for r in group.members}, ranges=False,
                          keyed=keyed)


def split_problems(values, bank_bits=BANK_BITS):
    """The histogram's pixel split against a bank of ``2**bank_bits`` bins (the build's,
    :attr:`~fliss.hdl.protocol.Identity` ``bank_bits``), as messages: ``2**pixel_bits`` pixels of
    ``2**(13 - bin_shift)`` bins must fit the bank, and the pixels ``first_pixel …
    first_pixel + 2**pixel_bits - 1`` must be addresses of the sensor (below 64)."""
    pixel_bits, shift, first = values["pixel_bits"], values["bin_shift"], values["first_pixel"]
    bin_bits = TIMESTAMP_BITS - shift
    found = []
    if pixel_bits + bin_bits > bank_bits:
        found.append(f"pixel_bits ({pixel_bits}) and bin_shift ({shift}) ask for "
                     f"{1 << pixel_bits} pixels of {1 << bin_bits} bins, more than this "
                     f"board's histogram bank holds ({1 << bank_bits} bins, bank_bits "
                     f"{bank_bits}): pixel_bits + 13 - bin_shift must be at most {bank_bits}")
    pixels = 1 << ADDRESS_BITS
    if first + (1 << pixel_bits) > pixels:
        found.append(f"first_pixel ({first}) plus {1 << pixel_bits} pixels (pixel_bits "
                     f"{pixel_bits}) goes past the last pixel address ({pixels - 1}): "
                     f"first_pixel + 2**pixel_bits must be at most {pixels}")
    return found
