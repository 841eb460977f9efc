"""Open-loop amplitude-frequency response and resonance (harmonic-drive.md 9.2).

The drive holds its position (CSP, the loop keeps the axis at its working
point) while the host adds a band-limited random torque to the torque
feed-forward, one RPDO per SYNC (lock-step on the virtual drive).  The drive's
capture buffer records the total torque command u (controller + excitation),
the motor and the output angle at 2 kHz; the plant FRFs are the H1 estimates
u -> theta_M / N and u -> theta_L with coherence (Welch, Hann, 50 % overlap,
averaged over several capture blocks).  Using the measured u makes the
estimate independent of the host's timing, so the same procedure runs on a
real drive with wall-clock pacing.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import numpy as np

from . import metrics as mt
from .closedloop import AXIS_SETUP
from .results import Result, figure, save_figure
from ..drive import DriveError
from .runner import CAPTURE_WORDS, DT, SIG, Bench, Progress
from ..phase import unwrap_turns

from ..units import TURN  # noqa: E402


def _excitation(n: int, rms_Nm: float, f_hi_Hz: float, fs_Hz: float, seed: int) -> np.ndarray:
    """Band-limited (brick-wall in the DFT) Gaussian noise of RMS rms_Nm."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal(n)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(n, 1.0 / fs_Hz)
    X[(f > f_hi_Hz) | (f < 1.0)] = 0.0
    x = np.fft.irfft(X, n)
    return x / np.sqrt(np.mean(x ** 2)) * rms_Nm


def measure_frf(bench: Bench, rms_Nm: float = 6.0, blocks: int = 3, f_hi_Hz: float = 250.0, nperseg: int = 1024,
                seed: int = 1, progress: Optional[Progress] = None) -> dict[str, Any]:
    """Record the torque -> motor / output angle FRFs (see the module docstring)."""
    k = bench.sync_periods
    fs_sp = 1.0 / (k * DT)
    decim = 5
    fs = 1.0 / (decim * DT)
    frames = 2730
    rated = bench.rated_torque_Nm()
    per_block = int(math.ceil(frames * decim / k)) + 20
    exc = _excitation((blocks + 1) * per_block, rms_Nm, min(f_hi_Hz, 0.45 * fs_sp), fs_sp, seed)
    us, ym, yl = [], [], []
    bench.rig.brake(False)
    bench.enable("CYCLIC SYNCHRONOUS POSITION")
    bench.wait(0.2)
    send = lambda v: bench.rpdo_torque(v, rated)   # noqa: E731
    bench.stream(exc[:per_block], send)             # transient
    for b in range(blocks):
        seg = exc[(b + 1) * per_block:(b + 2) * per_block]
        cap = bench.capture(["torque_cmd", "pos_mot_lo", "pos_out_lo"], frames, decim,
                            action=lambda seg=seg: bench.stream(seg, send))
        us.append(cap["torque_cmd"].astype(float) / 2 ** 16)
        ym.append(unwrap_turns(cap["pos_mot_lo"], centred=False) * TURN / bench.ratio)
        yl.append(unwrap_turns(cap["pos_out_lo"], centred=False) * TURN)
        if progress:
            progress((b + 1) / blocks, f"block {b + 1}/{blocks}")
    send(0.0)
    bench.sync()
    fault = bench.fault()
    bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the FRF (fault code {fault})")
    hm = mt.welch_frf(us, ym, fs, nperseg)
    hl = mt.welch_frf(us, yl, fs, nperseg)
    return {"f_Hz": hm["f_Hz"], "H_motor": hm["H"], "coh_motor": hm["coherence"], "H_load": hl["H"],
            "coh_load": hl["coherence"], "fs_Hz": fs, "segments": int(hm["segments"]), "rms_Nm": rms_Nm,
            "u_rms_Nm": float(np.sqrt(np.mean(np.concatenate(us) ** 2)))}


