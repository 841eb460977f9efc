"""Figure-of-merit calculators of the test procedures (pure functions, SI units).

Every function takes plain numpy arrays and returns numbers or dicts, so that
the definitions can be tested on synthetic signals with known answers
(tests/python/test_procedures_metrics.py).  Definitions follow
``research/harmonic-drive.md`` sections 2.2 and 9 and ISO 230-2.

Angles are in rad unless a name says ``_arcsec``; torques in N.m; times in s.
"""
from __future__ import annotations

import math
from typing import Any, Optional, Sequence

import numpy as np

from ..units import ARCMIN, ARCSEC, DEG  # noqa: F401  (re-exported for the procedures)


# ---- gear: stiffness curve, hysteresis loss, lost motion ------------------------------

def three_slope_fit(torque_Nm: np.ndarray, twist_rad: np.ndarray,
                    t_max_Nm: float | None = None) -> dict[str, float]:
    """Fit the catalogue three-slope curve to a (midline) torque-twist curve.

    The model is the HD catalogue one (harmonic-drive.md 2.1), odd in T:
    ``phi(T) = T/K1`` on ``|T| <= T1``, slope ``1/K2`` on ``T1..T2`` and
    ``1/K3`` above ``T2``.  The breakpoints are searched on a grid, the three
    compliances by linear least squares for each candidate.

    Parameters
    ----------
    torque_Nm : ndarray
        Transmitted torque, N.m (both signs).
    twist_rad : ndarray
        Twist at those torques, rad, zero at zero torque.
    t_max_Nm : float, optional
        Largest |T| used (default: all).

    Returns
    -------
    dict
        ``k1_Nm_per_rad``, ``k2_Nm_per_rad``, ``k3_Nm_per_rad``, ``t1_Nm``,
        ``t2_Nm``, ``rms_residual_rad``.
    """
    t = np.asarray(torque_Nm, float)
    p = np.asarray(twist_rad, float)
    if t_max_Nm is not None:
        keep = np.abs(t) <= t_max_Nm
        t, p = t[keep], p[keep]
    if t.size < 8:
        raise ValueError("three_slope_fit needs at least 8 points")
    a = np.abs(t)
    s = np.sign(t)
    top = float(a.max())
    best: dict[str, float] | None = None
    grid = np.linspace(0.05 * top, 0.95 * top, 46)
    for i, t1 in enumerate(grid):
        for t2 in grid[i + 1:]:
            x = np.stack([s * np.minimum(a, t1), s * np.clip(a - t1, 0.0, t2 - t1), s * np.clip(a - t2, 0.0, None)], 1)
            c, *_ = np.linalg.lstsq(x, p, rcond=None)
            if np.any(c <= 0):
                continue
            r = float(np.sqrt(np.mean((x @ c - p) ** 2)))
            if best is None or r < best["rms_residual_rad"]:
                best = {"k1_Nm_per_rad": 1.0 / c[0], "k2_Nm_per_rad": 1.0 / c[1], "k3_Nm_per_rad": 1.0 / c[2],
                        "t1_Nm": float(t1), "t2_Nm": float(t2), "rms_residual_rad": r}
    if best is None:
        raise ValueError("three_slope_fit: no positive-stiffness fit")
    return best


def linear_stiffness(torque_Nm: np.ndarray, twist_rad: np.ndarray, t_lo_Nm: float, t_hi_Nm: float) -> float:
    """Secant stiffness of a midline between |T| = t_lo and t_hi (both signs), N.m/rad."""
    t = np.asarray(torque_Nm, float)
    p = np.asarray(twist_rad, float)
    keep = (np.abs(t) >= t_lo_Nm) & (np.abs(t) <= t_hi_Nm)
    if keep.sum() < 4:
        raise ValueError("linear_stiffness: too few points in the torque band")
    x = np.stack([t[keep], np.ones(keep.sum())], 1)
    c, *_ = np.linalg.lstsq(x, p[keep], rcond=None)
    return float(1.0 / c[0])


