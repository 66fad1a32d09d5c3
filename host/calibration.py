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


__all__ = ["TABLE_ENTRIES", "OSCILLATOR_INPUT", "LEAST_HITS_PER_CODE", "TABLE_TOLERANCE_S",
           "TABLE_SAMPLES", "Calibration", "has_fine_tdc", "read_table", "write_table",
           "code_counts", "least_hits", "table_check", "calibrate"]


#: Entries of the calibration table (raw codes 0 to ``2**CODE_BITS - 1``).
TABLE_ENTRIES = 1 << CODE_BITS
#: ``tdc_input`` of the on-chip oscillator.
OSCILLATOR_INPUT = HitInput.OSCILLATOR.value
#: Least hits a code on average for a table: a code's width is its share of the hits, a
#: Poisson count of mean ``n`` whose relative error is ``1 / sqrt(n)``: 20 % (one standard
#: deviation) at 25. With fewer, the table's widths are mostly noise (15 hits over 700 codes
#: give a DNL of some 45 codes).
LEAST_HITS_PER_CODE = 25
#: Largest distance between an entry of the board's table and the same code's time from a
#: fresh code density before the self-test calls the table bad: the nominal table (no
#: calibration since power-up) is off by up to some 250 ps (the taps' drift), a fresh density
#: of 25 hits a code by some 50 ps (one standard deviation at mid-line).
TABLE_TOLERANCE_S = 1e-9
#: Entries of the board's table the self-test reads to compare (each two commands).
TABLE_SAMPLES = 32
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


def read_table(client: BoardClient, current: Optional[dict] = None, *,
               codes=None, progress=None) -> np.ndarray:
    """The board's calibration table, read back entry by entry (``uint16``); with ``codes``,
    those entries only (in their order)."""
    current = client.read_registers() if current is None else current
    codes = range(TABLE_ENTRIES) if codes is None else [int(code) for code in codes]
    table = np.zeros(len(codes), dtype=np.uint16)
    for index, code in enumerate(codes):
        client.write_registers({"table_address": code}, current=current)
        table[index] = client.read_registers(["table_data"])["table_data"]
        if progress is not None:
            progress.update(index + 1, "entries read back")
    return table


def write_table(client: BoardClient, table, current: Optional[dict] = None, *,
                progress=None) -> None:
    """Write ``table`` (``TABLE_ENTRIES`` entries in 12.5 ps units) to the board, read it back
    and compare; :exc:`CalibrationError` if the board does not keep it, or if the writing is
    interrupted (Ctrl-C: the board's table is then partly the new one, which the message says).
    ``progress``, if given, has ``update(done, extra)``: entries written, then read back."""
    table = np.asarray(table)
    if table.shape != (TABLE_ENTRIES,) or table.min() < 0 or table.max() >= 1 << TABLE_BITS:
        raise CalibrationError(f"a calibration table has {TABLE_ENTRIES} entries from 0 to "
                               f"{(1 << TABLE_BITS) - 1}")
    current = client.read_registers() if current is None else current
    # Each entry by one WRITE of its address and value together, which the board applies
    # address first: a WRITE the host re-sends (its reply late or lost) writes the same entry
    # again, where a WRITE of the value alone would move the pointer on twice.
    code = 0
    try:
        for code, value in enumerate(table):
            client.write_registers({"table_address": code, "table_data": int(value)},
                                   current=current)
            if progress is not None:
                progress.update(code + 1, "entries written")
    except KeyboardInterrupt:
        raise CalibrationError(
            f"interrupted while writing the calibration table: the board's table is partial "
            f"(codes 0 to {code - 1} new, {code} to {TABLE_ENTRIES - 1} as they were); "
            f"run fliss calibrate again, or configure the FPGA again for the nominal table") \
            from None
    back = read_table(client, current, progress=progress)
    wrong = np.flatnonzero(back != table)
    if len(wrong):
        code = int(wrong[0])
        raise CalibrationError(f"the board on {client.port_name} did not keep its calibration "
                               f"table: {len(wrong)} entries read back differ (code {code}: "
                               f"wrote {int(table[code])}, read {int(back[code])})")