def _upload(bench: Bench, n: int) -> np.ndarray:
    """The capture buffer as (frames, n) int64; the upload is repeated after a failed transfer
    (with fast pacing the drive's 1 s SDO time-out is drive time)."""
    for attempt in range(4):
        try:
            raw = bench.drive.read_domain(0x5000, 7)
            break
        except DriveError:
            if attempt == 3:
                raise
    w = np.frombuffer(raw, dtype="<i4").astype(np.int64)
    return w[: (w.size // n) * n].reshape(-1, n)


def _wait_capture(bench: Bench, periods: int) -> None:
    """Let drive time run until the capture buffer is full (0x5000:2 = 3)."""
    for _ in range(100000):
        if bench.read(0x5000, 2) == 3:
            return
        bench.wait(max(periods // 4, bench.sync_periods) * DT)
    raise DriveError("capture did not finish")  # pragma: no cover


def line_frf(u: list[np.ndarray], y: list[np.ndarray], per: int, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H1 = sum conj(U) Y / sum |U|^2 and coherence at the DFT ``lines`` of whole periods of
    ``per`` samples of a periodic excitation (rectangular window: no leakage), averaged over
    every whole period of every block."""
    suu = syy = 0.0
    suy: Any = 0.0
    for ub, yb in zip(u, y):
        for s in range(0, ub.size - per + 1, per):
            a = np.fft.rfft(ub[s:s + per])[lines]
            b = np.fft.rfft(yb[s:s + per])[lines]
            suu = suu + np.abs(a) ** 2
            syy = syy + np.abs(b) ** 2
            suy = suy + np.conj(a) * b
    return suy / suu, np.abs(suy) ** 2 / (suu * syy)


def measure_frf_drive(bench: Bench, rms_Nm: float = 6.0, blocks: int = 3, lines: int = 64, period_s: float = 0.8,
                      decimation: int = 8, progress: Optional[Progress] = None) -> dict[str, Any]:
    """Torque -> motor / output angle FRFs with the drive's own multisine (0x5010).

    The drive holds its position (CSP, then excitation injection ``torque_ff``: the
    multisine is added to the torque feed-forward of the position loop) and runs a
    Schroeder multisine of ``lines`` lines at k / period_s Hz (RMS ``rms_Nm``).  The capture
    buffer (armed first, triggered by the start of the excitation, then re-triggered per
    block) records the excitation, the total torque command u, the motor and output angles
    every ``decimation`` periods; the first period is dropped as transient.  H1 (u -> y) and
    coherence at the excited lines, averaged over whole periods; nothing is streamed from
    the host, so the timing is the drive's own.
    """
    per_loop = int(round(period_s / DT))
    if per_loop % decimation:
        raise ValueError("measure_frf_drive: period_s / DT must be a multiple of the decimation")
    per = per_loop // decimation
    fs = 1.0 / (decimation * DT)
    sig = ["exc", "torque_cmd", "pos_mot_lo", "pos_out_lo"]
    frames = (CAPTURE_WORDS // len(sig)) // per * per
    if frames < per:
        raise ValueError("measure_frf_drive: the capture buffer holds less than one period")
    amp = rms_Nm / math.sqrt(lines / 2.0)
    d = bench.drive
    bench.rig.brake(False)
    bench.enable("CYCLIC SYNCHRONOUS POSITION")
    bench.wait(0.2)
    rs, us, ym, yl = [], [], [], []
    try:
        for b in range(blocks):
            while True:
                try:
                    d.arm_capture([SIG[s] for s in sig], frames, decimation)
                    break
                except DriveError:
                    if frames <= per:           # a smaller buffer (STM32: 4096 words): fewer periods
                        raise
                    frames = max(per, (frames // 2) // per * per)
            if b == 0:
                d.excite("multisine", amp, injection="torque_ff", lines=lines, period_s=period_s)
            else:
                d.write(0x5000, 1, 2)
            _wait_capture(bench, frames * decimation)
            w = _upload(bench, len(sig))
            skip = per if b == 0 else 0                     # transient of the first period
            if w.shape[0] - skip < per:
                continue
            rs.append(w[skip:, 0].astype(float) / 2 ** 16)
            us.append(w[skip:, 1].astype(float) / 2 ** 16)
            ym.append(unwrap_turns(w[skip:, 2] & 0xFFFFFFFF, centred=False) * TURN / bench.ratio)
            yl.append(unwrap_turns(w[skip:, 3] & 0xFFFFFFFF, centred=False) * TURN)
            if progress:
                progress((b + 1) / blocks, f"block {b + 1}/{blocks}")
    finally:
        try:
            d.stop_excitation()
        except DriveError:
            pass
    bench.sync()
    fault = bench.fault()
    bench.disable()
    if fault:
        raise RuntimeError(f"the drive faulted during the FRF (fault code {fault})")
    k = np.arange(1, lines + 1)
    hm, cm = line_frf(us, ym, per, k)
    hl, cl_ = line_frf(us, yl, per, k)
    nseg = sum(x.size // per for x in us)
    return {"f_Hz": k / period_s, "H_motor": hm, "coh_motor": cm, "H_load": hl, "coh_load": cl_, "fs_Hz": fs,
            "segments": int(nseg), "rms_Nm": rms_Nm, "u_rms_Nm": float(np.sqrt(np.mean(np.concatenate(us) ** 2))),
            "exc": rs, "method": "drive"}


def _plot(r: Result, d: Path, fmt: str) -> list[Path]:
    fig, ax = figure(2, 1, (8, 6))
    s = r.series
    f = s["f_Hz"]
    keep = (f >= 2) & (f <= 300)
    ax[0][0].loglog(f[keep], np.abs(s["H_motor"][keep]), label="u -> theta_M/N")
    ax[0][0].loglog(f[keep], np.abs(s["H_load"][keep]), label="u -> theta_L")
    ax[0][0].set_ylabel("|H| (rad/N.m)")
    ax[0][0].legend()
    ax[1][0].semilogx(f[keep], s["coh_motor"][keep], label="motor")
    ax[1][0].semilogx(f[keep], s["coh_load"][keep], label="output")
    ax[1][0].set_ylabel("coherence (-)")
    ax[1][0].set_xlabel("frequency (Hz)")
    for a in (ax[0][0], ax[1][0]):
        a.grid(True, which="both")
    return save_figure(fig, d, r.name, fmt, label=r.label)


def _summary(d: dict[str, Any], f_lo: float, f_hi: float) -> dict[str, Any]:
    f = d["f_Hz"]
    w2 = (2 * np.pi * f) ** 2
    fr = mt.resonances(f, w2 * d["H_load"], f_lo, f_hi)["resonance_Hz"]     # output side: peak at f_r
    res = {"resonance_Hz": fr}
    try:
        below = mt.resonances(f, w2 * d["H_motor"], f_lo, fr + 1e-9)          # motor side: dip f_a below f_r
        if "anti_resonance_Hz" in below:
            res["anti_resonance_Hz"] = below["anti_resonance_Hz"]
    except ValueError:
        pass
    band = (f >= f_lo) & (f <= f_hi)
    return {**res, "mean_coherence_motor": float(np.mean(d["coh_motor"][band])),
            "mean_coherence_load": float(np.mean(d["coh_load"][band]))}


def frf(bench: Bench, rms_Nm: float = 6.0, blocks: int = 3, f_lo_Hz: float = 25.0, f_hi_Hz: float = 100.0,
        progress: Optional[Progress] = None, source: str = "auto") -> Result:
    """Open-loop amplitude-frequency response (motor and output side) with coherence.

    ``source``: "drive" = the drive's own multisine (0x5010, :func:`measure_frf_drive`),
    "host" = host-streamed random torque (:func:`measure_frf`), "auto" = drive when the drive
    has the excitation objects, else host.
    """
    if source not in ("auto", "drive", "host"):
        raise ValueError("frf: source must be auto, drive or host")
    on_drive = source == "drive" or (source == "auto" and bench.drive.has_excitation())
    if on_drive:
        d = measure_frf_drive(bench, rms_Nm, blocks, progress=progress)
        how = "drive multisine (0x5010, torque feed-forward)"
    else:
        d = measure_frf(bench, rms_Nm, blocks, progress=progress)
        how = "host-streamed random torque"
    r = Result("frf", conditions={"excitation_rms_Nm": rms_Nm, "blocks": blocks, "sample_rate_Hz": d["fs_Hz"],
                                  "segments": d["segments"], "setup": AXIS_SETUP.name, "excitation": how,
                                  "method": "H1 with the measured torque command, closed position loop holding"})
    f = d["f_Hz"]
    pick = np.unique(np.clip(np.searchsorted(f, np.geomspace(2.0, 300.0, 60)), 0, f.size - 1))
    r.figures = {"f_Hz": f[pick].tolist(), "motor_mag_rad_per_Nm": np.abs(d["H_motor"][pick]).tolist(),
                 "motor_phase_deg": np.degrees(np.angle(d["H_motor"][pick])).tolist(),
                 "load_mag_rad_per_Nm": np.abs(d["H_load"][pick]).tolist(),
                 "coherence_motor": d["coh_motor"][pick].tolist(), "coherence_load": d["coh_load"][pick].tolist(),
                 "u_rms_Nm": d["u_rms_Nm"], **_summary(d, f_lo_Hz, f_hi_Hz)}
    r.headline = {"resonance_hz": r.figures["resonance_Hz"], "anti_resonance_hz": r.figures.get("anti_resonance_Hz")}
    r.series = d
    r.plot = _plot
    return r


def resonance(bench: Bench, rms_Nm: float = 6.0, blocks: int = 3, f_lo_Hz: float = 25.0, f_hi_Hz: float = 100.0,
              progress: Optional[Progress] = None, source: str = "auto") -> Result:
    """First torsional resonance (peak of the output-side accelerance) and anti-resonance (motor-side dip).

    Searched in [f_lo_Hz, f_hi_Hz] (default 25-100 Hz, where the reference axis has its
    first mode); the loop's notch removes torque near 50 Hz, so the coherence dips there.
    """
    r = frf(bench, rms_Nm, blocks, f_lo_Hz, f_hi_Hz, progress, source)
    r.name = "resonance"
    keep = {k: r.figures[k] for k in ("resonance_Hz", "anti_resonance_Hz", "mean_coherence_motor",
                                       "mean_coherence_load", "u_rms_Nm") if k in r.figures}
    r.figures = keep
    return r


__all__ = ["frf", "line_frf", "measure_frf", "measure_frf_drive", "resonance"]
