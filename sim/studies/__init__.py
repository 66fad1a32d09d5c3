"""Studies on the scene simulator.

* :mod:`.detection`: target detection in a histogram, and decision metrics over frames;
* :mod:`.interference`: how often a frame reports a wrong distance, per point of a sweep;
* :mod:`.parameters`: a sweep point's parameters checked one by one;
* :mod:`.schemes`: the field's other interference schemes (no scheme, PRF hopping, pulse codes,
  coincidence) beside FLISS, on one photon-level model of a frame;
* :mod:`.attacker`, :mod:`.generators`, :mod:`.gf2`: an attacker that predicts the victim's
  delays from its emission times, and the public generators it may assume;
* :mod:`.attack_scene`: the attacker in the scene simulator;
* :mod:`.predicting_aggressor`: the attacker as an aggressor of the interference study;
* :mod:`.finetdc`: the fine TDC's figures from its model (non-linearity, precision,
  temperature drift, a scene through the lines).
"""
