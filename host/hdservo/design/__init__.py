"""Harmonic-drive design support: component catalogues and structure-to-model relations.

Modules
-------
catalogue
    Typed loaders of the packaged harmonic-drive, motor and sensor catalogues.
structure
    Analytic relations from flexspline / wave-generator structure to the model
    parameters (stiffness K1-K3, hysteresis, lost motion, friction, resonance).
flexspline_fe
    A 1-D finite-element model of the flexspline's torsional stiffness.
sensitivity
    Normalised sensitivities of resonance and lost motion to structural parameters.
crossval
    Leave-one-size-out / leave-one-ratio-out (held-out) errors of the structure relations.
influence
    Influence laws: elasticities of the servo figures to the nonlinearity parameters,
    by simulation and by describing function.
"""
