"""Linear algebra and linear recurrences over GF(2), for the attacker model.

Vectors are Python integers (bit ``i`` is component ``i``); a matrix is a list of such integers,
one per row. Polynomials are integers too: bit ``i`` is the coefficient of ``x**i``.

A binary sequence ``s`` satisfies the connection polynomial ``C(x) = 1 + c1 x + … + cL x**L``
when ``s[n] = c1 s[n-1] ^ … ^ cL s[n-L]`` for every ``n >= L``; its linear complexity is the
smallest such ``L``. :func:`berlekamp_massey` finds both from ``2 L`` bits (J. L. Massey, "Shift-
register synthesis and BCH decoding", IEEE Trans. Inf. Theory 15, 1969).
"""

import numpy as np


__all__ = ["parity", "apply", "rank", "solve", "left_inverse", "BerlekampMassey",
           "berlekamp_massey"]


def parity(value):
    """The XOR of the bits of ``value``: 0 or 1."""
    return int(value).bit_count() & 1


def apply(rows, vector):
    """The matrix ``rows`` times ``vector``: bit ``i`` of the result is ``rows[i] · vector``."""
    result = 0
    for index, row in enumerate(rows):
        result |= ((row & vector).bit_count() & 1) << index
    return result


def _eliminate(rows, columns):
    """Reduced row echelon form of ``rows`` with each row's combination of the inputs.

    Returns ``{pivot column: (row, combination)}`` and the combinations of the rows that
    reduced to zero; a combination has bit ``i`` set when input row ``i`` takes part.
    """
    pivots = {}
    zeros = []
    for index, row in enumerate(rows):
        row = int(row)
        combination = 1 << index
        for column, (pivot_row, pivot_combination) in pivots.items():
            if row >> column & 1:
                row ^= pivot_row
                combination ^= pivot_combination
        if row == 0:
            zeros.append(combination)
            continue
        column = (row & -row).bit_length() - 1
        if column >= columns:
            raise ValueError(f"Row {index} has a bit beyond column {columns - 1}")
        for other, (other_row, other_combination) in pivots.items():
            if other_row >> column & 1:
                pivots[other] = (other_row ^ row, other_combination ^ combination)
        pivots[column] = (row, combination)
    return pivots, zeros


def rank(rows, columns):
    """Rank of the matrix ``rows`` with ``columns`` columns."""
    return len(_eliminate(rows, columns)[0])


def solve(rows, values, columns):
    """A solution ``x`` of ``rows · x = values`` (bit ``i`` of ``values`` for row ``i``).

    Returns ``None`` when the system has no solution; free unknowns are set to zero.
    """
    pivots, zeros = _eliminate(rows, columns)
    if any(parity(combination & values) for combination in zeros):
        return None
    solution = 0
    for column, (_, combination) in pivots.items():
        # The row is e_column plus free columns only (reduced form); free unknowns are zero.
        solution |= parity(combination & values) << column
    return solution


def left_inverse(rows, columns):
    """A matrix ``P`` with ``P · (rows · x) = x`` for every ``x``: ``columns`` rows over
    ``len(rows)`` bits. Raises :exc:`ValueError` unless ``rows`` has full column rank."""
    pivots, _ = _eliminate(rows, columns)
    if len(pivots) != columns:
        raise ValueError(f"The matrix has rank {len(pivots)}, not {columns}: the unknowns are "
                         f"not determined")
    return [pivots[column][1] for column in range(columns)]


class BerlekampMassey:
    """Berlekamp–Massey over GF(2), one bit at a time.

    Attributes
    ----------
    length : int
        Linear complexity of the bits pushed so far.
    connection : int
        A shortest connection polynomial of them (bit 0 set).
    count : int
        Bits pushed.
    """

    def __init__(self):
        self.length = 0
        self.connection = 1
        self.count = 0
        self._previous = 1          # B(x): the connection before the last length change
        self._shift = 1             # n - m: bits since that change
        self._history = 0           # bit i is s[n-1-i]

    def predict(self):
        """The next bit the current recurrence gives."""
        return parity((self.connection >> 1) & self._history)

    def push(self, bit):
        """Add the next bit; returns the discrepancy (1 when the prediction was wrong)."""
        bit = int(bit) & 1
        discrepancy = bit ^ self.predict()
        if discrepancy:
            previous = self.connection
            self.connection ^= self._previous << self._shift
            if 2 * self.length <= self.count:
                self.length = self.count + 1 - self.length
                self._previous = previous
                self._shift = 1
            else:
                self._shift += 1
        else:
            self._shift += 1
        self.count += 1
        self._history = (self._history << 1) | bit
        return discrepancy


def berlekamp_massey(bits):
    """Linear complexity and a shortest connection polynomial of the bit sequence ``bits``."""
    machine = BerlekampMassey()
    for bit in np.asarray(bits, dtype=np.int64).ravel():
        if bit not in (0, 1):
            raise ValueError(f"Bits must be 0 or 1, not {bit!r}")
        machine.push(bit)
    return machine.length, machine.connection

