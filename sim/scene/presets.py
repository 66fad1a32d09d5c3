"""Detectors with published figures, by name: :data:`PRESETS`.

Each value's source, and the assumptions made where a figure is not published, are in
``docs/scene.md`` (section *Detector presets*); a value the sources do not give is the model's
default (noted there), never a guess presented as a figure.
"""

from .detector import Detector


__all__ = ["PRESETS"]


#: Detector presets by name.
PRESETS = {
    # The paper's sensor (60 x 1 column, 180 nm CIS, Table 1): the paper publishes no SPAD
    # figure; the model's defaults (20 ns non-paralysable dead time, 100 ps jitter).
    "paper": Detector(),
    # Thorlabs SPCM20A single-photon counting module (Si SPAD, 20 um): 25 Hz dark counts
    # (typical), photon detection probability 35 % (typical, at its 500 nm peak), a count
    # every 35 ns at most (28 MHz maximum count rate); jitter and afterpulsing not published
    # in the source: the 300 ps FWHM of a comparable module (EG&G SPCM-AQ) assumed, no
    # afterpulsing.
    "spcm20a": Detector(pdp=0.35, dark_count_hz=25.0, dead_time_s=35e-9,
                        jitter_fwhm_s=300e-12),
    # LinoSPAD2 SPAD array: median dark count rate 125 counts/s per pixel, nearest-neighbour
    # crosstalk 0.22 % (average); the rest not published in the source: the model's defaults.
    "linospad2": Detector(dark_count_hz=125.0, crosstalk_orthogonal=0.0022),
}
