"""The keyed source's IVs as the host sees them: a run in ``keyed`` mode refused before its
START when the board reports that its keyed source has used every IV under its key (STATUS
``ivs_used_up``: the IV in use is the last, ``2**80 - 1``, and its keystream was used). The board
would run and fire no laser pulse (it never wraps the IV around to 0 under the same key); only a
new key ends it (no IV is above the last).
"""

from typing import Mapping, Optional

from ..hdl.delay.modes import mode_row
from ..hdl.registers import value_of
from .errors import IvsUsedUp


__all__ = ["USED_UP", "used_up", "refuse_used_up", "used_up_by"]


#: Why a run in keyed mode fires no pulse, in a few words.
USED_UP = "the keyed source has used every IV under its key; write a new key"


def _keyed(registers: Mapping[str, int]) -> bool:
    row = mode_row(registers["delay_mode"])
    return row is not None and row.keyed


def used_up(registers: Mapping[str, int], status: Mapping[str, int]) -> Optional[str]:
    """One line saying why a run with ``registers`` (as the board reads them: the IV in use)
    fires no pulse, when the board's STATUS ``status`` says its keyed source has used every IV
    under its key and the mode is keyed; else None."""
    if not status.get("ivs_used_up") or not _keyed(registers):
        return None
    return (f"the keyed source has used every IV under its key (the IV in use, "
            f"{value_of(registers, 'iv'):#022x}, is the last): in keyed mode the board would "
            f"fire no laser pulse; write a new key (fliss config --key HEX, or --key random)")


def refuse_used_up(registers: Mapping[str, int], status: Mapping[str, int]) -> None:
    """Raise :exc:`~fliss.host.errors.IvsUsedUp` with :func:`used_up`'s line, if it has one."""
    message = used_up(registers, status)
    if message is not None:
        raise IvsUsedUp(message)


def used_up_by(status_start: Mapping[str, int], status_end: Optional[Mapping[str, int]]
               ) -> Optional[str]:
    """One line when the board's keyed source used its last IV during a run (STATUS
    ``ivs_used_up`` from 0 at ``status_start`` to 1 at ``status_end``): the next run in keyed
    mode will fire no pulse; else None."""
    if status_end is None or not status_end.get("ivs_used_up") or \
            status_start.get("ivs_used_up"):
        return None
    return ("the keyed source has used every IV under its key (this run used the last): a run "
            "in keyed mode fires no laser pulse until a new key is written (fliss config "
            "--key HEX, or --key random)")
