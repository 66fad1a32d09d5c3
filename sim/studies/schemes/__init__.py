"""The field's other interference schemes beside FLISS, on one photon-level model.

Each camera of a frame (the victim and ``cameras - 1`` aggressors, all running the same
scheme) fires as :mod:`~fliss.sim.studies.schemes.emitters` says; the victim's macro-pixel
(:mod:`~fliss.sim.studies.schemes.macropixel`: ``spads`` SPADs with the scene's detector, a
``coincidence``-of-``spads`` gate, a single- or multi-hit TDC) makes a histogram per frame
(:mod:`~fliss.sim.studies.schemes.frame`), which the interference study's detector judges
(:func:`fliss.sim.studies.detection.classify`). Every scheme sends the same echo energy per
frame: ``detections_per_frame`` detected photons (FLISS's at the study's defaults), spread
over its pulses.

Schemes (``scheme``; ``coincidence`` > 1 adds the gate to any of them):

* ``none``: a fixed period ``period_cycles`` on the camera's own oscillator (``± ppm_spread``).
* ``hopping``: PRF hopping, ``hop_periods`` periods ``hop_step_cycles`` apart, a new one every
  ``hop_dwell`` pulses.
* ``fliss``: the gateware's delays (``delay_mode`` ``mseq`` L = ``length`` or ``masked``
  Wm = ``mask_width``), interval mode, each camera its own seed.
* ``code``: a burst of ``code_chips`` pulses at a random Golomb ruler of ``code_slots`` slots
  of ``code_slot_cycles`` cycles every period, a multi-hit TDC, and the histogram correlated
  with the victim's code.

The other point parameters (defaults in :data:`PARAMETERS`): ``cameras`` (1 to 64, the victim
included; the others are its aggressors), ``aggressor_power`` (each aggressor's detections at
the victim's pixel over the victim's echo), ``ppm_spread`` (the aggressors' oscillators, uniform
in ± that many ppm), ``detections_per_frame`` (the echo's energy), ``background_hz`` (ambient
light at the macro-pixel, thinned by the PDP; the sensor's dark counts come on top, per SPAD),
``spads``, ``coincidence`` and ``coincidence_window_ns`` (the gate), ``multi_hit`` and ``keep``
(the TDC: every event, or the ``"last"``/``"first"`` of a window), ``distance_m``,
``t_int_s``, ``threshold_sigma`` (the detector's) and ``frames`` (each its own draw of every
camera). The SPADs' detector: ``sensor_preset`` (a name of :data:`fliss.sim.scene.PRESETS`;
default ``"paper"``) and each setting of ``fliss board`` by the same name with the same values
as text with units (``dead_time = "22ns"``, ``afterpulsing = "1.4%"``, ``dark_count = "7kHz"``,
``paralysable = true``, ``crosstalk = "3.5%"`` with ``spads`` > 1; the table of
:mod:`fliss.sim.scene.detector_options`, as the interference study), each given replacing the
preset's value.

The point's parameters and defaults are :data:`PARAMETERS`; :func:`evaluate` returns ``frames``,
``miss``/``ghost``/``wrong_depth``/``failure`` (a miss or a wrong depth) counts with ``p_*`` and 95 % Wilson bounds ``p_*_lo`` and
``p_*_hi``, the depth error's mean and RMS, ``s_db``, ``pulses_per_frame``,
``detections_per_pulse``, ``windows_per_frame`` and the TDC's events per frame by origin
(``echo_``, ``background_``, ``aggressor_``, ``effect_events_per_frame``: afterpulses and
crosstalk) and the SPADs' counts of the echo (``echo_counts_per_frame``).
"""

from .study import PARAMETERS, REFERENCE_DETECTIONS, check_point, evaluate, pulses_per_frame


__all__ = ["PARAMETERS", "REFERENCE_DETECTIONS", "check_point", "evaluate", "pulses_per_frame"]
