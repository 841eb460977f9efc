"""The candidate library: for each missing effect its signature, parametric form and fitter.

Every candidate contributes extra regression columns to the baseline equations (or,
for the current-loop lag, a filter on the measured torque) and has at most one
nonlinear hyper-parameter searched on a grid (Stribeck velocity, stop thresholds,
backlash half-gap, cogging order, lag time constant); the linear coefficients are
re-fitted jointly with the baseline by :func:`hdservo.discrepancy.regression.solve`.

Signatures (research/harmonic-drive.md 10.5) are what the columns encode and what the
plots show: the coordinate in :attr:`Effect.coordinate` reveals the effect.

| name | equation | columns (per unit of the coefficient) | hyper |
|---|---|---|---|
| stribeck_friction | M,R / R | exp(-(v/vs)^2) sgn v, motor and load side | vs |
| asymmetric_friction | M,R / R | 1 and abs(v), per side (direction-dependent Coulomb and viscous) | - |
| transmission_error | M | cos/sin(k theta_m)/N, k = 1..4 per wave-generator revolution (coef = K*e_k) | - |
| cogging_torque | M,R | cos/sin(p theta_m), cos/sin(2p theta_m) | order p >= 5 |
| nonlinear_stiffness | M | phi abs(phi)/N, phi^3/N, or a knee sat_b(phi)/N with K_in/K >= 0.25 | form, b |
| hysteresis | M | stop operators S_D[phi]/N at 12 thresholds, 2-90 % of the twist span (Maxwell-slip) | - |
| backlash | M | sat_b(phi)/N with K_in/K < 0.25 (soft/lost-motion zone); reports the lost-motion test | b |
| gravity_unbalance | R | cos(theta_l)/N, sin(theta_l)/N | - |
| unmodelled_compliance | R (rigid baseline) | (a_l - a_m/N)/N, coefficient J_l | - |
| current_loop_lag | lhs | tau -> first-order lag of tau | T |
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Iterator

import numpy as np
import scipy.signal as sps

from .regression import Column, Design, Fit, smooth_sign
from .residuals import lost_motion


@dataclass
class Variant:
    """One fully specified form of a candidate (hyper-parameters fixed)."""

    hyper: dict[str, Any]
    columns: list[Column]
    tau: np.ndarray | None = None          # replacement of the measured torque (lag)
    tau_key: str = "tau"
    n_hyper: int = 0                       # nonlinear parameters searched (penalised too)
    #: Coefficients fitted on the simulation error (column name -> value), kept fixed
    #: in the least-squares fits; None: all columns fitted by least squares.
    fixed: dict[str, float] | None = None
    #: Levels (in units of the side's fitted Coulomb friction) tried for each column by
    #: the output-error fitter; None: no output-error fit.
    oe_levels: tuple[float, ...] | None = None
    #: Set by the output-error fitter: drop of the simulation error's SSE it achieved, as
    #: a fraction of that SSE (ranks the variants instead of the equation-error evidence).
    oe_gain: float | None = None


class Effect:
    """Base class of a candidate effect."""

    name: str = ""
    coordinate: str = ""                   # what reveals it (plots)
    signature: str = ""

    def applicable(self, d: Design) -> bool:
        return True

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        raise NotImplementedError

    def valid(self, fit: Fit, v: Variant) -> bool:
        return True

    def own_evidence(self, d: Design, fit: Fit, v: Variant) -> dict[str, float]:
        """Explained fractions of the effect's own signature outside the torque residuals
        (counted by the size rule, :func:`hdservo.discrepancy.workflow.size`); none by
        default."""
        return {}

    def twin(self, d: Design, v: Variant) -> Variant | None:
        """A look-alike of the variant without the effect's defining signature, for an
        effect whose columns also fit something else (None by default): hysteresis without
        its memory.

        :func:`hdservo.discrepancy.workflow.rank` fits the twin as well and reports how much
        better the effect explains the residuals than its twin (``twin_delta_bic``,
        ``sim_twin_delta_bic``); without that margin the effect is not significant
        (:func:`hdservo.discrepancy.workflow.beats_twin`)."""
        return None

    def region_bands(self, d: Design, v: Variant) -> dict[str, float] | None:
        """Where the effect can act, from the data and the variant (never from the truth).

        Returns the speed band per side (``"m"``: motor or rigid coordinate, in its own
        unit/s; ``"l"``: output rad/s) below which the effect acts, or None when it acts
        over the whole record (periodic, spring, gravity, lag terms).  Used to report the
        gap and to judge the effect size where the effect acts
        (:func:`hdservo.discrepancy.simerr.region_mask`).
        """
        return None

    def refine_hyper(self, d: Design, v: Variant, frac: float) -> list[Variant]:
        """Variants ``frac`` of the ranking grid's step either side of ``v``, tried when the
        effect is added (:func:`hdservo.discrepancy.workflow.refit_named`); none by default."""
        return []

    def rebuild(self, d: Design, v: Variant) -> Variant:
        """``v`` built again from ``d``'s signals: the same hyper-parameters and fixed
        coefficients, columns (and torque) from ``d``.

        Used for the noise images (:func:`hdservo.discrepancy.workflow.noise_images`: the
        model's columns on the signals plus injected sensor noise).  Default: the variant
        of :meth:`variants` with equal hyper-parameters (effects whose grid does not
        depend on the data); effects with data-dependent grids build it directly.
        """
        for w in self.variants(d, np.zeros(0)):
            if w.hyper == v.hyper:
                return self._keep(w, v)
        raise ValueError(f"{self.name}: no variant with {v.hyper} on these signals")

    @staticmethod
    def _keep(w: Variant, v: Variant) -> Variant:
        """``w`` with ``v``'s fitted-elsewhere coefficients and output-error figures."""
        return replace(w, fixed=v.fixed, oe_levels=v.oe_levels, oe_gain=v.oe_gain)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        out: dict[str, Any] = {k: (float(x) if isinstance(x, (int, float, np.floating)) else x)
                               for k, x in v.hyper.items()}
        for c in v.columns:
            out[c.name] = float(fit.theta[fit.names.index(c.name)]) * c.scale
        return out


def _idx(fit: Fit, name: str) -> float:
    return float(fit.theta[fit.names.index(name)])


class Stribeck(Effect):
    name = "stribeck_friction"
    coordinate = "velocity"
    signature = "excess friction at low speed decaying with abs(v) (both directions alike)"

    #: Stribeck velocities tried when ranking: geometric from max(2 v_eps, 1e-3 vmax) to
    #: 0.5 vmax (vmax: 99th percentile of the output speed).
    n_vs = 8

    def vs_grid(self, d: Design) -> np.ndarray:
        """The Stribeck velocities of :meth:`variants`, output rad/s (m/s)."""
        vmax = float(np.percentile(np.abs(d.sig.v_out), 99))
        return np.geomspace(max(2 * d.v_eps, 1e-3 * vmax), 0.5 * vmax, self.n_vs)

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        for vs in self.vs_grid(d):
            yield self.variant_at(d, float(vs))

    def variant_at(self, d: Design, vs: float) -> Variant:
        """The variant with Stribeck velocity ``vs`` (output rad/s), any value."""
        s = d.sig
        cols = []
        if s.kind == "rigid":
            g = np.exp(-(s.w_m / (vs * s.ratio)) ** 2) * smooth_sign(s.w_m, 0.1 * d.v_eps * s.ratio)
            vm = vs * s.ratio
            cols.append(Column("dFs", None, g, key=f"dFs{vs:.6g}", fric="m",
                               fn=lambda tm, wm, tl, wl, vm=vm: (None, np.exp(-(wm / vm) ** 2) * np.sign(wm))))
        else:
            N = s.ratio
            gm = np.exp(-(s.w_m / (vs * N)) ** 2) * smooth_sign(s.w_m, 0.1 * d.v_eps * N)
            gl = np.exp(-(s.w_l / vs) ** 2) * smooth_sign(s.w_l, 0.1 * d.v_eps)
            def fm(tm, wm, tl, wl, vm=vs * N):
                g = np.exp(-(wm / vm) ** 2) * np.sign(wm)
                return g, g
            cols += [Column("dFs_motor_Nm", gm, gm, key=f"dFsm{vs:.6g}", fn=fm, fric="m"),
                     Column("dFs_load_Nm", None, gl / N, key=f"dFsl{vs:.6g}", fric="l",
                            fn=lambda tm, wm, tl, wl, vl=vs, N=N: (None, np.exp(-(wl / vl) ** 2) * np.sign(wl) / N))]
        return Variant({"vs_out_rad_s": float(vs)}, cols, n_hyper=1, oe_levels=self.levels)

    def refine_hyper(self, d: Design, v: Variant, frac: float) -> list[Variant]:
        """Variants ``frac`` of :meth:`vs_grid`'s step either side of ``v``'s vs."""
        g = self.vs_grid(d)
        r = float(g[1] / g[0]) if len(g) > 1 else 2.0
        vs = float(v.hyper["vs_out_rad_s"])
        return [self.variant_at(d, vs * r ** e) for e in (-frac, frac)]

    def rebuild(self, d: Design, v: Variant) -> Variant:
        return self._keep(self.variant_at(d, float(v.hyper["vs_out_rad_s"])), v)

    #: Stribeck excess Fs - Fc tried per side by the output-error fitter, in units of that
    #: side's Coulomb friction (Fs/Fc from 1.25 to 3).
    levels = (0.25, 0.5, 1.0, 2.0)

    #: The Stribeck term exp(-(v/vs)^2) is below 1e-4 of its peak beyond 3 vs.
    band_vs = 3.0

    def region_bands(self, d: Design, v: Variant) -> dict[str, float] | None:
        """Speeds below ``band_vs`` x the variant's vs on each side (motor side in motor rad/s)."""
        vs = float(v.hyper["vs_out_rad_s"])
        b = {"m": self.band_vs * vs * d.sig.ratio}
        if d.sig.kind != "rigid":
            b["l"] = self.band_vs * vs
        return b

    def valid(self, fit: Fit, v: Variant) -> bool:
        # a Stribeck hump raises friction at low speed: no side's excess may be negative
        return all(_idx(fit, c.name) >= 0 for c in v.columns) and sum(_idx(fit, c.name) for c in v.columns) > 0


class Asymmetric(Effect):
    name = "asymmetric_friction"
    coordinate = "velocity"
    signature = "friction differs between directions: offset and slope of the residual change sign with v"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        one = np.ones_like(s.tau)
        if s.kind == "rigid":
            # On one coordinate a direction-dependent Coulomb level is a constant torque
            # while moving, which the baseline's offset is too: free, it takes it up; held
            # at the standstill median, it is known only within the static friction band
            # (a hold ends wherever the axis stuck), and on the clean one-encoder
            # calibration logs the constant column named a false asymmetry on 12 of 47.
            # Only a baseline without an offset (``offset = false``: no constant load)
            # leaves the constant to this candidate.
            # For the same reason the viscous column is centred on its mean over the fitted
            # samples when there is an offset: its mean is a constant too.
            aw = np.abs(s.w_m)
            m0 = _fitted_mean(d, aw) if _has_offset(d) else 0.0
            fv = Column("dFv_asym", None, aw - m0, fn=lambda tm, wm, tl, wl, m0=m0: (None, np.abs(wm) - m0),
                        fric="m", shift=m0)
            fc = Column("dFc_asym", None, one, fn=lambda tm, wm, tl, wl: (None, np.ones_like(wm)), fric="m")
            yield Variant({"centre_abs_v": m0} if m0 else {}, [fv] if _has_offset(d) else [fv, fc])
            return
        N = s.ratio
        aw = np.abs(s.w_m)
        yield Variant({}, [
            Column("dFc_motor_asym_Nm", one, one, fric="m",
                   fn=lambda tm, wm, tl, wl: (np.ones_like(wm), np.ones_like(wm))),
            Column("dFv_motor_asym_Nms_per_rad", aw, aw, fric="m",
                   fn=lambda tm, wm, tl, wl: (np.abs(wm), np.abs(wm))),
            Column("dFc_load_asym_Nm", None, one / N, fric="l", fn=lambda tm, wm, tl, wl: (None, np.ones_like(wl) / N)),
            Column("dFv_load_asym_Nms_per_rad", None, np.abs(s.w_l) / N, fric="l",
                   fn=lambda tm, wm, tl, wl: (None, np.abs(wl) / N))])

    def rebuild(self, d: Design, v: Variant) -> Variant:
        """The same columns as ``v`` (a design built again knows nothing of the baseline's
        offset), centred as ``v``'s."""
        s = d.sig
        if s.kind == "rigid":
            m0 = float(v.hyper.get("centre_abs_v", 0.0))
            cols = {c.name: c for c in v.columns}
            out = [Column("dFv_asym", None, np.abs(s.w_m) - m0, fric="m", shift=m0,
                          fn=lambda tm, wm, tl, wl, m0=m0: (None, np.abs(wm) - m0))]
            if "dFc_asym" in cols:
                out.append(Column("dFc_asym", None, np.ones_like(s.tau), fric="m",
                                  fn=lambda tm, wm, tl, wl: (None, np.ones_like(wm))))
            return self._keep(Variant(dict(v.hyper), out), v)
        return super().rebuild(d, v)


def _names(d: Design) -> set[str]:
    return set(getattr(d, "_baseline_names", set()))


def _fitted_mean(d: Design, x: np.ndarray) -> float:
    """Mean of a log-rate series over the design's fitted (moving, decimated) samples."""
    q = max(d.sig.q, 1)
    xd = x[::q][: len(d.mask)]
    sel = xd[d.mask[: len(xd)]]
    return float(np.mean(sel)) if sel.size else 0.0


def _has_offset(d: Design) -> bool:
    """The baseline has a constant torque offset, fitted or held fixed (a rigid default)."""
    return "offset" in _names(d) or "offset" in set(getattr(d, "_fixed_names", set()))


class TransmissionError(Effect):
    """Kinematic transmission error e(theta_m, theta_l), rad at the output.

    The measured twist theta_m/N - theta_l misses e, so the spring torque is
    K (phi + e) and its reaction on the motor carries T de/dtheta_m (virtual work,
    docs/plant.md).  Per harmonic e_k = a cos(k theta) + b sin(k theta) of the
    wave-generator (= motor) angle the motor equation gains, with T ~ K phi,

        K a (cos(k th)/N - k phi sin(k th)) + K b (sin(k th)/N + k phi cos(k th)),

    linear in K a, K b.  Output-angle harmonics (FS run-out, 1-2 per output revolution)
    enter as cos/sin(j theta_l)/N (their reaction term is negligible).
    """

    name = "transmission_error"
    coordinate = "motor angle (wave-generator angle)"
    signature = "lines at 1, 2, 4 per wave-generator revolution in the spring (motor) equation only"
    orders = (1, 2, 3, 4)
    out_orders = (1, 2)

    def applicable(self, d: Design) -> bool:
        return d.sig.kind == "two_mass"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        N = s.ratio
        th = s.raw_th_m
        phi = s.phi
        cols = []
        for k in self.orders:
            c, sn = np.cos(k * th), np.sin(k * th)
            cols.append(Column(f"te_wg{k}_cos", c / N - k * phi * sn, None,
                               fn=lambda tm, wm, tl, wl, k=k: (np.cos(k * tm) / N - k * (tm / N - tl) * np.sin(k * tm), None)))
            cols.append(Column(f"te_wg{k}_sin", sn / N + k * phi * c, None,
                               fn=lambda tm, wm, tl, wl, k=k: (np.sin(k * tm) / N + k * (tm / N - tl) * np.cos(k * tm), None)))
        thl = s.raw_th_l if s.raw_th_l is not None else th / N
        for j in self.out_orders:
            cols.append(Column(f"te_out{j}_cos", np.cos(j * thl) / N, None,
                               fn=lambda tm, wm, tl, wl, j=j: (np.cos(j * tl) / N, None)))
            cols.append(Column(f"te_out{j}_sin", np.sin(j * thl) / N, None,
                               fn=lambda tm, wm, tl, wl, j=j: (np.sin(j * tl) / N, None)))
        yield Variant({"orders_per_wg_rev": list(self.orders), "orders_per_output_rev": list(self.out_orders)},
                      cols)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        K = _idx(fit, "K_Nm_per_rad")
        out: dict[str, Any] = {}
        for pre, ks in (("wg", self.orders), ("out", self.out_orders)):
            for k in ks:
                a, b = _idx(fit, f"te_{pre}{k}_cos"), _idx(fit, f"te_{pre}{k}_sin")
                out[f"{pre}{k}_amp_rad"] = float(np.hypot(a, b) / K)
                out[f"{pre}{k}_phase_rad"] = float(np.arctan2(a, b))
        return out


class Cogging(Effect):
    name = "cogging_torque"
    coordinate = "motor angle"
    signature = "high-order lines (LCM of slots and poles) per motor revolution, in both equations"
    min_order = 5
    max_order = 200
    alpha = 0.01          # false-alarm probability of the order search

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        from .residuals import line_statistics
        orders = np.arange(self.min_order, self.max_order + 1)
        # Each order is tested on the samples where its line lies inside the log's band
        # (p |w_m| / 2 pi below the angle cutoff): above it the parallel filter has taken
        # the line out of torque and column alike, and at 1 kHz (cutoff 100 Hz) a line of
        # order 48-72 is in band on only 3-8 % of the moving samples of a closed-loop log,
        # which a spectrum over the whole record dilutes below its noise.
        stat, _, _ = line_statistics(d, resid, s.raw_th_m, d.dec("state:wm", s.w_m)[d.mask], orders)
        ok = np.isfinite(stat)
        if not np.any(ok):
            return
        # Fisher-type periodicity test with a Bonferroni correction over the tested
        # orders: the statistic of an order without a line is about exponential (chi-square
        # with 2 degrees of freedom for a white residual); its mean is estimated robustly
        # over the orders (median / ln 2), which absorbs the residual's colour.  The
        # largest of M such values exceeds mean * ln(M / alpha) with probability alpha.
        # Only orders above that level are candidate cogging orders (else a line found
        # among ~200 would fit whatever happens at a few reversal angles).
        st = stat[ok]
        level = float(np.median(st)) / np.log(2.0) * np.log(len(st) / self.alpha)
        hit = st >= level
        if not np.any(hit):
            return
        cand, cst = orders[ok][hit], st[hit]
        for p in cand[np.argsort(cst)[::-1][:3]]:
            yield self.variant_at(d, int(p))

    def region_bands(self, d: Design, v: Variant) -> dict[str, float] | None:
        """Motor speeds at which the line of order p stays inside the log's band
        (p |w_m| / 2 pi below the angle cutoff); the output side at that speed / N.

        Faster, the parallel filter takes the line out of torque and columns alike, so the
        effect's size is judged where the log can show it."""
        w = 2 * np.pi * d.sig.fc_Hz / float(v.hyper["order_per_motor_rev"])
        b = {"m": w}
        if d.sig.kind != "rigid":
            b["l"] = w / d.sig.ratio
        return b

    def variant_at(self, d: Design, p: int) -> Variant:
        """Lines at ``p`` and ``2 p`` per motor revolution."""
        s = d.sig
        eq_m = s.kind == "two_mass"
        cols = []
        for m in (p, 2 * p):
            c, sn = np.cos(m * s.raw_th_m), np.sin(m * s.raw_th_m)
            cols.append(Column(f"cog{m}_cos_Nm", c if eq_m else None, c,
                               fn=lambda tm, wm, tl, wl, m=m, e=eq_m: (np.cos(m * tm) if e else None, np.cos(m * tm))))
            cols.append(Column(f"cog{m}_sin_Nm", sn if eq_m else None, sn,
                               fn=lambda tm, wm, tl, wl, m=m, e=eq_m: (np.sin(m * tm) if e else None, np.sin(m * tm))))
        # the order was chosen among max_order candidates: penalise the search
        return Variant({"order_per_motor_rev": p}, cols, n_hyper=1)

    def rebuild(self, d: Design, v: Variant) -> Variant:
        return self._keep(self.variant_at(d, int(v.hyper["order_per_motor_rev"])), v)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        p = v.hyper["order_per_motor_rev"]
        out: dict[str, Any] = {"order_per_motor_rev": p}
        for m in (p, 2 * p):
            a, b = _idx(fit, f"cog{m}_cos_Nm"), _idx(fit, f"cog{m}_sin_Nm")
            out[f"h{m}_amp_Nm"] = float(np.hypot(a, b))
            out[f"h{m}_phase_rad"] = float(np.arctan2(a, b))
        return out


def sat(x: np.ndarray, b: float) -> np.ndarray:
    """Saturation at +-b."""
    return np.clip(x, -b, b)


#: Knee / half-gap grid: geometric, 2 % to 80 % of the 99th percentile of the twist,
#: about 25 % apart (a finer grid is not resolvable by the filtered twist).
PHI_GRID_N = 17


def _phi_grid(d: Design) -> np.ndarray:
    a = np.abs(d.sig.phi)
    hi = float(np.percentile(a, 99))
    return np.geomspace(max(hi * 0.02, 1e-9), hi * 0.8, PHI_GRID_N)


def _sat_fn(b: float, N: float):
    """State function of the column sat_b(phi)/N (phi = th_m/N - th_l)."""
    def f(tm: np.ndarray, wm: np.ndarray, tl: np.ndarray, wl: np.ndarray) -> tuple[np.ndarray, None]:
        return np.clip(tm / N - tl, -b, b) / N, None
    return f


class NonlinearStiffness(Effect):
    name = "nonlinear_stiffness"
    coordinate = "torsion"
    signature = "odd, memoryless residual in the twist (stiffening: grows like phi^3 or kinks at T1)"

    def applicable(self, d: Design) -> bool:
        return d.sig.kind == "two_mass"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        N = s.ratio
        phi = s.phi
        def f2(tm, wm, tl, wl):
            p = tm / N - tl
            return p * np.abs(p) / N, None

        def f3(tm, wm, tl, wl):
            return (tm / N - tl) ** 3 / N, None
        yield Variant({"form": "cubic"}, [Column("k2_Nm_per_rad2", phi * np.abs(phi) / N, None, fn=f2),
                                          Column("k3_Nm_per_rad3", phi ** 3 / N, None, fn=f3)], n_hyper=1)
        for b in _phi_grid(d):
            yield self.knee(d, float(b))

    @staticmethod
    def knee(d: Design, b: float) -> Variant:
        """The knee form at twist ``b`` (rad at the output)."""
        N = d.sig.ratio
        return Variant({"form": "knee", "knee_rad": b},
                       [Column("dk_knee_Nm_per_rad", sat(d.sig.phi, b) / N, None, key=f"sat{b:.6g}", fn=_sat_fn(b, N))],
                       n_hyper=2)

    def rebuild(self, d: Design, v: Variant) -> Variant:
        if v.hyper["form"] == "knee":
            return self._keep(self.knee(d, float(v.hyper["knee_rad"])), v)
        return super().rebuild(d, v)

    def valid(self, fit: Fit, v: Variant) -> bool:
        if v.hyper["form"] != "knee":
            return True
        K = _idx(fit, "K_Nm_per_rad")
        return K > 0 and (K + _idx(fit, "dk_knee_Nm_per_rad")) >= 0.25 * K


class Backlash(Effect):
    name = "backlash"
    coordinate = "torsion"
    signature = "near-zero stiffness (lost motion) in a band of twist around zero"

    def applicable(self, d: Design) -> bool:
        return d.sig.kind == "two_mass"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        for b in _phi_grid(d):
            yield self.variant_at(d, float(b))

    @staticmethod
    def variant_at(d: Design, b: float) -> Variant:
        """Half-gap ``b`` (rad at the output)."""
        return Variant({"half_gap_rad": b}, [Column("dk_gap_Nm_per_rad", sat(d.sig.phi, b) / d.sig.ratio, None,
                                                    key=f"sat{b:.6g}", fn=_sat_fn(b, d.sig.ratio))], n_hyper=1)

    def rebuild(self, d: Design, v: Variant) -> Variant:
        return self._keep(self.variant_at(d, float(v.hyper["half_gap_rad"])), v)

    def valid(self, fit: Fit, v: Variant) -> bool:
        K = _idx(fit, "K_Nm_per_rad")
        return K > 0 and (K + _idx(fit, "dk_gap_Nm_per_rad")) < 0.25 * K

    def own_evidence(self, d: Design, fit: Fit, v: Variant) -> dict[str, float]:
        """The lost-motion test at the torque reversals (:func:`hdservo.discrepancy.residuals.lost_motion`):
        the motor's travel beyond the spring's while the transmitted torque reverses.

        Reported with the candidate and not counted by the size rule: on the calibration
        logs it finds none of the zones of 1-4 output counts that the torque residuals
        miss (too few reversals during which the motor keeps its direction) and finds a
        lost motion on some nonlinear-stiffness logs (docs/discrepancy.md, "Lost motion
        at the torque reversals")."""
        return lost_motion(d, fit.params())

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        K = _idx(fit, "K_Nm_per_rad")
        a = _idx(fit, "dk_gap_Nm_per_rad")
        return {"half_gap_rad": v.hyper["half_gap_rad"], "stiffness_in_gap_Nm_per_rad": float(K + a)}


def stop_operator(x: np.ndarray, delta: float) -> np.ndarray:
    """Stop (elastic-perfectly-plastic) operator output, clamp(x - xi, +-delta), xi relaxed at x[0]."""
    out = np.empty_like(x)
    xi = float(x[0])
    for i, xv in enumerate(x.tolist()):
        e = xv - xi
        if e > delta:
            xi = xv - delta
            e = delta
        elif e < -delta:
            xi = xv + delta
            e = -delta
        out[i] = e
    return out


class Hysteresis(Effect):
    name = "hysteresis"
    coordinate = "torsion"
    signature = "residual vs twist depends on the direction of twist change (loops, return-point memory)"
    #: Stop thresholds in units of the twist span (99th percentile of abs(phi)): geometric,
    #: sqrt(2) apart, from 2 % to 90 %.  In closed loop the span is often no more than
    #: twice an element's slip twist, and a grid 2x apart that stops at 64 % leaves the
    #: elements slipping near the span's top between grid points (on such logs this grid
    #: shrinks the equation-error gap 5.5-7.6 times, the coarser one 1.7-2.4 times).
    fractions = tuple(float(x) for x in np.geomspace(0.02, 0.905, 12))

    def applicable(self, d: Design) -> bool:
        return d.sig.kind == "two_mass"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        span = float(np.percentile(np.abs(d.sig.phi), 99))
        yield self.variant_at(d, [f * span for f in self.fractions])

    @staticmethod
    def variant_at(d: Design, thresholds: list[float]) -> Variant:
        """Stop operators of the given thresholds (rad of twist at the output)."""
        s = d.sig
        phi = s.phi
        cols = []
        # the twist is already low-passed at fc: run the (sequential) operators at about
        # 2.5 fc and interpolate back (the operator output is as smooth as its input)
        step = max(1, s.q // 2)
        idx = np.arange(0, len(phi), step)
        for i, D in enumerate(thresholds):
            sop = np.interp(np.arange(len(phi)), idx, stop_operator(phi[idx], D))
            cols.append(Column(f"maxwell{i + 1}_k_Nm_per_rad", sop / s.ratio, None, key=f"stop{D:.6g}"))
        return Variant({"thresholds_rad": list(thresholds)}, cols)

    def rebuild(self, d: Design, v: Variant) -> Variant:
        return self._keep(self.variant_at(d, [float(x) for x in v.hyper["thresholds_rad"]]), v)

    def twin(self, d: Design, v: Variant) -> Variant:
        """The elements' first-loading curves sat_D(phi)/N at the same slip twists: the
        spring the Maxwell-slip elements make along a monotone twist, without their memory.

        Between two reversals of a symmetric cycle the free-sign elements can follow any
        odd memoryless spring (a lost-motion zone, a stiffening), so the hysteresis columns
        fit a backlash or a nonlinear stiffness nearly as well as those effects' own
        columns; what only hysteresis has is the loop, the torque at equal twist depending
        on the direction the twist came from.  The twin has as many columns, so the
        difference of the two fits is that loop alone."""
        N = d.sig.ratio
        # like the stop operators, taken along the measured twist in the simulation error
        cols = [Column(f"twin{i + 1}_k_Nm_per_rad", sat(d.sig.phi, float(D)) / N, None, key=f"sat{float(D):.6g}")
                for i, D in enumerate(v.hyper["thresholds_rad"])]
        return Variant({"thresholds_rad": list(v.hyper["thresholds_rad"]), "memoryless": True}, cols)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for i, (c, D) in enumerate(zip(v.columns, v.hyper["thresholds_rad"])):
            k = _idx(fit, c.name)
            out[f"e{i + 1}_k_Nm_per_rad"] = k
            out[f"e{i + 1}_w_Nm"] = k * D
        return out


class Gravity(Effect):
    """Unbalance of the load: T_g = mgl cos(theta_l + offset) at the output.

    On a baseline with a constant offset (a rigid one), cos and sin of an angle that
    moves over a radian or two can also make up a constant, which is the offset's (and on
    one coordinate equally a direction-dependent friction level's): on the clean
    one-encoder calibration logs whose standstill offset is off, the unbalance took up
    97-99 % of that constant.  So there the columns are centred on their mean over the
    fitted samples: the unbalance explains how the torque varies with the angle, and
    the fit's physical offset is the offset less the centring
    (:attr:`hdservo.discrepancy.regression.Column.shift`).
    """

    name = "gravity_unbalance"
    coordinate = "load angle"
    signature = "torque on the load following cos/sin of the load angle (1 per output revolution)"

    def applicable(self, d: Design) -> bool:
        return d.sig.units.get("angle") == "rad"

    @staticmethod
    def _angle(d: Design) -> tuple[np.ndarray, Any]:
        s = d.sig
        N = s.ratio
        if s.th_l is not None:
            return s.th_l, lambda tm, tl: tl
        return s.th_m / N, lambda tm, tl: tm / N

    @classmethod
    def centre(cls, d: Design) -> tuple[float, float] | None:
        """Mean of cos and sin of the output angle over the fitted (moving) samples when
        the baseline has an offset, else None."""
        if d.sig.kind != "rigid" or not _has_offset(d):
            return None
        th, _ = cls._angle(d)
        return _fitted_mean(d, np.cos(th)), _fitted_mean(d, np.sin(th))

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        yield self.variant_at(d, self.centre(d))

    def variant_at(self, d: Design, centre: tuple[float, float] | None) -> Variant:
        """cos/sin columns of the output angle, centred on ``centre`` (None: not centred)."""
        s = d.sig
        th, out = self._angle(d)
        N = s.ratio
        c0, s0 = centre if centre is not None else (0.0, 0.0)
        hyper = {} if centre is None else {"centre_cos": c0, "centre_sin": s0}
        return Variant(hyper, [
            Column("g_cos_Nm", None, (np.cos(th) - c0) / N, shift=c0 / N,
                   fn=lambda tm, wm, tl, wl: (None, (np.cos(out(tm, tl)) - c0) / N)),
            Column("g_sin_Nm", None, (np.sin(th) - s0) / N, shift=s0 / N,
                   fn=lambda tm, wm, tl, wl: (None, (np.sin(out(tm, tl)) - s0) / N))])

    def rebuild(self, d: Design, v: Variant) -> Variant:
        h = v.hyper
        c = (float(h["centre_cos"]), float(h["centre_sin"])) if "centre_cos" in h else None
        return self._keep(self.variant_at(d, c), v)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        a, b = _idx(fit, "g_cos_Nm"), _idx(fit, "g_sin_Nm")
        # load torque needed = -T_g = mgl cos(th + off) = mgl cos off cos th - mgl sin off sin th
        return {"mgl_Nm": float(np.hypot(a, b)), "offset_rad": float(np.arctan2(-b, a))}


class Compliance(Effect):
    name = "unmodelled_compliance"
    coordinate = "twist acceleration / frequency (torsional mode)"
    signature = "residual follows the twist acceleration; a spectral peak at the torsional mode"

    def applicable(self, d: Design) -> bool:
        return d.sig.kind == "rigid" and d.sig.has_load

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        yield Variant({}, [Column("J_l_kgm2", None, (s.a_l - s.a_m / s.ratio) / s.ratio)])

    def own_evidence(self, d: Design, fit: Fit, v: Variant) -> dict[str, float]:
        """Share of the measured twist that a spring explains: ``twist_fraction``.

        A rigid model puts the load at the motor angle / N, so on a two-encoder log its
        error on the load angle is the measured twist phi = theta_m/N - theta_l.  A spring
        makes it follow the transmitted torque, N (tau - J_m a_m - motor friction) =
        K phi + c phi': phi is regressed on tau, a_m, w_m, sgn w_m, phi' and a constant
        (the encoders' zeros) over the fitted samples, and the fraction is the share of
        phi's variance about its mean that the regression explains, 0 unless the
        torque's coefficient is a positive compliance N/K.  Quantisation of the twist
        (a coarse encoder on a stiff axis) does not follow the torque and stays
        unexplained.  The twist is the compliance's own signature, which the equation
        error of the rigid model weighs only through the twist acceleration.
        """
        s = d.sig
        if not s.has_load:
            return {}
        N = s.ratio
        cols = [s.tau, s.a_m, s.w_m, smooth_sign(s.w_m, 0.1 * d.v_eps * N), s.dphi, np.ones_like(s.tau)]
        X = np.column_stack([d.dec(f"twist:{k}", c)[d.mask] for k, c in enumerate(cols)])
        y = d.dec("twist:phi", s.phi)[d.mask]
        sc = np.sqrt(np.sum(X ** 2, axis=0))
        sc[sc == 0] = 1.0
        coef, *_ = np.linalg.lstsq(X / sc, y, rcond=None)
        coef = coef / sc
        r = y - X @ coef
        ss0 = float(np.sum((y - np.mean(y)) ** 2))
        frac = 1.0 - float(np.sum(r ** 2)) / ss0 if ss0 > 0 else 0.0
        return {"twist_fraction": frac if coef[0] > 0 else 0.0}


class CurrentLag(Effect):
    name = "current_loop_lag"
    coordinate = "torque rate"
    signature = "residual follows -T d(tau)/dt: the torque acting lags the logged command"

    def variants(self, d: Design, resid: np.ndarray) -> Iterator[Variant]:
        s = d.sig
        for T in np.geomspace(0.3 * s.dt, 0.3 / s.fc_Hz, 8):
            a = np.exp(-s.dt / T)
            tau = sps.lfilter([1 - a], [1, -a], s.tau, zi=[a * s.tau[0]])[0]
            yield Variant({"time_constant_s": float(T)}, [], tau=tau, tau_key=f"tau_lag{T:.6g}", n_hyper=1)

    def params(self, fit: Fit, v: Variant) -> dict[str, Any]:
        T = v.hyper["time_constant_s"]
        return {"time_constant_s": T, "bandwidth_Hz": float(1 / (2 * np.pi * T))}


def library() -> list[Effect]:
    """Every candidate, in the order of :data:`hdservo.discrepancy.EFFECT_NAMES`."""
    return [Stribeck(), Asymmetric(), TransmissionError(), Cogging(), NonlinearStiffness(), Hysteresis(),
            Backlash(), Gravity(), Compliance(), CurrentLag()]
