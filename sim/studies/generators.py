"""What the attacker may assume a victim's delay source to be: the public generators.

Each hypothesis reads the recovered delays ``d`` of a run of consecutive pulses as observations
``x = d + offset`` of a linear register and tells the first window of pulses from which it can
predict, with its predictions checked (see :mod:`fliss.sim.studies.attacker` for the lock rule):

* :class:`KnownTaps`: ``mseq`` of length ``L`` (the delay is the whole register minus one:
  ``x = d + 1``, one register step per pulse) or ``masked`` of width ``Wm`` (``x = d``, the low
  ``Wm`` bits of a 32-bit register stepped ``MASKED_STEPS`` times per pulse), taps from the
  polynomial table. The register state at the window's first pulse is solved by linear algebra
  over GF(2) from the first ``n`` pulses (the fewest whose bits determine it); the next ``V``
  pulses are predicted and compared. All windows are tried at once, vectorised.
* :class:`UnknownTaps`: the taps are unknown; Berlekamp–Massey runs on bit 0 of ``x`` and the
  recurrence it finds predicts every bit of the next ``x`` (all bits of a register's outputs obey
  the register's characteristic polynomial). It runs on a window of bounded length: when the
  linear complexity passes ``max_complexity`` it starts again, so memory and time per pulse stay
  bounded whatever the victim.
"""

import math

import numpy as np

from ...hdl.delay.settings import (MASKED_LENGTH, MASKED_STEPS, MAX_LENGTH, MAX_MASK_WIDTH,
                                   MIN_LENGTH)
from . import gf2
from ..models import lfsr as _lfsr


__all__ = ["KnownTaps", "UnknownTaps", "verify_pulses", "hypotheses"]


def verify_pulses(width, verify_bits, minimum=4):
    """Pulses whose predictions must hold before a lock: at least ``minimum`` and at least
    ``verify_bits`` predicted bits, ``width`` bits a pulse."""
    return max(minimum, math.ceil(verify_bits / max(width, 1)))


def _jump_columns(bits, steps):
    """Image of each basis state after ``steps`` register steps."""
    if steps == 0:
        return [1 << bit for bit in range(bits)]
    return [int(_lfsr.states(bits, 1 << bit, 2, steps=steps)[1]) for bit in range(bits)]


def _transpose(columns, bits):
    """Rows of the matrix whose columns are given (both as integers)."""
    return [sum(((column >> row) & 1) << index for index, column in enumerate(columns))
            for row in range(bits)]


