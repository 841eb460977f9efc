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

#: Signal sets of a log: both encoders, the motor encoder alone, the output encoder alone
#: (each with the motor torque).
SIGNAL_SETS: tuple[str, ...] = ("both", "motor", "output")

#: What each signal set can reveal (docs/discrepancy.md, "What the signals can show").
#: An effect acting through the twist needs both angles; the transmission error is the
#: output's position error against the motor's, so it needs both too; cogging is periodic
#: in the motor angle, which an output encoder alone gives only as N x output angle plus an
#: unmeasured twist (at order 36 per motor revolution, 1e-4 rad of output twist on N = 100
#: is 0.36 rad of phase), so it needs the motor encoder.  Unmodelled compliance is tested
#: with a rigid baseline on a two-encoder log (the twist acceleration's column).  A
#: current-loop lag needs the motor angle: the output angle sees the torque through the
#: gear's spring, which below the torsional mode delays it like a lag of 2 zeta/omega_0
#: (0.5-1.5 ms on the catalogue axes, the lag of a 100-300 Hz current loop), so an
#: output-only log shows a lag whether the current loop has one or not.  A ranked effect can
#: still have a part the baseline cannot tell from its own terms (the Coulomb part of an
#: asymmetry next to a constant offset): :func:`not_identifiable_parts`.
IDENTIFIABLE: dict[str, tuple[str, ...]] = {
    "both": EFFECT_NAMES,
    "motor": ("stribeck_friction", "asymmetric_friction", "cogging_torque", "gravity_unbalance",
              "current_loop_lag"),
    "output": ("stribeck_friction", "asymmetric_friction", "gravity_unbalance"),
}

#: The phrase the workflow reports for an effect its signals cannot show.
NOT_IDENTIFIABLE = "not identifiable from these signals"

#: Why a Coulomb asymmetry is not identifiable next to a constant torque offset.  Friction
#: with fc+ != fc- (and fs+ != fs- in the same proportion) is, in motion *and* at standstill,
#: symmetric friction of level (fc+ + fc-)/2 plus a constant torque (fc+ - fc-)/2: the
#: torque while moving is fc+ or -fc- either way, the static band [-fs-, fs+] either way, and
#: the jump at a reversal is fc+ + fc- either way.  A baseline that carries an unknown
#: constant load (the rigid default) therefore cannot tell the two apart, whatever the
#: motion; the direction-dependent viscous part of an asymmetry is not a constant and stays
#: identifiable.
COULOMB_ASYMMETRY_WHY = ("symmetric Coulomb friction plus a constant load torque gives the same torque in "
                         "motion and at standstill; identifiable with offset = false in --model (an axis known "
                         "to carry no constant load)")


def not_identifiable_parts(structure: str, offset: bool | None = None) -> dict[str, dict[str, str]]:
    """Parts of an effect that the baseline cannot tell from its own terms, although the
    effect's candidate is ranked for the rest of it: effect -> part -> why.

    Parameters
    ----------
    structure : str
        The baseline's structure, ``"rigid"`` or ``"two_mass"``.
    offset : bool, optional
        The baseline's constant torque offset as in :func:`hdservo.discrepancy.workflow.run`
        (None: the default, the standstill offset of a rigid baseline, none on a two-mass one).

    Returns
    -------
    dict
        ``{"asymmetric_friction": {"coulomb": why}}`` when the baseline has an offset (a
        rigid baseline unless ``offset`` is False, a two-mass one only with ``offset`` True),
        else empty.
    """
    has_offset = offset is not False if structure == "rigid" else offset is True
    return {"asymmetric_friction": {"coulomb": COULOMB_ASYMMETRY_WHY}} if has_offset else {}


def identifiability(angles: str) -> dict[str, str]:
    """Per effect of :data:`EFFECT_NAMES`: ``"identifiable"`` or :data:`NOT_IDENTIFIABLE`.

    Parameters
    ----------
    angles : str
        The log's signal set, one of :data:`SIGNAL_SETS`.
    """
    ok = IDENTIFIABLE[angles]
    return {e: "identifiable" if e in ok else NOT_IDENTIFIABLE for e in EFFECT_NAMES}
