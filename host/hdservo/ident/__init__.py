"""Identification of a harmonic-drive axis.

Experiments are defined once (:mod:`.experiments`) and run on the simulator
(:class:`.experiments.SimRunner`) or, later, on a drive over CAN; each fit
lives in its own module:

* :mod:`.friction` -- gravity/inertia sweep, Stribeck static map (NLS),
  LuGre presliding;
* :mod:`.stribeck_online` -- recursive least squares on the Stribeck model
  made linear by a grid over the Stribeck velocity;
* :mod:`.stiffness` -- three-slope (+ Maxwell-slip) and cubic stiffness,
  catalogue hysteresis loss and lost motion;
* :mod:`.hysteresis` -- Maxwell-slip NNLS, Preisach Everett function from
  first-order reversal curves, firmware table;
* :mod:`.te` -- transmission-error harmonics in the wave-generator angle;
* :mod:`.frf` -- H1 / closed-loop FRF, coherence, two-mass fit;
* :mod:`.model_toml` -- the identified axis/model TOML;
* :mod:`.report` -- plots and the JSON report.
"""
from __future__ import annotations