def code_counts(board, duration_s: float = 1.0, *, integration_s: float = 0.1,
                timeout_s: Optional[float] = None, progress=None) -> np.ndarray:
    """Hits per raw code from the on-chip oscillator over ``duration_s``, with the board's
    histogram readout (a :class:`~fliss.host.board.Board` with the fine TDC), in histograms of
    ``integration_s``, each waited for ``timeout_s`` (None: the board's own wait); the settings
    changed are put back. ``progress``, if given, has ``update(done, extra)``: histograms."""
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
    counts = np.zeros(TABLE_ENTRIES, dtype=np.int64)
    try:
        for done, histogram in enumerate(board.stream(frames, timeout_s=timeout_s), 1):
            counts += np.asarray(histogram.counts, dtype=np.int64)[:TABLE_ENTRIES]
            if progress is not None:
                progress.update(done, f"{int(counts.sum())} hits")
    finally:
        client.write_registers({name: before[name] for name in _CHANGED}, current=current)
    return counts


def least_hits(counts) -> int:
    """The hits a table needs: :data:`LEAST_HITS_PER_CODE` for each code from the first hit
    to the last."""
    used = np.flatnonzero(counts)
    return LEAST_HITS_PER_CODE * (int(used[-1] - used[0]) + 1 if len(used) else TABLE_ENTRIES)


def table_check(client: BoardClient, counts, clock_hz: int) -> Optional[str]:
    """Compare :data:`TABLE_SAMPLES` entries of the board's table, spread over the codes hit,
    with the times the code density ``counts`` gives them; None if each is within
    :data:`TABLE_TOLERANCE_S`, else what is wrong (one line)."""
    fresh = _analysis.table(counts, 1 / clock_hz, UNIT_S, width=TABLE_BITS)
    used = np.flatnonzero(counts)
    codes = np.unique(np.linspace(used[0], used[-1], TABLE_SAMPLES).round().astype(int))
    current = client.read_registers()
    board = read_table(client, current, codes=codes).astype(np.int64)
    client.write_registers({"table_address": current["table_address"]}, current=current)
    off = np.abs(board - fresh[codes].astype(np.int64)) * UNIT_S
    if off.max() <= TABLE_TOLERANCE_S:
        return None
    k = int(np.argmax(off))
    return (f"the board's calibration table looks bad: code {codes[k]} reads "
            f"{board[k] * UNIT_S * 1e12:.0f} ps, the oscillator's codes put it at "
            f"{fresh[codes[k]] * UNIT_S * 1e12:.0f} ps (more than "
            f"{TABLE_TOLERANCE_S * 1e12:.0f} ps apart): run fliss calibrate again")


def calibrate(board, duration_s: float = 1.0, *, integration_s: float = 0.1,
              timeout_s: Optional[float] = None, force: bool = False,
              progress=None) -> Calibration:
    """Calibrate the board's fine TDC by code density (histograms of ``integration_s``, each
    waited for ``timeout_s``) and store the table on the board (read back and compared);
    returns the :class:`Calibration`. Fewer hits than :func:`least_hits` raise
    :exc:`CalibrationError`, the board's table left as it was, unless ``force``.
    ``progress``, if given, is called ``progress(stage)`` with ``"histograms"`` or
    ``"table"`` and returns an object with ``update(done, extra)`` for that stage."""
    counts = code_counts(board, duration_s, integration_s=integration_s, timeout_s=timeout_s,
                         progress=None if progress is None else progress("histograms"))
    if not counts.sum():
        raise CalibrationError(f"the fine TDC of the board on {board.port} saw no hits from "
                               f"its oscillator in {duration_s:g} s")
    hits, needed = int(counts.sum()), least_hits(counts)
    if hits < needed and not force:
        raise CalibrationError(
            f"{hits} hits are too few for a table: it needs {LEAST_HITS_PER_CODE} a code on "
            f"average, {needed} (each code's width then within 20 %), some "
            f"{duration_s * needed / hits:.3g} s of the oscillator; the board's table is left "
            f"as it was (force it to write this one)")
    table = _analysis.table(counts, 1 / board.clock_hz, UNIT_S, width=TABLE_BITS)
    write_table(board.client, table, progress=None if progress is None else progress("table"))
    return Calibration(counts, table, board.clock_hz)
