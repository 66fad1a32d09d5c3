"""The fine TDC's code-density calibration on a board, and its calibration table.

:func:`calibrate` puts the fine TDC on the on-chip oscillator (``tdc_input`` 1, hits
uncorrelated with the clock) with raw tap codes as timestamps (``tdc_source`` 3), histograms
them with the board's own histogram readout (``bin_shift`` 0: one bin a code), computes the
table with :mod:`fliss.analysis.calibration`, writes it to the board's table registers, reads
it back and compares, and puts the settings it changed back as they were.

The table is reached through a pointer (:data:`fliss.hdl.registers.FINE_TDC`): a WRITE of
``table_address`` moves it, each WRITE of ``table_data`` writes the entry at the pointer and
moves it on, a READ of ``table_data`` gives the entry at the pointer. :func:`read_table` reads
the whole table (a capture with the fine TDC records it); :func:`has_fine_tdc` asks whether the
board's build has the fine TDC at all (a smaller build refuses ``table_address`` other than 0).
"""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..analysis import calibration as _analysis
from ..hdl.finetdc import CODE_BITS, TABLE_BITS, UNIT_S, HitInput
from ..hdl.protocol import NakCode
from ..hdl.registers import AcquisitionMode, TdcSource
from .client import BoardClient
from .errors import BoardRefused, CalibrationError


__all__ = ["TABLE_ENTRIES", "OSCILLATOR_INPUT", "Calibration", "has_fine_tdc", "read_table",
           "write_table", "code_counts", "calibrate"]


#: Entries of the calibration table (raw codes 0 to ``2**CODE_BITS - 1``).
TABLE_ENTRIES = 1 << CODE_BITS
#: ``tdc_input`` of the on-chip oscillator.
OSCILLATOR_INPUT = HitInput.OSCILLATOR.value
#: The registers :func:`code_counts` changes, and puts back.
_CHANGED = ("acquisition", "tdc_source", "tdc_input", "bin_shift", "integration", "pixel_bits")


@dataclass(frozen=True)
class Calibration:
    """A code-density calibration.

    Attributes
    ----------
    counts : numpy.ndarray
        Hits per raw code (``TABLE_ENTRIES`` codes).
    table : numpy.ndarray
        The table written: each code's fine time in 12.5 ps units.
    clock_hz : int
    """
    counts: np.ndarray
    table: np.ndarray
    clock_hz: int

    @property
    def first_code(self) -> int:
        return int(np.flatnonzero(self.counts)[0])

    @property
    def last_code(self) -> int:
        return int(np.flatnonzero(self.counts)[-1])

    @property
    def empty_codes(self) -> np.ndarray:
        """Codes from the first to the last one hit that no hit fell on (taps the calibration
        does not cover)."""
        used = self.counts[self.first_code:self.last_code + 1]
        return self.first_code + np.flatnonzero(used == 0)

    @property
    def mean_code_s(self) -> float:
        """Mean width of the codes hit: the clock period over their number."""
        return 1 / self.clock_hz / (self.last_code - self.first_code + 1)

    @property
    def dnl_max(self) -> float:
        return float(np.abs(_analysis.dnl(self.counts)).max())

    @property
    def inl_max(self) -> float:
        return float(np.abs(_analysis.inl(self.counts)).max())


def has_fine_tdc(client: BoardClient, current: Optional[dict] = None) -> bool:
    """Whether the board's build has the fine TDC: it takes a move of the table's pointer
    (which it puts back)."""
    current = client.read_registers() if current is None else current
    address = current["table_address"]
    try:
        client.write_registers({"table_address": 1 - min(address, 1)}, current=current)
    except BoardRefused as error:
        if error.code != NakCode.OUT_OF_RANGE:
            raise
        return False
    client.write_registers({"table_address": address}, current=current)
    return True


def read_table(client: BoardClient, current: Optional[dict] = None) -> np.ndarray:
    """The board's calibration table, read back entry by entry (``uint16``)."""
    current = client.read_registers() if current is None else current
    table = np.zeros(TABLE_ENTRIES, dtype=np.uint16)
    for code in range(TABLE_ENTRIES):
        client.write_registers({"table_address": code}, current=current)
        table[code] = client.read_registers(["table_data"])["table_data"]
    return table


def write_table(client: BoardClient, table, current: Optional[dict] = None) -> None:
    """Write ``table`` (``TABLE_ENTRIES`` entries in 12.5 ps units) to the board, read it back
    and compare; :exc:`CalibrationError` if the board does not keep it."""
    table = np.asarray(table)
    if table.shape != (TABLE_ENTRIES,) or table.min() < 0 or table.max() >= 1 << TABLE_BITS:
        raise CalibrationError(f"a calibration table has {TABLE_ENTRIES} entries from 0 to "
                               f"{(1 << TABLE_BITS) - 1}")
    current = client.read_registers() if current is None else current
    # Each entry by one WRITE of its address and value together, which the board applies
    # address first: a WRITE the host re-sends (its reply late or lost) writes the same entry
    # again, where a WRITE of the value alone would move the pointer on twice.
    for code, value in enumerate(table):
        client.write_registers({"table_address": code, "table_data": int(value)},
                               current=current)
    back = read_table(client, current)
    wrong = np.flatnonzero(back != table)
    if len(wrong):
        code = int(wrong[0])
        raise CalibrationError(f"the board on {client.port_name} did not keep its calibration "
                               f"table: {len(wrong)} entries read back differ (code {code}: "
                               f"wrote {int(table[code])}, read {int(back[code])})")


def code_counts(board, duration_s: float = 1.0, *, integration_s: float = 0.1) -> np.ndarray:
    """Hits per raw code from the on-chip oscillator over ``duration_s``, with the board's
    histogram readout (a :class:`~fliss.host.board.Board` with the fine TDC); the settings
    changed are put back."""
    client = board.client
    before = client.read_registers()
    if not has_fine_tdc(client, before):
        raise CalibrationError(f"the board on {client.port_name} has no fine TDC (its build "
                               f"refuses the fine TDC's registers; only the ULX3S's has one)")
    integration_s = min(integration_s, duration_s)
    cycles = max(1, round(integration_s * board.clock_hz))
    frames = max(1, round(duration_s / integration_s))
    board.stop()
    current = client.write_registers({
        "acquisition": AcquisitionMode.HISTOGRAM.value, "tdc_source": TdcSource.FINE_RAW.value,
        "tdc_input": OSCILLATOR_INPUT, "bin_shift": 0, "integration": cycles, "pixel_bits": 0},
        current=before)
    try:
        histograms = board.acquire(frames)
    finally:
        client.write_registers({name: before[name] for name in _CHANGED}, current=current)
    counts = np.asarray(histograms.counts, dtype=np.int64).sum(axis=0)
    return counts[:TABLE_ENTRIES]


def calibrate(board, duration_s: float = 1.0, *, integration_s: float = 0.1) -> Calibration:
    """Calibrate the board's fine TDC by code density (histograms of ``integration_s``) and store
    the table on the board (read back and compared); returns the :class:`Calibration`."""
    counts = code_counts(board, duration_s, integration_s=integration_s)
    if not counts.sum():
        raise CalibrationError(f"the fine TDC of the board on {board.port} saw no hits from "
                               f"its oscillator in {duration_s:g} s")
    table = _analysis.table(counts, 1 / board.clock_hz, UNIT_S, width=TABLE_BITS)
    write_table(board.client, table)
    return Calibration(counts, table, board.clock_hz)