def branches(torque_Nm: np.ndarray, twist_rad: Optional[np.ndarray] = None) -> tuple[list[np.ndarray], list[int]]:
    """Split a cyclic torque record into monotone branches; returns index arrays and their direction (+1/-1).

    Pass the commanded (clean) torque: noise on a measured torque would split it into tiny branches.
    """
    t = np.asarray(torque_Nm, float)
    d = np.sign(np.diff(t))
    idx: list[np.ndarray] = []
    dirs: list[int] = []
    start = 0
    cur = 0
    for k, v in enumerate(d):
        if v == 0:
            continue
        if cur == 0:
            cur = int(v)
        elif v != cur:
            idx.append(np.arange(start, k + 1))
            dirs.append(cur)
            start, cur = k, int(v)
    idx.append(np.arange(start, t.size))
    dirs.append(cur)
    return idx, dirs


def twist_at_torque(torque_Nm: np.ndarray, twist_rad: np.ndarray, level_Nm: float) -> float:
    """Twist where a monotone branch passes ``level_Nm`` (linear interpolation; NaN if it does not)."""
    t = np.asarray(torque_Nm, float)
    p = np.asarray(twist_rad, float)
    if t.size < 2:
        return float("nan")
    o = np.argsort(t, kind="stable")
    ts, ps = t[o], p[o]
    if not ts[0] <= level_Nm <= ts[-1]:
        return float("nan")
    return float(np.interp(level_Nm, ts, ps))


def hysteresis_loss(torque_Nm: np.ndarray, twist_rad: np.ndarray, level_Nm: float = 0.0,
                    ref_Nm: Optional[np.ndarray] = None) -> dict[str, Any]:
    """Hysteresis loss: twist difference of the unloading branches at zero torque (points B-B').

    The record is a cycle 0 -> +T -> 0 -> -T -> 0 (repeated).  The
    decreasing branches from a +T tip and increasing branches from a -T tip
    (within 10 % of the record's extremes; the branch from the start is not
    one) are each interpolated at ``level_Nm``; the loss is the mean
    difference (decreasing minus increasing) over the pairs after the first,
    rad.

    ``ref_Nm`` (optional): the commanded torque, used to find the branches.

    Returns
    -------
    dict
        ``loss_rad``, ``loss_arcmin``, ``per_cycle_rad`` (list).
    """
    ref = np.asarray(torque_Nm if ref_Nm is None else ref_Nm, float)
    idx, dirs = branches(ref)
    t = np.asarray(torque_Nm, float)
    p = np.asarray(twist_rad, float)
    # unloading branches only: from a +T tip down, from a -T tip up (the branch from the start,
    # e.g. the virgin 0 -> +T, has its zero crossing wherever the record began)
    hi, lo = 0.9 * ref.max(), 0.9 * ref.min()
    down = [twist_at_torque(t[i], p[i], level_Nm) for i, d in zip(idx, dirs)
            if d < 0 and ref[i[0]] >= hi and t[i].max() > level_Nm]
    up = [twist_at_torque(t[i], p[i], level_Nm) for i, d in zip(idx, dirs)
          if d > 0 and ref[i[0]] <= lo and t[i].min() < level_Nm]
    down = [v for v in down if math.isfinite(v)]
    up = [v for v in up if math.isfinite(v)]
    n = min(len(down), len(up))
    if n == 0:
        raise ValueError("hysteresis_loss: the record has no full cycle through zero torque")
    per = [down[k] - up[k] for k in range(n)]
    loss = float(np.mean(per[1:] if n > 1 else per))   # first cycle starts from the virgin state
    return {"loss_rad": loss, "loss_arcmin": loss / ARCMIN, "per_cycle_rad": per}


