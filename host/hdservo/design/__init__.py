"""Harmonic-drive design support: component catalogues and structure-to-model relations.

Modules
-------
catalogue
    Typed loaders of the packaged harmonic-drive, motor and sensor catalogues.
structure
    Analytic relations from flexspline / wave-generator structure to the model
    parameters (stiffness K1-K3, hysteresis, lost motion, friction, resonance).
flexspline_fe
    Finite-element model of the cup flexspline (scikit-fem, axisymmetric solid with Fourier
    harmonics): torsional stiffness under the tooth load with the wave-generator ellipse
    imposed, torsional and tilting modes with the load.
fe_gear
    The FE flexspline in series with the wave-generator bearing and the tooth mesh (a rule
    validated on held-out sizes); the design flow's FE resonance figures.
fe_study
    The FE studies of ``make results`` (closed forms, convergence, sensitivities).
sensitivity
    Normalised sensitivities of resonance and lost motion to structural parameters.
crossval
    Leave-one-size-out / leave-one-ratio-out (held-out) errors of the structure relations.
influence
    Influence laws: elasticities of the servo figures to the nonlinearity parameters,
    by simulation and by describing function.
"""
