"""Photon-HDF5 files: raw captures written with phconvert, and Photon-HDF5 files read as
captures (h5py).

A raw capture's events become photons (``/photon_data``): ``timestamps`` the laser cycle, in
units of the laser period; ``nanotimes`` the TDC code, in units of the code; ``detectors`` the
pixel address. The settings go where the format has a place for them (``/setup``,
``measurement_specs``, ``nanotimes_specs``, ``/provenance``) and the rest into ``/user/fliss``,
the group Photon-HDF5 leaves to the program that wrote the file (docs/file-format.md).
Photon-HDF5 holds photons one by one, so histogram and image captures have no form here.
"""

import contextlib
import io
import re
import warnings

import h5py
import numpy as np

from ... import __version__
from ...hdl.event import ADDRESS_BITS, TIMESTAMP_BITS
from ...protocol.events import EVENT_DTYPE
from ..errors import FormatError
from ..kinds import for_mode
from .metadata import cycle_chunks, imported, metadata, restored, settings, timing


__all__ = ["write_photon_hdf5", "read_photon_hdf5", "is_photon_hdf5"]


def write_photon_hdf5(capture, path):
    """Write the raw ``capture`` to the Photon-HDF5 file ``path``; returns the number of
    photons (:func:`fliss.host.formats.export_capture` refuses the other modes).

    The photons go into the file run by run (:func:`~.metadata.cycle_chunks`), as extendable
    arrays with phconvert's compression (zlib, level 6); phconvert then writes the rest around
    them and checks the file (``save_photon_hdf5`` with ``h5file``: arrays already in the file
    are kept)."""
    try:
        import phconvert
        import tables
    except ImportError:
        raise FormatError("Photon-HDF5 files need the phconvert package: pip install "
                          "'fliss[formats]'") from None
    # phconvert's own default compression for the files it writes.
    h5file = tables.open_file(str(path), mode="w",
                              filters=tables.Filters(complevel=6, complib="zlib"))
    try:
        data = _photon_data(capture, h5file, tables)
        # phconvert prints the file name and warns of optional fields (wavelengths, author).
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            phconvert.hdf5.save_photon_hdf5(data, h5file=h5file, warnings=False)
    except (ValueError, TypeError, phconvert.hdf5.Invalid_PhotonHDF5) as error:
        if isinstance(error, FormatError):
            raise
        raise FormatError(f"{capture.path}: phconvert cannot write it ({error})") from None
    finally:
        if h5file.isopen:
            h5file.close()
    return len(capture.events)


def _photon_data(capture, h5file, tables):
    # The photons written run by run; the dict phconvert completes the file from.
    period_s, prf_hz = timing(capture)
    events, codes, n = capture.events, 1 << TIMESTAMP_BITS, len(capture.events)
    group = h5file.create_group("/", "photon_data")
    fliss = h5file.create_group(h5file.create_group("/", "user"), "fliss")
    columns = {name: h5file.create_earray(where, name, tables.Atom.from_dtype(np.dtype(dtype)),
                                          (0,), expectedrows=max(1, n))
               for where, name, dtype in ((group, "timestamps", np.int64),
                                          (group, "detectors", np.uint8),
                                          (group, "nanotimes", np.uint16),
                                          (fliss, "collision", np.uint8))}
    detected = np.zeros(1 << ADDRESS_BITS, dtype=np.int64)
    first = last = None
    for start, cycles in cycle_chunks(capture):
        run = events[start:start + len(cycles)]
        columns["timestamps"].append(cycles)
        columns["detectors"].append(run["address"].astype(np.uint8))
        columns["nanotimes"].append(run["timestamp"].astype(np.uint16))
        columns["collision"].append(run["collision"].astype(np.uint8))
        detected += np.bincount(run["address"], minlength=len(detected))
        first = int(cycles[0]) if first is None else first
        last = int(cycles[-1])
    user = dict(settings(capture), collision=columns["collision"])
    if not getattr(capture, "source", None):        # (not another instrument's recording)
        user.update(metadata(capture))
    pixels = np.arange(1 << ADDRESS_BITS, dtype=np.uint8)
    ids = np.flatnonzero(detected).astype(np.uint8)
    duration_s = capture.attrs.get("capture_s")
    if duration_s is None:
        duration_s = float(last - first) * period_s if n else 0.0
    return {
        "description": f"FLISS raw capture {capture.path}: the laser cycle of each event "
                       f"(timestamps), its TDC code (nanotimes), its pixel address "
                       f"(detectors); the settings in /user/fliss",
        "acquisition_duration": float(duration_s),
        "photon_data": {
            "timestamps": columns["timestamps"],
            "detectors": columns["detectors"],
            "nanotimes": columns["nanotimes"],
            "timestamps_specs": {"timestamps_unit": period_s},
            "nanotimes_specs": {"tcspc_unit": capture.code_s, "tcspc_num_bins": codes,
                                "tcspc_range": capture.code_s * codes},
            "measurement_specs": {"measurement_type": "generic",
                                  "laser_repetition_rate": prf_hz,
                                  "detectors_specs": {"spectral_ch1": pixels}},
        },
        "setup": {"num_pixels": len(pixels), "num_spots": 1, "num_spectral_ch": 1,
                  "num_polarization_ch": 1, "num_split_ch": 1, "modulated_excitation": False,
                  "excitation_alternated": [False], "lifetime": True, "excitation_cw": [False],
                  "laser_repetition_rates": [prf_hz],
                  # What phconvert would count from the whole detectors array.
                  "detectors": {"id": ids, "id_hardware": ids, "counts": detected[ids]}},
        "provenance": {"filename": capture.path, "software": "fliss",
                       "software_version": __version__,
                       "creation_time": str(capture.attrs.get("created_utc", ""))},
        "user": {"fliss": user},
    }


