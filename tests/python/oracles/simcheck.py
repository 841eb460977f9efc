"""Check a describing-function limit-cycle prediction against the C simulator.

The prediction uses only the axis file and the drive's gains (the same numbers
the simulator is run with); the simulation is the project's closed-loop C
simulator (firmware application + plant in lock-step, :mod:`hdservo.sim`),
run from scenario text written here.

Case (docs/describing-functions.md, "Check against the C simulator"):
friction hunting.  The position loop is detuned with integral action
(``pos_ki``); the dominant nonlinearity is the motor-side friction (Stribeck,
referred to the output it is 7-10 N m against 0.4-0.6 N m on the output side).
Plant effects that would blur the cycle are switched off (base motion, gravity,
transmission error, cogging, both hystereses, sensor noise); friction stays on
both sides as in the axis file (LuGre on).  The axis starts at rest, a 100 arcsec
position step at 0.05 s starts the motion, and the oscillation of the position
error ``setpoint - true load angle`` is measured after the transient:
frequency from the mean period between upward crossings of the mid-range,
amplitude as half its peak-to-peak.  The DF amplitude of the same quantity is
``A |G_theta,w / G_z,w|`` at the cycle (:meth:`LoopModel.cycle_amplitude`); the
DF's own variable (motor velocity) is compared with the first harmonic of the
simulated motor velocity at the simulated frequency.
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional

import numpy as np

from hdservo.tomltext import basic_string
from hdservo.analysis.axis import load_axis, load_gains
from hdservo.analysis.catalogue import build
from hdservo.analysis.limitcycle import LimitCycle, find_limit_cycles
from hdservo.analysis.loop import LoopModel
from oracles.timesim import measure_oscillation

from hdservo.units import ARCSEC as ARCSEC_RAD  # noqa: E402

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[3]

#: Plant effects switched off so that the friction cycle is not blurred.
QUIET_PLANT: Dict[str, bool] = {
    "base.enabled": False, "gravity.enabled": False, "transmission_error.enabled": False,
    "cogging.enabled": False, "hysteresis_maxwell.enabled": False, "hysteresis_preisach.enabled": False,
    "encoder_motor.enabled": False, "encoder_load.enabled": False, "gyro.enabled": False,
    "current_sensor.enabled": False,
}

#: Lock-step simulator: the sensor sample taken at the start of a period drives
#: the command held over that period (zero-order hold, T/2; no computation delay).
SIM_DELAY_PERIODS = 0.5


@dataclass
class HuntingCase:
    """A detuned loop to run in the C simulator and to analyse.

    Attributes
    ----------
    pos_ki : float
        Position-loop integral gain (1/s^2), the detuning.
    nonlinearity : str
        Catalogue name of the element the DF analysis uses (``stribeck_motor``).
    plant : dict
        Plant overrides (``"section.key"`` -> value), applied in the simulator
        and to the analysis' axis parameters alike.
    duration_s : float
        Simulated time (s).
    settle_s : float
        Start of the measurement window (s).
    step_rad : float
        Position step at 0.05 s that starts the motion (rad).
    log_decimation : int
        Log one row every this many 100 us periods.
    """

    pos_ki: float
    nonlinearity: str = "stribeck_motor"
    plant: Dict[str, Any] = field(default_factory=lambda: dict(QUIET_PLANT))
    duration_s: float = 4.0
    settle_s: float = 1.5
    step_rad: float = 100.0 * ARCSEC_RAD
    log_decimation: int = 5


@dataclass
class SimCheck:
    """Prediction against simulation for one case.

    Attributes
    ----------
    case : HuntingCase
    cycle : LimitCycle or None
        The stable predicted cycle (None: none predicted).
    predicted_pos_amp_rad : float
        Predicted amplitude of the position error (rad), 0 without a cycle.
    sim_pos_amp_rad : float
        Simulated half peak-to-peak of the position error (rad).
    sim_frequency_Hz : float
        Simulated frequency (Hz), 0 if fewer than 3 crossings.
    sim_cycles : int
        Whole periods in the measurement window.
    sim_vel_h1_rad_s : float
        First harmonic of the simulated motor velocity at ``sim_frequency_Hz``
        (rad/s at the motor).
    """

    case: HuntingCase
    cycle: Optional[LimitCycle]
    predicted_pos_amp_rad: float
    sim_pos_amp_rad: float
    sim_frequency_Hz: float
    sim_cycles: int
    sim_vel_h1_rad_s: float

    @property
    def amplitude_error(self) -> float:
        """(predicted - simulated) / simulated position amplitude (dimensionless)."""
        return (self.predicted_pos_amp_rad - self.sim_pos_amp_rad) / self.sim_pos_amp_rad

    @property
    def frequency_error(self) -> float:
        """(predicted - simulated) / simulated frequency (dimensionless)."""
        assert self.cycle is not None
        return (self.cycle.frequency_Hz - self.sim_frequency_Hz) / self.sim_frequency_Hz

    def to_dict(self) -> Dict[str, Any]:
        d: Dict[str, Any] = {"pos_ki": self.case.pos_ki, "nonlinearity": self.case.nonlinearity,
                             "sim_pos_amp_arcsec": self.sim_pos_amp_rad / ARCSEC_RAD,
                             "sim_frequency_Hz": self.sim_frequency_Hz, "sim_cycles": self.sim_cycles,
                             "sim_motor_vel_h1_rad_s": self.sim_vel_h1_rad_s}
        if self.cycle is not None:
            d.update(df_pos_amp_arcsec=self.predicted_pos_amp_rad / ARCSEC_RAD,
                     df_frequency_Hz=self.cycle.frequency_Hz, df_motor_vel_amp_rad_s=self.cycle.amplitude,
                     amplitude_error=self.amplitude_error, frequency_error=self.frequency_error)
        return d


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(float(v))


def axis_file() -> Path:
    """The reference axis file both the analysis and the simulator read."""
    return REPO_ROOT / "sim" / "axes" / "reference.toml"


def scenario_text(case: HuntingCase, axis: Path) -> str:
    """Scenario TOML (docs/sim.md) of a hunting case.

    Parameters
    ----------
    case : HuntingCase
    axis : pathlib.Path
        Axis file (written as given; the scenario is a temporary file).
    """
    plant = "\n".join(f"{k} = {_toml_value(v)}" for k, v in case.plant.items())
    return f"""[scenario]
