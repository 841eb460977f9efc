"""Baseline axis model, its regression columns and the weighted least-squares fit.

Two structures (docs/discrepancy.md):

* ``two_mass`` -- motor inertia J_m and load inertia J_l joined by a linear spring K
  with damping c (output side), viscous + Coulomb friction on each side.  Written as two
  linear-in-the-parameters equations in the measured motor torque tau (N.m, motor side):

  motor equation (M):  tau = J_m a_m + (K phi + c phi')/N + Fv_m w_m + Fc_m sgn w_m
  rigid-body sum (R):  tau = J_m a_m + J_l a_l/N + Fv_m w_m + Fc_m sgn w_m + (Fv_l w_l + Fc_l sgn w_l)/N

  with phi = theta_m/N - theta_l the measured twist.  R is the sum of the motor and load
  equations; it holds whatever the spring does, M carries the spring.
* ``rigid`` -- one mass on one coordinate: tau = J a + Fv w + Fc sgn w + offset (the
  symmetric inverse model of EMPS).  With two encoders and a rigid baseline the
  coordinate is the motor angle.  By default the offset is the median torque of the
  log's standstill segments (:func:`standstill_offset`), held fixed in the fit: on the
  moving samples a free constant is indistinguishable from a Coulomb level that differs
  between directions (it would take up an asymmetric friction); at standstill friction
  holds no net torque on average, a constant load does.  A log with too little
  standstill gets a free offset.

Both are fitted by ordinary least squares on the parallel-filtered, decimated data
(IDIM-LS), each equation weighted by the inverse of its residual scale, samples at
standstill excluded (friction there is the unknown sticking force).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from .signals import Signals


@dataclass
class Column:
    """One regressor: its series (log rate) in the motor equation M and in the rigid-body equation R.

    ``scale`` converts the fitted coefficient into the physical parameter ``name``.
    """

    name: str
    M: np.ndarray | None
    R: np.ndarray | None
    scale: float = 1.0
    key: str = ""            # cache key of the filtered series (name + hyper-parameters)
    #: The column as a function of the state, for the simulation error
    #: (:mod:`hdservo.discrepancy.simerr`): ``fn(th_m, w_m, th_l, w_l) -> (M, R)`` (None
    #: where the column is absent from an equation; signs are sharp there).  None: the
    #: column is taken along the measured trajectory (memory operators, accelerations).
    fn: Callable[..., tuple[Any, Any]] | None = field(default=None, repr=False)
    #: Friction column of the motor side ("m") or load side ("l"): replaced by the
    #: static (sticking) force when that side stands still in the simulation.
    fric: str = ""
    #: Inertia column ("Jm", "Jl", or "J" for the rigid model): the simulated dynamics.
    role: str = ""
    #: Coefficient estimated outside the fit (the standstill offset), held fixed by
    #: :func:`solve`; None: fitted.
    fixed: float | None = None
    #: Constant taken off the column (per unit of its coefficient), N.m at the motor: a
    #: column centred so that it cannot make up a constant (the offset's); the physical
    #: offset of the uncentred column is ``offset - coefficient * shift`` (:meth:`Fit.params`).
    shift: float = 0.0


#: Width of the smoothed sign relative to the standstill threshold (samples below the
#: threshold are not used, so the sign is effectively sharp where it matters).
SIGN_SMOOTH = 0.1


def smooth_sign(v: np.ndarray, eps: float) -> np.ndarray:
    """tanh(v/eps): a sign function smoothed over +-eps (same unit as v)."""
    return np.tanh(v / max(eps, 1e-300))


@dataclass
class Design:
    """Data shared by every fit of one log.

    Attributes
    ----------
    sig : Signals
    v_eps : float
        Velocity below which the axis counts as standing (output side), rad/s (m/s).
    mask : numpy.ndarray of bool
        Decimated samples used in the fit (moving, away from the ends).
    equations : tuple of str
        ``("M", "R")`` for two-mass, ``("R",)`` for rigid.
    """

    sig: Signals
    v_eps: float
    mask: np.ndarray
    equations: tuple[str, ...]
    _cache: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def dec(self, key: str, x: np.ndarray | None) -> np.ndarray:
        """Parallel-filtered, decimated copy of ``x`` (zeros if None), cached under ``key``."""
        if x is None:
            return np.zeros(self.sig.n_dec())
        if key not in self._cache:
            self._cache[key] = self.sig.dec(x)
        return self._cache[key]

    def stack(self, col: Column) -> np.ndarray:
        """The column's decimated values over the used samples of every equation."""
        parts = [self.dec(f"{col.key or col.name}:{e}", getattr(col, e))[self.mask] for e in self.equations]
        return np.concatenate(parts)

    def lhs(self, tau: np.ndarray, key: str = "tau") -> np.ndarray:
        """The measured torque stacked like :meth:`stack`."""
        d = self.dec(key, tau)[self.mask]
        return np.concatenate([d for _ in self.equations])

    @property
    def n_rows(self) -> int:
        return int(self.mask.sum()) * len(self.equations)