def _tables(columns):
    """Byte lookup tables of the linear map with these columns, for :func:`_map`."""
    tables = np.zeros(((len(columns) + 7) // 8, 256), dtype=np.uint64)
    for byte in range(tables.shape[0]):
        for bit in range(8):
            index = 8 * byte + bit
            if index < len(columns):
                tables[byte, 1 << bit:2 << bit] = tables[byte, :1 << bit] ^ \
                    np.uint64(columns[index])
    return tables


def _map(tables, values):
    values = values.astype(np.uint64)
    result = np.zeros_like(values)
    for byte in range(tables.shape[0]):
        result ^= tables[byte][(values >> np.uint64(8 * byte)) & np.uint64(0xff)]
    return result


def _window_ok(valid, linked, size):
    """``ok[a]``: pulses ``a … a + size - 1`` are all valid and each linked to the previous."""
    count = len(valid)
    if count < size:
        return np.zeros(0, dtype=bool)
    bad = np.concatenate(([0], np.cumsum(~valid)))
    cut = np.concatenate(([0], np.cumsum(~linked)))
    starts = np.arange(count - size + 1)
    return ((bad[starts + size] - bad[starts]) == 0) & \
           ((cut[starts + size] - cut[starts + 1]) == 0)


class KnownTaps:
    """The hypothesis "``mseq`` of length ``size``" or "``masked`` of width ``size``".

    Parameters
    ----------
    mode : str
        ``"mseq"`` or ``"masked"``.
    size : int
        ``L`` or ``Wm``.
    verify_bits : int
        Predicted bits that must hold before a lock (see :func:`verify_pulses`).
    """

    def __init__(self, mode, size, *, verify_bits=48):
        if mode == "mseq":
            _lfsr.check_length(size)
            self.bits, self.steps, self.width, self.offset = size, 1, size, 1
        elif mode == "masked":
            if not isinstance(size, int) or not 1 <= size <= MAX_MASK_WIDTH:
                raise ValueError(f"Mask width must be from 1 to {MAX_MASK_WIDTH}, not {size!r}")
            self.bits, self.steps, self.width, self.offset = MASKED_LENGTH, MASKED_STEPS, size, 0
        else:
            raise ValueError(f"A known-taps hypothesis is 'mseq' or 'masked', not {mode!r}")
        self.mode, self.size = mode, size
        self.name = f"{mode} {'L' if mode == 'mseq' else 'Wm'}={size}, known taps"
        # Rows of the observation matrix, pulse after pulse, until they determine the state
        self._verify_bits = verify_bits
        self.verify_pulses = verify_pulses(self.width, verify_bits)
        low = (1 << self.width) - 1
        step = _transpose(_jump_columns(self.bits, self.steps), self.bits)
        jumps = [[1 << bit for bit in range(self.bits)]]     # columns of the map of i pulses
        rows = []
        while gf2.rank(rows, self.bits) < self.bits:
            rows += [sum(((column >> j) & 1) << b for b, column in enumerate(jumps[-1]))
                     for j in range(self.width)]
            jumps.append([gf2.apply(step, column) for column in jumps[-1]])
        self.solve_pulses = len(jumps) - 1
        inverse = gf2.left_inverse(rows, self.bits)
        self._solve = [_tables([sum(((inverse[r] >> (i * self.width + j)) & 1) << r
                                    for r in range(self.bits)) for j in range(self.width)])
                       for i in range(self.solve_pulses)]
        self._identity = self.solve_pulses == 1 and self.width == self.bits
        # Predictions of the pulses after the solved ones, as many as the narrowest delays need
        self._predict = []
        for _ in range(verify_pulses(1, verify_bits)):
            self._predict.append(_tables([column & low for column in jumps[-1]]))
            jumps.append([gf2.apply(step, column) for column in jumps[-1]])

    @property
    def window(self):
        """Pulses from the first of a window to its lock: solve plus verify."""
        return self.solve_pulses + self.verify_pulses

    @property
    def theory_pulses(self):
        """Pulses needed in theory to determine the state: ``ceil(bits / width)``."""
        return -(-self.bits // self.width)

    def observations(self, delays):
        """``x`` of each delay and whether it is a possible output of this source."""
        x = np.asarray(delays, dtype=np.int64) + self.offset
        valid = (x >= self.offset) & (x < (1 << self.width))
        return np.where(valid, x, 0), valid

    def first_lock(self, delays, linked, *, chunk=1 << 16):
        """The first window whose predictions all hold: ``(lock pulse, first pulse, state
        there)`` or ``None``. ``linked[k]`` says pulse ``k`` follows pulse ``k - 1`` with none
        missed. The predictions checked are :func:`verify_pulses` of the width of the largest
        delay of the window (at most the hypothesis's width)."""
        delays = np.asarray(delays, dtype=np.int64)
        x, valid = self.observations(delays)
        linked = np.asarray(linked, dtype=bool)
        ok = _window_ok(valid, linked, self.window)
        best = None
        for begin in range(0, len(ok), chunk):
            starts = np.flatnonzero(ok[begin:begin + chunk]) + begin
            if len(starts) == 0:
                continue
            if self._identity:
                states = x[starts].astype(np.uint64)
            else:
                states = np.zeros(len(starts), dtype=np.uint64)
                for i, tables in enumerate(self._solve):
                    states ^= _map(tables, x[starts + i])
            for i in range(self.verify_pulses):
                keep = _map(self._predict[i], states) == \
                    x[starts + self.solve_pulses + i].astype(np.uint64)
                starts, states = starts[keep], states[keep]
                if len(starts) == 0:
                    break
            for start, state in zip(starts.tolist(), states.tolist()):
                if best is not None and start + self.window - 1 >= best[0]:
                    break
                lock = self._extend(x, valid, linked, delays, start, state)
                if lock is not None and (best is None or lock < best[0]):
                    best = (lock, start, state)
            if best is not None:
                return best
        return best

    def _extend(self, x, valid, linked, delays, start, state):
        # Checks the further predictions narrow delays need; the lock pulse or None.
        end = start + self.window
        width = max(1, int(delays[start:end].max()).bit_length())
        needed = verify_pulses(min(width, self.width), self._verify_bits)
        while end < start + self.solve_pulses + needed:
            if end >= len(x) or not valid[end] or not linked[end]:
                return None
            if int(_map(self._predict[end - start - self.solve_pulses],
                        np.array([state], dtype=np.uint64))[0]) != int(x[end]):
                return None
            width = max(width, int(delays[end]).bit_length())
            needed = verify_pulses(min(width, self.width), self._verify_bits)
            end += 1
        return end - 1

    def predict(self, state, count):
        """Delays of ``count`` pulses from the one whose register state is ``state``."""
        if state == 0:
            values = np.zeros(count, dtype=np.int64)
        else:
            values = _lfsr.states(self.bits, state, count, steps=self.steps).astype(np.int64)
        return (values & ((1 << self.width) - 1)) - self.offset


class UnknownTaps:
    """The hypothesis "an LFSR of unknown taps", found by Berlekamp–Massey.

    Parameters
    ----------
    offset : int
        1 to read delays as ``mseq`` register states (``x = d + 1``), 0 as ``masked`` bits.
    max_complexity : int
        Longest register looked for; the window starts again beyond it.
    verify_bits : int
        Predicted bits that must hold before a lock.
    """

    def __init__(self, offset, *, max_complexity=MAX_LENGTH + 8, verify_bits=48):
        self.offset = offset
        self.max_complexity = max_complexity
        self.verify_bits = verify_bits
        self.name = f"{'mseq' if offset else 'masked'}-like, unknown taps (Berlekamp-Massey)"

    def first_lock(self, delays, linked, *, stop=None):
        """The first pulse at which the recurrence has been checked: ``(pulse, (connection,
        history))`` or ``None``; ``history`` holds the last ``x`` values, newest last. Scans at
        most to pulse ``stop``."""
        x = np.asarray(delays, dtype=np.int64) + self.offset
        valid = x >= 0
        stop = len(x) if stop is None else min(stop, len(x))
        machine, words, streak, width = None, [], 0, 1
        for k in range(stop):
            if not valid[k] or machine is None or not linked[k] or \
                    machine.length > self.max_complexity:
                machine, words, streak, width = gf2.BerlekampMassey(), [], 0, 1
                if not valid[k]:
                    machine = None
                    continue
            value = int(x[k])
            connection, length = machine.connection, machine.length
            if len(words) >= length:
                predicted = 0
                for lag in range(1, length + 1):
                    if connection >> lag & 1:
                        predicted ^= words[-lag]
                hit = predicted == value
            else:
                hit = False
            changed = machine.push(value & 1)
            words.append(value)
            if len(words) > self.max_complexity + 1:
                del words[0]
            width = max(width, int(delays[k]).bit_length())
            streak = streak + 1 if hit and not changed else 0
            needed = verify_pulses(width, self.verify_bits)
            if streak >= needed and machine.count - needed >= 2 * machine.length:
                return k, (machine.connection, list(words[-max(machine.length, 1):]))
        return None

    def predict(self, found, count):
        """The ``count`` delays after the lock pulse, from its ``(connection, history)``."""
        connection, history = found
        length = connection.bit_length() - 1
        words = list(history)
        lags = [lag for lag in range(1, length + 1) if connection >> lag & 1]
        out = np.empty(count, dtype=np.int64)
        for index in range(count):
            value = 0
            for lag in lags:
                value ^= words[-lag]
            words.append(value)
            out[index] = value
            if len(words) > 4 * (length + 1):
                del words[:-(length + 1)]
        return out - self.offset


def hypotheses(*, known_taps=True, unknown_taps=True, verify_bits=48):
    """Every hypothesis an attacker who knows the public design tries."""
    result = []
    if known_taps:
        result += [KnownTaps("mseq", length, verify_bits=verify_bits)
                   for length in range(MIN_LENGTH, MAX_LENGTH + 1)]
        result += [KnownTaps("masked", width, verify_bits=verify_bits)
                   for width in range(1, MAX_MASK_WIDTH + 1)]
    if unknown_taps:
        result += [UnknownTaps(1, verify_bits=verify_bits), UnknownTaps(0, verify_bits=verify_bits)]
    if not result:
        raise ValueError("The attacker needs at least one hypothesis: known or unknown taps")
    return result
