"""Bit-exact model of :class:`fliss.hdl.delay.source.DelaySource`.

The settings each mode needs, its largest delay, sequence period and mean delay are those of the
table of modes (:data:`fliss.hdl.delay.modes.MODES`); the delays of each mode are made here.
"""

import sys
from functools import lru_cache

import numpy as np

from ...hdl.delay.modes import MODES, SIZES, DelayMode
from ...hdl.delay.settings import LAST_IV, MAX_LENGTH, MASKED_LENGTH, MASKED_STEPS, as_int
from . import lfsr, trivium


__all__ = ["DelayMode", "parse_mode", "check_settings", "delays", "max_delay", "mean_delay",
           "sequence_period", "DelayStream", "MaskedDelays", "block_stream", "next_iv",
           "KeyedRestarts"]


def parse_mode(mode):
    """A :class:`DelayMode` from itself or its name (``"off"``, ``"mseq"``, ``"masked"``,
    ``"keyed"``)."""
    if isinstance(mode, DelayMode):
        return mode
    try:
        return DelayMode[str(mode).upper()]
    except KeyError:
        names = ", ".join(m.name.lower() for m in DelayMode)
        raise ValueError(f"Delay mode must be one of {names}, not {mode!r}") from None


def check_settings(mode, *, length=None, mask_width=None, seed=1, key=None, iv=None):
    """Validate delay settings as a user gives them; return the mode.

    A mode needs the settings its row of :data:`~fliss.hdl.delay.modes.MODES` names: ``length``
    for ``mseq``, ``mask_width`` for ``masked`` and ``keyed``, ``key`` and ``iv`` (10 bytes or an
    80-bit integer, :mod:`fliss.sim.models.trivium`) for ``keyed``. The seed must be a non-zero
    state of the register: from 1 to ``2**L - 1`` (``2**32 - 1`` for ``masked``).
    """
    mode = parse_mode(mode)
    row = MODES[mode]
    if row.keyed:
        if key is None or iv is None:
            raise ValueError(f"The {row.name} delay source needs a key and an IV")
        as_int(key, "key")
        as_int(iv, "IV")
    settings = {"length": length, "mask_width": mask_width}
    if row.size is not None:
        value, size = settings[row.size], SIZES[row.size]
        if value is None:
            raise ValueError(f"The {row.name} delay source needs {size.what}")
        if not isinstance(value, (int, np.integer)) or \
                not size.minimum <= value <= size.maximum:
            raise ValueError(f"{size.noun} must be an integer from {size.minimum} to "
                             f"{size.maximum}, not {value!r}")
    bits = settings[row.seed_bits] if isinstance(row.seed_bits, str) else MAX_LENGTH
    if not isinstance(seed, (int, np.integer)) or not 1 <= seed < (1 << bits):
        raise ValueError(f"Seed must be an integer from 1 to {(1 << bits) - 1} (a non-zero "
                         f"{bits}-bit register state), not {seed!r}")
    return mode


def delays(mode, count, *, length=None, mask_width=None, seed=1, key=None, iv=None):
    """The first ``count`` delays, in clock cycles, after a load; a ``numpy.int64`` array.
    (``keyed``: after a load that initialises with ``iv``, see :class:`KeyedRestarts`.)"""
    mode = check_settings(mode, length=length, mask_width=mask_width, seed=seed, key=key, iv=iv)
    if mode == DelayMode.KEYED:
        return trivium.keyed_delays(key, iv, mask_width, count)
    if mode == DelayMode.MSEQ:
        return lfsr.states(length, seed, count).astype(np.int64) - 1
    if mode == DelayMode.MASKED:
        states = lfsr.states(MASKED_LENGTH, seed, count, steps=MASKED_STEPS)
        return (states & np.uint64((1 << mask_width) - 1)).astype(np.int64)
    return np.zeros(count, dtype=np.int64)


def _shape(mode, length, mask_width):
    # The row of a mode and the settings that shape its delays, checked (the key and IV do not
    # shape them)
    mode = parse_mode(mode)
    key = iv = 0 if MODES[mode].keyed else None
    check_settings(mode, length=length, mask_width=mask_width, key=key, iv=iv)
    return MODES[mode], {"length": length, "mask_width": mask_width}


def max_delay(mode, *, length=None, mask_width=None):
    """Largest delay of the source, in clock cycles
    (:meth:`~fliss.hdl.delay.modes.Mode.max_delay`)."""
    row, settings = _shape(mode, length, mask_width)
    return row.max_delay(**settings)