def _noise_scale(v: np.ndarray, sig: Signals) -> float:
    """Robust (1.4826 MAD) scale of the high-frequency part of a velocity, same unit."""
    hf = v - _smooth(v, max(3, int(round(1.0 / (sig.fc_Hz * sig.dt) / 2))))
    return 1.4826 * float(np.median(np.abs(hf - np.median(hf))))


#: Standstill margin: decimated samples dropped on each side of a stop, in units of the
#: angle low-pass' time scale 1/fc (its zero-phase impulse response has decayed to
#: below 1 % after about 2/fc).
STOP_MARGIN_FC = 2.5


def stop_margin(sig: Signals) -> int:
    """Decimated samples dropped on each side of a stop (``STOP_MARGIN_FC / fc``, >= 3)."""
    return max(3, int(np.ceil(STOP_MARGIN_FC / (sig.fc_Hz * sig.dt * max(sig.q, 1)))))


def _erode(ok: np.ndarray, k: int) -> np.ndarray:
    """``ok`` with every sample within ``k`` samples of a False one set False."""
    m = ok.copy()
    for s in range(1, k + 1):
        m[s:] &= ok[:-s]
        m[:-s] &= ok[s:]
    return m


def away_from_reversals(d: Design) -> np.ndarray:
    """Used samples farther than the stop margin from a velocity reversal of either side.

    A fast reversal crosses zero between two decimated samples, so :func:`make_design`
    keeps the samples around it; there the static friction model's unknown force (the
    side sticks for an instant) and its sign jump, spread by the parallel filter, leave a
    spike in the equation error that no candidate of the library models and that is the
    same before and after any effect is added.  Aligned with the used samples
    (``d.mask``); every sample when there are no reversals.
    """
    sig = d.sig
    sides = [sig.dec(sig.v_out)] + ([sig.dec(sig.w_m)] if sig.has_load else [])
    ok = np.ones(len(d.mask), dtype=bool)
    for v in sides:
        flip = np.signbit(v[1:]) != np.signbit(v[:-1])
        ok[1:] &= ~flip
        ok[:-1] &= ~flip
    return _erode(ok, stop_margin(sig))[d.mask]