def lost_motion(torque_Nm: np.ndarray, twist_rad: np.ndarray, level_Nm: float,
                ref_Nm: Optional[np.ndarray] = None) -> dict[str, Any]:
    """Lost motion at +-level: twist between the loop tips at +level and -level.

    The tips are the samples where the commanded torque ``ref_Nm`` (default:
    ``torque_Nm``) is within 2 % of +-level; the mean twists of the LAST
    tip of each sign (the established loop, not the virgin one) are
    subtracted (HD definition at +-4 % of the rated torque, harmonic-drive.md 2.2).
    """
    t = np.asarray(torque_Nm if ref_Nm is None else ref_Nm, float)
    p = np.asarray(twist_rad, float)

    def last_group(mask: np.ndarray) -> np.ndarray:
        ix = np.flatnonzero(mask)
        if ix.size == 0:
            raise ValueError("lost_motion: the record does not reach +-level")
        brk = np.flatnonzero(np.diff(ix) > 1)
        return ix[brk[-1] + 1:] if brk.size else ix

    hi = last_group(t >= 0.98 * level_Nm)
    lo = last_group(t <= -0.98 * level_Nm)
    lm = float(p[hi].mean() - p[lo].mean())
    return {"lost_motion_rad": lm, "lost_motion_arcmin": lm / ARCMIN}


# ---- transmission accuracy -------------------------------------------------------------

def transmission_error(motor_rad: np.ndarray, load_rad: np.ndarray, ratio: float) -> np.ndarray:
    """TE = theta_L - theta_M / N with the mean removed (rad)."""
    e = np.asarray(load_rad, float) - np.asarray(motor_rad, float) / ratio
    return e - e.mean()


def transmission_accuracy(motor_rad: np.ndarray, load_rad: np.ndarray, ratio: float,
                          orders_wg: Sequence[int] = (1, 2, 4), orders_out: Sequence[int] = (1,)) -> dict[str, Any]:
    """Catalogue transmission accuracy over one output revolution, and the TE spectrum.

    Transmission accuracy = max positive + max negative deviation of the output
    from the theoretical angle theta_M / N, over one full output revolution in
    one direction (harmonic-drive.md 2.2).  A straight line (scale / drift) is
    NOT removed: the catalogue compares with the ideal ratio.  The harmonic
    lines are fitted by least squares in the wave-generator angle (orders per
    motor revolution) and in the output angle (orders per output revolution).

    Returns
    -------
    dict
        ``accuracy_rad``, ``accuracy_arcmin``, ``lines``: list of
        ``{"kind": "wg"|"out", "order", "amplitude_rad", "phase_rad"}``
        (model ``a sin(n theta + p)``), ``residual_rms_rad``.
    """
    m = np.asarray(motor_rad, float)
    l = np.asarray(load_rad, float)
    e = transmission_error(m, l, ratio)
    cols = [np.ones_like(e)]
    names: list[tuple[str, int]] = []
    for n in orders_wg:
        cols += [np.sin(n * m), np.cos(n * m)]
        names.append(("wg", int(n)))
    for n in orders_out:
        cols += [np.sin(n * l), np.cos(n * l)]
        names.append(("out", int(n)))
    x = np.stack(cols, 1)
    c, *_ = np.linalg.lstsq(x, e, rcond=None)
    lines = []
    for k, (kind, n) in enumerate(names):
        s, co = c[1 + 2 * k], c[2 + 2 * k]
        lines.append({"kind": kind, "order": n, "amplitude_rad": float(math.hypot(s, co)),
                      "amplitude_arcsec": float(math.hypot(s, co) / ARCSEC), "phase_rad": float(math.atan2(co, s))})
    acc = float(e.max() - e.min())
    return {"accuracy_rad": acc, "accuracy_arcmin": acc / ARCMIN, "lines": lines,
            "residual_rms_rad": float(np.sqrt(np.mean((e - x @ c) ** 2)))}


# ---- minimum smooth rate: fixed-angle timing -----------------------------------------------