def sequence_period(mode, *, length=None, mask_width=None):
    """Number of pulses after which the delay sequence repeats; ``None`` for ``keyed`` (its
    period is unknown and far beyond any run: Trivium's state has 288 bits)
    (:meth:`~fliss.hdl.delay.modes.Mode.sequence_period`)."""
    row, settings = _shape(mode, length, mask_width)
    return row.sequence_period(**settings)


def mean_delay(mode, *, length=None, mask_width=None):
    """Mean delay over one whole sequence period, in clock cycles, as an exact fraction
    (:meth:`~fliss.hdl.delay.modes.Mode.mean_delay`)."""
    row, settings = _shape(mode, length, mask_width)
    return row.mean_delay(**settings)


class DelayStream:
    """The delays of a delay source after a load, continued block after block.

    ``take(n)`` returns the next ``n`` delays; consecutive calls give exactly
    :func:`fliss.sim.models.delay.delays` of the total count. Sequences of up to ``2**16`` pulses are
    tabulated once; longer ones advance a block of register states by a precomputed jump.
    """

    TABLE_LIMIT = 1 << 16

    #: Delays of a :meth:`block` of the ``keyed`` source.
    KEYED_BLOCK = 1 << 12

    def __init__(self, mode, *, length=None, mask_width=None, seed=1, block=1 << 16, key=None,
                 iv=None):
        self.mode = check_settings(mode, length=length, mask_width=mask_width, seed=seed,
                                   key=key, iv=iv)
        self._table = None
        self._position = 0
        if self.mode == DelayMode.KEYED:
            self._keystream = trivium.Trivium(key, iv)
            self._mask_width = mask_width
            return
        if self.mode == DelayMode.OFF:
            self._table = np.zeros(1, dtype=np.int64)
            return
        period = sequence_period(self.mode, length=length, mask_width=mask_width)
        if period <= self.TABLE_LIMIT:
            self._table = delays(self.mode, period, length=length, mask_width=mask_width,
                                        seed=seed)
            return
        if self.mode == DelayMode.MSEQ:
            bits, steps = length, 1
            self._offset, self._mask = 1, None
        else:
            bits, steps = MASKED_LENGTH, MASKED_STEPS
            self._offset, self._mask = 0, np.uint32((1 << mask_width) - 1)
        self._states = lfsr.states(bits, seed, block, steps=steps).astype(np.uint32)
        # The map of `block` pulses as two lookup tables of 16 bits each: the image of a state is
        # the XOR of the images of its set bits (the register is linear over GF(2)).
        columns = [int(lfsr.states(bits, 1 << bit, 2, steps=steps * block)[1])
                   for bit in range(bits)]
        self._tables = np.zeros(((bits + 15) // 16, 1 << 16), dtype=np.uint32)
        for half, table in enumerate(self._tables):
            for bit in range(min(16, bits - 16 * half)):
                table[1 << bit:2 << bit] = table[:1 << bit] ^ np.uint32(columns[16 * half + bit])

    @property
    def table(self):
        """One whole period of a tabulated sequence from its start, or ``None``."""
        return self._table

    def _next_states(self):
        # The low and high 16 bits of each state, as strided views of the uint32 array
        halves = self._states.view(np.uint16)
        low, high = (0, 1) if sys.byteorder == "little" else (1, 0)
        result = np.take(self._tables[0], halves[low::2])
        if len(self._tables) > 1:
            result ^= np.take(self._tables[1], halves[high::2])
        self._states = result

    def take(self, count):
        """The next ``count`` delays, as ``numpy.int64``."""
        if self.mode == DelayMode.KEYED:
            bits = self._keystream.bits(count * self._mask_width).reshape(count, -1)
            return (bits.astype(np.int64) << np.arange(self._mask_width)).sum(axis=1)
        if self._table is not None:
            index = (self._position + np.arange(count, dtype=np.int64)) % len(self._table)
            self._position = (self._position + count) % len(self._table)
            return self._table[index]
        pieces = []
        while count > 0:
            if self._position == len(self._states):
                self._next_states()
                self._position = 0
            piece = self._states[self._position:self._position + count]
            self._position += len(piece)
            count -= len(piece)
            pieces.append(piece)
        states = np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.uint32)
        return self._delays_of(states)

    def _delays_of(self, states):
        if self._mask is not None:
            return (states & self._mask).astype(np.int64)
        return states.astype(np.int64) - self._offset

    def block(self):
        """The delays from the current position to the end of the current block of register
        states (all of a block but the first time); the same sequence as :meth:`take`. Only for
        sequences that are not tabulated (``keyed``: the next ``KEYED_BLOCK`` delays)."""
        if self.mode == DelayMode.KEYED:
            return self.take(self.KEYED_BLOCK)
        if self._position == len(self._states):
            self._next_states()
            self._position = 0
        states = self._states[self._position:]
        self._position = len(self._states)
        return self._delays_of(states)


@lru_cache(maxsize=4)
def _basis_states(count):
    """States ``0 … count - 1`` of the masked source's register loaded with each basis vector:
    ``(MASKED_LENGTH, count)`` ``uint32``. The register is linear over GF(2), so the states after
    any seed are the XOR of the rows of its set bits."""
    return np.stack([lfsr.states(MASKED_LENGTH, 1 << bit, count,
                                  steps=MASKED_STEPS).astype(np.uint32)
                     for bit in range(MASKED_LENGTH)])


class MaskedDelays:
    """The delays of the ``masked`` source, block after block, as
    :class:`fliss.sim.models.delay.DelayStream` gives them (the same sequence), made cheaply for many
    seeds: one set of basis states is computed per block length and process, and each block of
    a seed is an XOR of its rows."""

    table = None

    def __init__(self, mask_width, seed, block):
        self._mask = np.uint32((1 << mask_width) - 1)
        self._basis = _basis_states(block)
        self._state = lfsr.load(seed, MASKED_LENGTH)

    def block(self):
        states = np.zeros(self._basis.shape[1], dtype=np.uint32)
        for bit in range(MASKED_LENGTH):
            if self._state >> bit & 1:
                states ^= self._basis[bit]
        # The next block starts one step of the source after the last state
        self._state = int(lfsr.states(MASKED_LENGTH, int(states[-1]), 2,
                                       steps=MASKED_STEPS)[1])
        return (states & self._mask).astype(np.int64)


def block_stream(mode, block, *, length=None, mask_width=None, seed=1, key=None, iv=None):
    """The delays of a delay source after a load, block after block, as the scene simulator
    takes them: an object with ``table`` (:attr:`DelayStream.table`) and ``block()``. The
    ``masked`` source's are :class:`MaskedDelays` of ``block`` delays (cheap for many seeds), the
    other modes' a :class:`DelayStream`."""
    if parse_mode(mode) == DelayMode.MASKED:
        return MaskedDelays(mask_width, seed, block)
    return DelayStream(mode, length=length, mask_width=mask_width, seed=seed, key=key, iv=iv)


def next_iv(iv):
    """The IV after ``iv`` (80-bit integer) in the ``keyed`` source's restarts: ``iv + 1``, or
    None after the last IV (``2**80 - 1``): the IV never wraps around to 0."""
    iv = as_int(iv, "IV")
    return iv + 1 if iv != LAST_IV else None


class KeyedRestarts:
    """Which IV each run of the ``keyed`` source uses, as :class:`fliss.hdl.delay.keyed.KeyedStream`
    decides it.

    A load of the source in ``keyed`` mode (a start, or an update while running) initialises
    Trivium again if the key or IV was written since the last initialisation (with the IV
    written), or if delays were taken since (with :func:`next_iv` of the IV in use); otherwise
    the keystream goes on where it is. The IV never wraps around: once delays were taken from
    the last IV's keystream, the next load (in any mode: the board loads its source in every
    cycle while stopped) with no key or IV written since does not initialise but leaves the
    source spent (it gives no delay) until a load after a key write initialises it;
    :attr:`spent` is True from that load until the write. The board starts with key and IV
    zero, not yet initialised.
    """

    def __init__(self):
        self.key = 0
        self.written_iv = 0
        self.iv = 0
        self._pending = True
        self._used = False
        self._spent = False

    @property
    def spent(self):
        """Every IV under the key is used and no key was written since: no delay (the gateware's
        ``spent``, and STATUS ``ivs_used_up``)."""
        return self._spent and not self._pending

    def write(self, *, key=None, iv=None):
        """The host writes the key, the IV, or both."""
        if key is not None:
            self.key = as_int(key, "key")
        if iv is not None:
            self.written_iv = as_int(iv, "IV")
        self._pending = True

    def load(self, keyed=True):
        """A load of the source, in ``keyed`` mode unless ``keyed`` is False; True if it
        initialises (the IV in use is then :attr:`iv`, the keystream from its start)."""
        following = next_iv(self.iv)
        if not self._pending and self._used and following is None:
            self._spent = True
            return False
        if not keyed:
            return False
        if self._pending:
            self.iv, self._pending, self._used, self._spent = self.written_iv, False, False, False
            return True
        if self._used:
            self.iv, self._used = following, False
            return True
        return False

    def take(self, count=1):
        """``count`` delays are taken from the keystream."""
        if count:
            self._used = True