def is_photon_hdf5(path):
    """Whether ``path`` is an HDF5 file with Photon-HDF5's ``photon_data`` group(s)."""
    try:
        with h5py.File(path, "r") as f:
            return any(_PHOTON_DATA.fullmatch(name) for name in f)
    except OSError:
        return False


_PHOTON_DATA = re.compile(r"photon_data\d*")


def _value(group, name, default=None):
    if name not in group:
        return default
    value = group[name][()]
    if isinstance(value, bytes):
        return value.decode()
    return value.item() if isinstance(value, np.generic) else value


def read_photon_hdf5(path):
    """The capture of a Photon-HDF5 file: a FLISS export as the raw capture it was made of;
    any other file as the TCSPC histogram of its photons' nanotimes (every spot, every
    detector but those ``detectors_specs/non_photon_id`` names). Refused with one line
    (:exc:`FormatError`): no nanotimes (not a TCSPC measurement), no TCSPC unit, spots of
    different units."""
    try:
        with h5py.File(path, "r") as f:
            return _read(f, path)
    except (OSError, KeyError, TypeError, ValueError, AttributeError, OverflowError) as error:
        if isinstance(error, FormatError):
            raise
        raise FormatError(f"{path}: cannot be read as Photon-HDF5 "
                          f"({str(error).splitlines()[0] if str(error) else error!r})") from None


def _read(f, path):
    fliss = f.get("user/fliss")
    # (FLISS captures of events, the kind that Photon-HDF5 takes, carry a fliss group with
    # their configuration; an export of another instrument's recording has none)
    if isinstance(fliss, h5py.Group) and not for_mode(_value(fliss, "mode")).framed and \
            "configuration" in fliss:
        texts = {name: _value(fliss, name) for name in ("configuration", "identity", "capture")}
        data = f["photon_data"]
        events = np.zeros(len(data["timestamps"]), dtype=EVENT_DTYPE)
        events["pulse"] = data["timestamps"][()].astype(np.int64) & 0xFFFFFFFF
        events["timestamp"] = data["nanotimes"][()]
        events["address"] = data["detectors"][()]
        events["collision"] = fliss["collision"][()]
        return restored(path, texts, events=events)
    counts, unit = None, None
    for name in sorted(name for name in f if _PHOTON_DATA.fullmatch(name)):
        data = f[name]
        if "nanotimes" not in data:
            raise FormatError(f"{path}: /{name} has no nanotimes (not a TCSPC measurement): "
                              f"there is no histogram to analyse")
        spot_unit, bins = _tcspc(f, data)
        if spot_unit is None:
            raise FormatError(f"{path}: /{name} gives no TCSPC unit (nanotimes_specs/"
                              f"tcspc_unit), so its nanotimes have no width")
        if unit is not None and spot_unit != unit:
            raise FormatError(f"{path}: its spots have different TCSPC units ({unit:g} s and "
                              f"{spot_unit:g} s), which add up to no one histogram")
        unit = spot_unit
        nanotimes = data["nanotimes"][()].astype(np.int64)
        others = data.get("measurement_specs/detectors_specs/non_photon_id")
        if others is not None and "detectors" in data:
            nanotimes = nanotimes[~np.isin(data["detectors"][()], others[()])]
        spot = np.bincount(nanotimes, minlength=bins or 0)
        if counts is not None and len(counts) != len(spot):
            size = max(len(counts), len(spot))
            counts, spot = (np.pad(a, (0, size - len(a))) for a in (counts, spot))
        counts = spot if counts is None else counts + spot
    if counts is None:
        raise FormatError(f"{path}: an HDF5 file without photon_data, not Photon-HDF5")
    software = _value(f, "identity/software") or "unknown software"
    return imported(path, counts, unit, f"a Photon-HDF5 file of {software}")


def _tcspc(f, data):
    # (unit in seconds, number of bins) from nanotimes_specs, or /setup/detectors (v0.5).
    specs = data.get("nanotimes_specs")
    if isinstance(specs, h5py.Group) and "tcspc_unit" in specs:
        return float(_value(specs, "tcspc_unit")), int(_value(specs, "tcspc_num_bins", 0))
    detectors = f.get("setup/detectors")
    if isinstance(detectors, h5py.Group) and "tcspc_units" in detectors:
        units = np.unique(detectors["tcspc_units"][()])
        bins = detectors["tcspc_num_bins"][()] if "tcspc_num_bins" in detectors else [0]
        if len(units) == 1:
            return float(units[0]), int(np.max(bins))
    return None, 0