def fixed_angle_rates(t_s: np.ndarray, angle_rad: np.ndarray, window_rad: float) -> np.ndarray:
    """Rates from fixed-angle timing: omega_i = window / (t_{i+1} - t_i) (rad/s).

    t_i is the first time the angle (relative to its first sample, in the
    direction of motion) reaches ``i * window`` (linear interpolation between
    samples).  A stop or reversal shows as a long interval (low rate).
    """
    t = np.asarray(t_s, float)
    a = np.asarray(angle_rad, float)
    a = a - a[0]
    sgn = 1.0 if a[-1] >= 0 else -1.0
    a = sgn * a
    run = np.maximum.accumulate(a)          # first crossings only
    levels = np.arange(0.0, run[-1], window_rad)
    if levels.size < 3:
        return np.zeros(0)
    k = np.searchsorted(run, levels, side="left")
    k = np.clip(k, 1, a.size - 1)
    a0, a1 = run[k - 1], run[k]
    t0, t1 = t[k - 1], t[k]
    frac = np.where(a1 > a0, (levels - a0) / np.where(a1 > a0, a1 - a0, 1.0), 0.0)
    tc = t0 + np.clip(frac, 0.0, 1.0) * (t1 - t0)
    tc[0] = t[0] if levels[0] == 0.0 else tc[0]
    return sgn * window_rad / np.diff(tc)


def rate_stability(t_s: np.ndarray, angle_rad: np.ndarray, rate_cmd_rad_s: float, window_rad: float) -> dict[str, Any]:
    """Rate accuracy and stability by fixed-angle timing (harmonic-drive.md 9.3).

    Returns
    -------
    dict
        ``windows`` (count), ``mean_rad_s``, ``accuracy`` = |mean - cmd| / cmd,
        ``stability`` = std(omega_i) / mean, ``min_rad_s``, ``max_rad_s``,
        ``monotone`` (no stop or reversal: every window's rate has the sign of
        the command and the angle never goes back by more than a window).
    """
    w = fixed_angle_rates(t_s, angle_rad, window_rad)
    if w.size < 2:
        return {"windows": int(w.size), "mean_rad_s": float("nan"), "accuracy": float("inf"),
                "stability": float("inf"), "min_rad_s": float("nan"), "max_rad_s": float("nan"), "monotone": False}
    mean = float(np.mean(w))
    a = np.asarray(angle_rad, float) * (1.0 if rate_cmd_rad_s >= 0 else -1.0)
    back = float(np.max(np.maximum.accumulate(a) - a))
    return {"windows": int(w.size), "mean_rad_s": mean,
            "accuracy": abs(mean - rate_cmd_rad_s) / abs(rate_cmd_rad_s),
            "stability": float(np.std(w, ddof=1) / abs(mean)) if mean != 0 else float("inf"),
            "min_rad_s": float(w.min()), "max_rad_s": float(w.max()),
            "monotone": bool(np.all(np.sign(w) == np.sign(rate_cmd_rad_s)) and back < window_rad),
            "max_backlash_rad": back}


def min_smooth_rate(ladder: Sequence[dict[str, Any]], bound: float,
                    accuracy_bound: Optional[float] = None) -> float | None:
    """Lowest rate of a decade ladder whose run is smooth, with every faster rung smooth too.

    ``ladder``: dicts with ``rate_deg_s``, ``stability``, ``monotone`` (and ``accuracy``).
    A rung is smooth when monotone and its rate fluctuation (stability) <= bound; with
    ``accuracy_bound`` the mean rate must also be within it of the command.
    Returns deg/s, or None when even the fastest rung fails.
    """
    best = None
    for r in sorted(ladder, key=lambda d: -d["rate_deg_s"]):
        ok = bool(r["monotone"]) and r["stability"] <= bound and (accuracy_bound is None or
                                                                  r["accuracy"] <= accuracy_bound)
        if not ok:
            break
        best = float(r["rate_deg_s"])
    return best


# ---- stabilisation ---------------------------------------------------------------------