name = "df_hunting_pos_ki_{case.pos_ki:g}"
axis = {basic_string(axis.as_posix())}
duration_s = {case.duration_s!r}
seed = 1
log_decimation = {int(case.log_decimation)}

[controller]
mode = "position"
compensators = []

[controller.gains]
pos_ki = {float(case.pos_ki)!r}

[setpoint]
type = "step"
initial_rad = 0.0
amplitude_rad = {case.step_rad!r}
t0_s = 0.05

[plant]
{plant}
"""


def run_simulation(case: HuntingCase) -> Dict[str, np.ndarray]:
    """Run a case in the C simulator; log columns (SI units, see docs/sim.md)."""
    from hdservo import sim

    with tempfile.TemporaryDirectory(prefix="hdservo-df-") as d:
        path = Path(d) / "hunting.toml"
        path.write_text(scenario_text(case, axis_file()))
        return dict(sim.run_scenario(path).columns)


def first_harmonic_at(t: np.ndarray, x: np.ndarray, f: float) -> float:
    """Amplitude of the component of ``x`` at ``f`` Hz over whole periods (units of x)."""
    if f <= 0:
        return 0.0
    n = int((t[-1] - t[0]) * f)
    if n < 1:
        return 0.0
    k = t < t[0] + n / f
    y = x[k] - x[k].mean()
    return float(2.0 * abs(np.mean(y * np.exp(-2j * math.pi * f * t[k]))))


def predict(case: HuntingCase) -> tuple[Optional[LimitCycle], float]:
    """DF prediction from the axis file and the drive's gains (+ the case's overrides).

    Returns
    -------
    cycle : LimitCycle or None
        The stable cycle (the one of largest amplitude if several).
    pos_amp_rad : float
        Its position-error amplitude (rad), 0 without a cycle.
    """
    ax, _ = load_axis(None)  # sim/axes/reference.toml, the file the simulator is given
    for k, v in case.plant.items():
        if k in ax:
            ax[k] = float(v)
    gains, _ = load_gains([f"pos_ki={case.pos_ki}", f"delay_periods={SIM_DELAY_PERIODS}"])
    entry = build(case.nonlinearity, ax)
    model = LoopModel(ax, gains)
    omega = 2 * math.pi * np.logspace(-1, 3, 1500)
    stable = [c for c in find_limit_cycles(model.H(entry.insertion), entry.nl, entry.amplitudes, omega)
              if c.stable]
    if not stable:
        return None, 0.0
    lc = stable[-1]
    return lc, model.cycle_amplitude(entry.insertion, "theta_L", lc.amplitude, lc.omega_rad_s)


def check(case: HuntingCase) -> SimCheck:
    """Predict, simulate and measure one case."""
    lc, amp = predict(case)
    r = run_simulation(case)
    t = r["t_s"]
    keep = t >= case.settle_s
    err = r["setpoint_rad"][keep] - r["load_angle_true_rad"][keep]
    osc = measure_oscillation(t[keep], err)
    vh1 = first_harmonic_at(t[keep], r["motor_velocity_rad_s"][keep], osc.frequency_Hz)
    return SimCheck(case, lc, amp, osc.amplitude, osc.frequency_Hz, osc.cycles, vh1)


def table(pos_kis: List[float]) -> List[Dict[str, Any]]:
    """Comparison rows for several ``pos_ki`` (for the docs)."""
    return [check(HuntingCase(pos_ki=k)).to_dict() for k in pos_kis]


def _main() -> None:  # pragma: no cover - documentation helper
    for row in table([0.0, 1000.0, 1500.0, 2000.0, 3000.0, 4000.0]):
        print({k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()})


if __name__ == "__main__":  # pragma: no cover
    _main()