def make_design(sig: Signals) -> Design:
    """Choose the standstill threshold and the used samples of a log.

    A sample is used when *every* measured coordinate moves (the output side, and the
    motor side if measured separately): a side that sticks carries an unknown static
    friction force.  The threshold per side is the larger of 4x its velocity noise and
    0.2 % of its peak speed; samples closer than ``STOP_MARGIN_FC / fc`` to a stop are
    dropped as well, because the parallel filter spreads the stuck segment's unknown
    force over that span.
    """
    v = sig.v_out
    v_eps = max(4.0 * _noise_scale(v, sig), 2e-3 * float(np.max(np.abs(v))), 1e-12)
    moving = np.abs(sig.dec(v)) > v_eps
    if sig.has_load:
        wm = sig.w_m / sig.ratio
        eps_m = max(4.0 * _noise_scale(wm, sig), 2e-3 * float(np.max(np.abs(wm))), 1e-12)
        moving &= np.abs(sig.dec(wm)) > eps_m
    n = len(moving)
    m = _erode(moving, stop_margin(sig))
    edge = max(10, n // 100)
    m[:edge] = False
    m[-edge:] = False
    eq = ("M", "R") if sig.kind == "two_mass" else ("R",)
    return Design(sig=sig, v_eps=v_eps, mask=m, equations=eq)


def _smooth(x: np.ndarray, w: int) -> np.ndarray:
    k = np.ones(w) / w
    return np.convolve(x, k, mode="same")


#: Least share of the (decimated, away-from-the-ends) samples at standstill for the rigid
#: baseline's offset to be estimated there (:func:`standstill_offset`): 5 %, a few hundred
#: samples on an 8 s log, enough for a median within the torque noise.
STILL_MIN_SHARE = 0.05


def standstill_offset(d: Design) -> float | None:
    """Median measured torque over the standstill segments of a log, N.m (motor side).

    A sample is at standstill when the output velocity stays below the design's threshold
    for the stop margin on each side (the same rule that drops it from the fit).  None when
    fewer than :data:`STILL_MIN_SHARE` of the samples stand still.
    """
    s = d.sig
    still = _erode(np.abs(s.dec(s.v_out)) <= d.v_eps, stop_margin(s))
    edge = max(10, len(still) // 100)
    still[:edge] = False
    still[-edge:] = False
    if int(still.sum()) < STILL_MIN_SHARE * max(len(still) - 2 * edge, 1):
        return None
    return float(np.median(d.dec("tau", s.tau)[still]))


def baseline_columns(d: Design, offset: bool | None = None) -> list[Column]:
    """Regressors of the baseline model (see the module docstring).

    ``offset``: rigid default (None) the standstill offset held fixed (a free one without
    enough standstill), True a free offset, False none; two-mass: True a free offset.
    """
    s = d.sig
    N = s.ratio
    eps = d.v_eps
    if s.kind == "rigid":
        one = np.ones_like(s.tau)
        cols = [Column("J", None, s.a_m, role="J"),
                Column("Fv", None, s.w_m, fn=lambda tm, wm, tl, wl: (None, wm), fric="m"),
                Column("Fc", None, smooth_sign(s.w_m, SIGN_SMOOTH * eps * N),
                       fn=lambda tm, wm, tl, wl: (None, np.sign(wm)), fric="m")]
        if offset is None or offset:
            c0 = standstill_offset(d) if offset is None else None
            cols.append(Column("offset", None, one, fn=lambda tm, wm, tl, wl: (None, np.ones_like(wm)), fixed=c0))
        return cols
    sm = smooth_sign(s.w_m, SIGN_SMOOTH * eps * N)
    sl = smooth_sign(s.w_l, SIGN_SMOOTH * eps)
    cols = [
        Column("J_m_kgm2", s.a_m, s.a_m, role="Jm"),
        Column("J_l_kgm2", None, s.a_l / N, role="Jl"),
        Column("K_Nm_per_rad", s.phi / N, None, fn=lambda tm, wm, tl, wl: ((tm / N - tl) / N, None)),
        Column("c_Nms_per_rad", s.dphi / N, None, fn=lambda tm, wm, tl, wl: ((wm / N - wl) / N, None)),
        Column("Fv_motor_Nms_per_rad", s.w_m, s.w_m, fn=lambda tm, wm, tl, wl: (wm, wm), fric="m"),
        Column("Fc_motor_Nm", sm, sm, fn=lambda tm, wm, tl, wl: (np.sign(wm), np.sign(wm)), fric="m"),
        Column("Fv_load_Nms_per_rad", None, s.w_l / N, fn=lambda tm, wm, tl, wl: (None, wl / N), fric="l"),
        Column("Fc_load_Nm", None, sl / N, fn=lambda tm, wm, tl, wl: (None, np.sign(wl) / N), fric="l"),
    ]
    if offset:
        cols.append(Column("offset_Nm", np.ones_like(s.tau), np.ones_like(s.tau),
                           fn=lambda tm, wm, tl, wl: (np.ones_like(wm), np.ones_like(wm))))
    return cols


@dataclass
class Fit:
    """A weighted least-squares fit.

    Attributes
    ----------
    theta : numpy.ndarray
        Coefficients, one per column.
    names : list of str
    resid : dict of str to numpy.ndarray
        Unweighted residual (measured - model) per equation over the used decimated
        samples, N.m at the motor.
    rss_w : float
        Weighted residual sum of squares.
    n_params : int
    """

    theta: np.ndarray
    names: list[str]
    resid: dict[str, np.ndarray]
    rss_w: float
    n_params: int
    #: :attr:`Column.shift` of the fit's centred columns (name -> N.m per unit coefficient).
    shifts: dict[str, float] = field(default_factory=dict)

    @property
    def rms(self) -> float:
        """RMS of the unweighted residual over all equations, N.m (motor side)."""
        allr = np.concatenate(list(self.resid.values()))
        return float(np.sqrt(np.mean(allr ** 2)))

    def params(self) -> dict[str, float]:
        """Coefficients by name; ``offset`` is the physical one: the fitted (or fixed)
        offset less what the centred columns took off (:attr:`Column.shift`)."""
        p = {n: float(v) for n, v in zip(self.names, self.theta)}
        if self.shifts and "offset" in p:
            p["offset"] -= sum(p[n] * sh for n, sh in self.shifts.items() if n in p)
        return p


def solve(d: Design, cols: Sequence[Column], weights: dict[str, float],
          tau: np.ndarray | None = None, tau_key: str = "tau",
          fixed: Sequence[tuple[Column, float]] = ()) -> Fit:
    """Weighted LS of the stacked equations (weights: 1/scale per equation).

    ``fixed`` columns keep the given coefficient (estimated elsewhere, e.g. on the
    simulation error); their contribution is subtracted from the measured torque and
    they are appended to the fit's coefficients (and counted in ``n_params``).
    """
    fixed = list(fixed) + [(c, c.fixed) for c in cols if c.fixed is not None]
    cols = [c for c in cols if c.name not in {f.name for f, _ in fixed}]
    X = np.column_stack([d.stack(c) for c in cols])
    y = d.lhs(d.sig.tau if tau is None else tau, tau_key)
    for c, a in fixed:
        y = y - a * d.stack(c)
    n = int(d.mask.sum())
    w = np.concatenate([np.full(n, weights.get(e, 1.0)) for e in d.equations])
    Xw = X * w[:, None]
    yw = y * w
    sc = np.sqrt(np.sum(Xw ** 2, axis=0))
    sc[sc == 0] = 1.0
    Xs = Xw / sc
    # normal equations of the unit-norm columns (a few columns, thousands of rows: ~10x
    # cheaper than a QR); an ill-conditioned Gram matrix falls back to SVD least squares
    G = Xs.T @ Xs
    try:
        if np.linalg.cond(G) > 1e10:
            raise np.linalg.LinAlgError("ill-conditioned")
        theta = np.linalg.solve(G, Xs.T @ yw)
        if not np.all(np.isfinite(theta)):
            raise np.linalg.LinAlgError("singular")
    except np.linalg.LinAlgError:
        theta, *_ = np.linalg.lstsq(Xs, yw, rcond=None)
    theta = theta / sc
    r = y - X @ theta
    resid = {e: r[i * n:(i + 1) * n] for i, e in enumerate(d.equations)}
    rss_w = float(np.sum((r * w) ** 2))
    theta = np.concatenate([theta, [float(a) for _, a in fixed]])
    names = [c.name for c in cols] + [c.name for c, _ in fixed]
    shifts = {c.name: c.shift for c in list(cols) + [f for f, _ in fixed] if c.shift}
    return Fit(theta=theta, names=names, resid=resid, rss_w=rss_w, n_params=len(names), shifts=shifts)


def equation_weights(fit: Fit) -> dict[str, float]:
    """Inverse robust scale (1.4826 MAD) of each equation's residual."""
    out = {}
    for e, r in fit.resid.items():
        s = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        out[e] = 1.0 / max(s, 1e-30)
    return out


def constant_share(fit: Fit, weights: dict[str, float] | None = None) -> float:
    """Share of a fit's weighted residual sum of squares that is the residual's mean.

    Per equation the sum of squares splits into n mean^2 (the constant) and the sum of
    squares about the mean; the shares are pooled over the equations with ``weights``
    (1/scale per equation, 1 where absent).  A residual that is mostly a constant (a
    rigid baseline whose offset, held at the standstill torque, differs from the mean
    torque while moving) leaves no room for a candidate that cannot make up a constant
    (a centred unbalance): its explained fraction is taken against that constant.

    Returns
    -------
    float
        In [0, 1]; 0 for a zero residual.
    """
    w = weights or {}
    const = total = 0.0
    for e, r in fit.resid.items():
        rw = np.asarray(r, dtype=float) * w.get(e, 1.0)
        if rw.size == 0:
            continue
        const += rw.size * float(np.mean(rw)) ** 2
        total += float(np.sum(rw ** 2))
    return const / total if total > 0 else 0.0


def residual_mean(fit: Fit) -> float:
    """Mean of the unweighted residual over every equation, N.m (motor side)."""
    allr = np.concatenate(list(fit.resid.values()))
    return float(np.mean(allr)) if allr.size else 0.0


def physical_params(fit: Fit, sig: Signals) -> dict[str, float]:
    """Baseline parameters in SI units (two-mass: output-side K, c, load friction; motor-side J_m, motor friction)."""
    return fit.params()