def inertial_angle_from_gyro(t_s: np.ndarray, rate_rad_s: np.ndarray) -> np.ndarray:
    """Integrate a gyro rate (trapezoid) and remove a straight line (bias and start angle), rad."""
    t = np.asarray(t_s, float)
    w = np.asarray(rate_rad_s, float)
    a = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    c = np.polyfit(t - t[0], a, 1)
    return a - np.polyval(c, t - t[0])


def pointing_error(error_rad: np.ndarray) -> dict[str, float]:
    """RMS and peak of a pointing error (mean removed), arcsec."""
    e = np.asarray(error_rad, float)
    e = e - e.mean()
    return {"rms_arcsec": float(np.sqrt(np.mean(e ** 2)) / ARCSEC), "peak_arcsec": float(np.max(np.abs(e)) / ARCSEC)}


# ---- positioning (ISO 230-2) -------------------------------------------------------------

def iso230_2(targets: np.ndarray, up: np.ndarray, down: np.ndarray) -> dict[str, Any]:
    """ISO 230-2 bidirectional positioning figures.

    Parameters
    ----------
    targets : ndarray, shape (m,)
        Target positions P_i.
    up, down : ndarray, shape (n, m)
        Measured positions of run j at target i approached in the positive
        (up) and negative (down) direction.  Any angle unit: the figures come
        out in the same unit.

    Returns
    -------
    dict
        ``A`` accuracy, ``R`` bidirectional repeatability, ``R_up``, ``R_down``
        unidirectional repeatabilities (4 s), ``B`` reversal value (max |B_i|),
        ``B_mean``, ``E`` bidirectional systematic positional deviation,
        ``E_up``, ``E_down``, ``M`` mean bidirectional positional deviation
        range, and per-target arrays ``mean_up``, ``mean_down``, ``s_up``,
        ``s_down``, ``B_i``, ``R_i``.
    """
    p = np.asarray(targets, float)
    xu = np.asarray(up, float) - p[None, :]
    xd = np.asarray(down, float) - p[None, :]
    if xu.shape != xd.shape or xu.ndim != 2 or xu.shape[0] < 2:
        raise ValueError("iso230_2: up and down must be (runs >= 2, targets) arrays of the same shape")
    mu, md = xu.mean(0), xd.mean(0)
    su, sd = xu.std(0, ddof=1), xd.std(0, ddof=1)
    b = mu - md
    r_up, r_dn = 4 * su, 4 * sd
    r_i = np.maximum(np.maximum(2 * su + 2 * sd + np.abs(b), r_up), r_dn)
    a = max(np.max(mu + 2 * su), np.max(md + 2 * sd)) - min(np.min(mu - 2 * su), np.min(md - 2 * sd))
    mean_bi = 0.5 * (mu + md)
    return {
        "A": float(a), "R": float(r_i.max()), "R_up": float(r_up.max()), "R_down": float(r_dn.max()),
        "B": float(np.max(np.abs(b))), "B_mean": float(np.mean(b)),
        "E": float(max(mu.max(), md.max()) - min(mu.min(), md.min())),
        "E_up": float(mu.max() - mu.min()), "E_down": float(md.max() - md.min()),
        "M": float(mean_bi.max() - mean_bi.min()),
        "mean_up": mu.tolist(), "mean_down": md.tolist(), "s_up": su.tolist(), "s_down": sd.tolist(),
        "B_i": b.tolist(), "R_i": r_i.tolist(),
    }



#: Parts of a stop's output deviation (:func:`stop_error_parts`): where the loop put the motor (motor angle
#: / N - target), the transmission error and minus the gear's twist; they sum to the output's deviation.
STOP_PARTS: tuple[str, ...] = ("motor_dev_arcsec", "te_arcsec", "minus_twist_arcsec")


