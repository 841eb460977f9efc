"""Model-discrepancy workflow: find the physics a baseline axis model lacks.

Modules
-------
signals    log -> filtered states and parallel-filtered regression data
baseline   the baseline model (two-mass or rigid) and its least-squares fit
effects    the candidate library: signature, parametric form, fitter per effect
residuals  spectra, order analysis, whiteness, effective sample count
simerr     simulation error: the model driven by the measured torque over 50 ms windows
workflow   rank candidates by evidence (BIC with parameter penalty), name, add, re-fit, stop
plots      residual before/after versus time and the revealing coordinate; gap per iteration
cases      synthetic test logs from the simulator (one hidden effect each), for tests/results

See docs/discrepancy.md.
"""
from __future__ import annotations

#: Effect names the workflow can attribute a residual to.
EFFECT_NAMES: tuple[str, ...] = (
    "stribeck_friction", "asymmetric_friction", "transmission_error", "cogging_torque",
    "nonlinear_stiffness", "hysteresis", "backlash", "gravity_unbalance",
    "unmodelled_compliance", "current_loop_lag",
)
