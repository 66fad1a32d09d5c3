"""The timing of a Becker & Hickl SPC file, which the file does not hold: its ``.set`` file
(the module's settings, saved beside it by B&H's SPCM software under the same name) gives the
module and the width of a micro-time channel (``SP_TAC_TC``, the TAC range over its gain and
the ADC's channels). phconvert's :func:`phconvert.bhreader.load_set` reads it.

The ``.spc`` file itself holds the macro-time clock (its first record) and the photons;
phconvert decodes them (:mod:`.tttr_decode`). Only the 32-bit FIFO records of the SPC-130/150/160/180/
830 modules are read: those of the SPC-600/630 and the SPC-QC are of other layouts.
"""

import math
import os
import warnings

from ..errors import FormatError


__all__ = ["spc_timing", "set_file", "MODULES"]


#: Module codes of a ``.set`` file's header (bits 4 to 11 of its ``revision``) whose FIFO files
#: are of the 32-bit SPC-130 layout, by name (B&H's SPC_data_file_structure.h).
MODULES = {0x20: "SPC-130", 0x25: "SPC-830", 0x28: "SPC-150", 0x2A: "SPC-130EM",
           0x2B: "SPC-160", 0x2E: "SPC-150N", 0x80: "SPC-150NX", 0x81: "SPC-160X",
           0x82: "SPC-160PCIE", 0x83: "SPC-130EMN", 0x84: "SPC-180N", 0x85: "SPC-180NX",
           0x86: "SPC-180NXX", 0x87: "SPC-180N-USB", 0x88: "SPC-130IN", 0x89: "SPC-130INX",
           0x8A: "SPC-130INXX"}
#: Other modules, named in a refusal.
_OTHERS = {0x21: "SPC-600", 0x22: "SPC-630", 0x23: "SPC-700", 0x24: "SPC-730",
           0x26: "SPC-140", 0x27: "SPC-930", 0x29: "DPC-230", 0x8B: "SPC-QC-104",
           0x8C: "SPC-QC-004", 0x8D: "SPC-QC-106", 0x8E: "SPC-QC-006"}


def set_file(path):
    """The `.set` file beside the SPC file ``path`` (same name), or None."""
    stem = os.path.splitext(str(path))[0]
    for ending in (".set", ".SET"):
        if os.path.isfile(stem + ending):
            return stem + ending
    return None


def spc_timing(path):
    """``(micro-time width in seconds, module name)`` of the SPC file ``path``, from its
    ``.set`` file; :exc:`FormatError` of one line when there is none, it cannot be read, or
    it names a module of another record layout."""
    setting = set_file(path)
    stem = os.path.splitext(str(path))[0]
    if setting is None:
        raise FormatError(f"{path}: a Becker & Hickl SPC file does not hold the width of its "
                          f"micro-time channels; its .set file ({stem}.set), which does, is not "
                          f"beside it")
    try:
        from phconvert.bhreader import load_set
    except ImportError:
        raise FormatError("SPC files need the phconvert package (it reads their .set files): "
                          "pip install 'fliss[formats]'") from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            meta = load_set(setting)
        revision = int(meta["header"][0]["revision"])
        width_s = float(meta["setup"]["SP_TAC_TC"])
    except Exception as error:              # whatever phconvert finds wrong: one line
        detail = str(error).splitlines()[0] if str(error) else repr(error)
        raise FormatError(f"{setting}: not a Becker & Hickl .set file phconvert can read "
                          f"({detail})") from None
    code = (revision >> 4) & 0xFF
    if code not in MODULES:
        module = _OTHERS.get(code, f"module code 0x{code:02X}")
        raise FormatError(f"{path}: recorded by an {module} (its .set file says), whose FIFO "
                          f"records fliss does not read; fliss reads those of the "
                          f"SPC-130/150/160/180/830 modules")
    if not 0 < width_s < math.inf:
        raise FormatError(f"{setting}: its micro-time width (SP_TAC_TC) is {width_s!r} s, which "
                          f"fliss cannot represent")
    return width_s, MODULES[code]