def _part_stats(up: np.ndarray, down: np.ndarray) -> dict[str, float]:
    """Systematic spread, direction difference, run-to-run scatter and first-run offset of one part."""
    mu, md = np.nanmean(up, 0), np.nanmean(down, 0)
    out = {"mean": float(np.nanmean(np.concatenate([up.ravel(), down.ravel()]))),
           "systematic": float(max(mu.max(), md.max()) - min(mu.min(), md.min())),
           "direction": float(np.max(np.abs(mu - md))),
           "scatter": float(max(np.nanmax(np.nanstd(up, 0, ddof=1)), np.nanmax(np.nanstd(down, 0, ddof=1))))
           if up.shape[0] >= 2 else float("nan"),
           "first_run": float("nan")}
    if up.shape[0] >= 2:
        rest_u, rest_d = np.nanmean(up[1:], 0), np.nanmean(down[1:], 0)
        out["first_run"] = float(max(np.max(np.abs(up[0] - rest_u)), np.max(np.abs(down[0] - rest_d))))
    return out


def stop_error_parts(stops: "dict[str, dict[str, Any]]") -> dict[str, Any]:
    """What the output's deviation at the positioning stops is made of (virtual rig).

    Each stop's output deviation is the sum of :data:`STOP_PARTS`: the motor angle / N's deviation
    from the target (in full closed the loop's reaction to the output encoder, in semi-closed the
    drive's predicted offset plus the loop error), the transmission error and minus the twist of
    the gear at the torque it holds (plant: theta_L = theta_M / N + TE - twist).  Per part and for
    the output itself the ISO 230-2 building blocks: the spread of the per-target means over both
    directions (``systematic``, E), the largest difference between the two approach directions
    (``direction``, B), the largest run-to-run standard deviation at one target and direction
    (``scatter``, s) and the largest offset of the first run from the later ones (``first_run``).

    Parameters
    ----------
    stops : dict
        ``{"up": {key: runs x targets}, "down": {...}}`` with the keys of
        :data:`hdservo.procedures.closedloop.RIG_AT_STOPS` (arcsec; gear torque N.m).

    Returns
    -------
    dict
        ``parts``: part -> statistics (arcsec); ``output``: the output deviation's statistics plus
        ``A`` (ISO 230-2 accuracy over all runs) and ``A_after_first_run`` (without the first run,
        None with fewer than 3 runs); ``gear_torque_Nm``: the held torque's statistics;
        ``sum_check_arcsec``: the largest |output - sum of the parts| (0 up to the rig's rounding).
    """
    arr = {d: {k: np.asarray(v, float) for k, v in stops[d].items()} for d in ("up", "down")}
    parts = {d: {"motor_dev_arcsec": arr[d]["motor_dev_arcsec"], "te_arcsec": arr[d]["te_arcsec"],
                 "minus_twist_arcsec": -arr[d]["twist_arcsec"]} for d in arr}
    out_u, out_d = arr["up"]["out_dev_arcsec"], arr["down"]["out_dev_arcsec"]
    check = max(float(np.nanmax(np.abs(arr[d]["out_dev_arcsec"] - sum(parts[d].values())))) for d in arr)
    res_out = _part_stats(out_u, out_d)
    zeros = np.zeros(out_u.shape[1])
    res_out["A"] = iso230_2(zeros, out_u, out_d)["A"] if out_u.shape[0] >= 2 else None
    res_out["A_after_first_run"] = iso230_2(zeros, out_u[1:], out_d[1:])["A"] if out_u.shape[0] >= 3 else None
    return {"parts": {k: _part_stats(parts["up"][k], parts["down"][k]) for k in STOP_PARTS},
            "output": res_out,
            "gear_torque_Nm": _part_stats(arr["up"]["gear_torque_Nm"], arr["down"]["gear_torque_Nm"]),
            "sum_check_arcsec": check}

# ---- frequency responses -----------------------------------------------------------------

