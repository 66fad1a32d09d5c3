"""What a decoder of another instrument's recording gives (:class:`Recording`), the kinds of
files (:data:`KINDS`), and the refusal of one that is not T3 (:func:`check_mode`): shared by
:mod:`.tttr_decode`, which decodes, and :mod:`.tttr_foreign`, which maps to a capture."""

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..errors import FormatError


__all__ = ["KINDS", "Recording", "check_mode"]


#: What each kind of file is called.
KINDS = {"ptu": "a PTU file", "ht3": "an HT3 file", "pt3": "a PT3 file",
         "spc": "a Becker & Hickl SPC file"}


@dataclass
class Recording:
    """The photons of a file as it holds them: ``sync`` the sync count (macro time, in sync
    periods: ``period_s``), ``micro`` the micro time (in ``width_s``), ``channel`` the
    channel of each; ``records`` the records of the file, of which ``markers`` were markers
    (their ``marker_channels``) and the rest, not photons, overflows (``overflows``);
    ``problems`` what of the file was not as it should be."""
    path: str
    kind: str
    source: str
    sync: np.ndarray
    micro: np.ndarray
    channel: np.ndarray
    period_s: float
    width_s: float
    records: int
    markers: int
    marker_channels: list
    problems: list = field(default_factory=list)
    #: The records its header announces (None: it does not say).
    announced: Optional[int] = None

    @property
    def overflows(self):
        return self.records - len(self.sync) - self.markers


def check_mode(path, kind, mode):
    """Refuse (one line) a file whose measurement mode ``mode`` is not T3 (3)."""
    what = KINDS[kind]
    if mode == 2:
        raise FormatError(f"{path}: a T2 {what.split(' ', 1)[1]} (time tags without a laser "
                          f"sync) holds no TCSPC histogram; fliss reads T3 files")
    if mode != 3:
        raise FormatError(f"{path}: its measurement mode is {mode!r}, not 3 (T3 records); "
                          f"fliss reads T3 files")