def welch_frf(u: np.ndarray, y: np.ndarray, fs_Hz: float, nperseg: int) -> dict[str, np.ndarray]:
    """H1 estimate S_uy / S_uu and coherence with Hann windows, 50 % overlap.

    ``u``, ``y`` may be lists of equally sampled records (blocks); segments are
    taken within each block and averaged over all.
    """
    us = u if isinstance(u, (list, tuple)) else [u]
    ys = y if isinstance(y, (list, tuple)) else [y]
    w = np.hanning(nperseg)
    suu = syy = 0.0
    suy: Any = 0.0
    n = 0
    for ub, yb in zip(us, ys):
        ub = np.asarray(ub, float)
        yb = np.asarray(yb, float)
        for s in range(0, ub.size - nperseg + 1, nperseg // 2):
            a = ub[s:s + nperseg]
            b = yb[s:s + nperseg]
            a = np.fft.rfft((a - a.mean()) * w)
            b = np.fft.rfft((b - b.mean()) * w)
            suu = suu + np.abs(a) ** 2
            syy = syy + np.abs(b) ** 2
            suy = suy + np.conj(a) * b
            n += 1
    if n == 0:
        raise ValueError("welch_frf: records shorter than one segment")
    f = np.fft.rfftfreq(nperseg, 1.0 / fs_Hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = suy / suu
        coh = np.abs(suy) ** 2 / (suu * syy)
    return {"f_Hz": f, "H": h, "coherence": np.nan_to_num(coh), "segments": np.array(n)}


def resonances(f_Hz: np.ndarray, h_accel: np.ndarray, f_lo: float, f_hi: float) -> dict[str, float]:
    """Anti-resonance (minimum) and resonance (maximum after it) of |H| in [f_lo, f_hi], Hz."""
    f = np.asarray(f_Hz, float)
    m = np.abs(np.asarray(h_accel))
    band = (f >= f_lo) & (f <= f_hi)
    fb, mb = f[band], m[band]
    if fb.size < 3:
        raise ValueError("resonances: band holds fewer than 3 lines")
    k = int(np.argmax(mb))
    out = {"resonance_Hz": float(fb[k])}
    if k > 0:
        j = int(np.argmin(mb[:k]))
        out["anti_resonance_Hz"] = float(fb[j])
    return out


def bandwidth_3db(f_Hz: np.ndarray, h: np.ndarray) -> float | None:
    """First frequency where |H| falls below 1/sqrt(2) of its lowest-frequency value (log interpolation)."""
    f = np.asarray(f_Hz, float)
    m = np.abs(np.asarray(h))
    ref = m[0]
    lim = ref / math.sqrt(2.0)
    for k in range(1, f.size):
        if m[k] < lim:
            x0, x1 = math.log(f[k - 1]), math.log(f[k])
            y0, y1 = m[k - 1], m[k]
            return float(math.exp(x0 + (lim - y0) * (x1 - x0) / (y1 - y0)))
    return None


def schroeder_multisine(n_samples: int, lines: Sequence[int]) -> np.ndarray:
    """Periodic multisine over n_samples with the given DFT lines, Schroeder phases, peak 1."""
    k = np.arange(n_samples)
    x = np.zeros(n_samples)
    nl = len(lines)
    for i, line in enumerate(lines):
        ph = -math.pi * i * (i + 1) / nl
        x += np.cos(2 * math.pi * line * k / n_samples + ph)
    return x / np.max(np.abs(x))


def line_response(r: np.ndarray, y: np.ndarray, lines: Sequence[int]) -> np.ndarray:
    """Complex ratio Y/R at DFT lines of one exact period of a periodic excitation."""
    rf = np.fft.fft(np.asarray(r, float))
    yf = np.fft.fft(np.asarray(y, float))
    ix = np.asarray(lines, int)
    return yf[ix] / rf[ix]


__all__ = ["ARCSEC", "ARCMIN", "DEG", "STOP_PARTS", "stop_error_parts", "three_slope_fit", "linear_stiffness", "branches", "twist_at_torque",
           "hysteresis_loss", "lost_motion", "transmission_error", "transmission_accuracy", "fixed_angle_rates",
           "rate_stability", "min_smooth_rate", "inertial_angle_from_gyro", "pointing_error", "iso230_2",
           "welch_frf", "resonances", "bandwidth_3db", "schroeder_multisine", "line_response"]
