"""Common base for the describing functions of :mod:`hdservo.analysis`.

Every nonlinearity is a subclass of python-control's
:class:`control.DescribingFunctionNonlinearity`, so it can be passed directly to
:func:`control.describing_function` and :func:`control.describing_function_response`.

Conventions (the same as python-control's numerical DF): for an input
``x = A sin(theta)`` the describing function is ``N(A) = (b1 + j a1) / A`` with
``b1 = (1/pi) int F sin(theta) dtheta`` and ``a1 = (1/pi) int F cos(theta) dtheta``.
A positive imaginary part is a phase *lead* of the output's first harmonic
(e.g. the force of a damper, or of a hysteretic spring); a negative one a lag
(e.g. backlash).
"""
from __future__ import annotations

import math
from typing import Any, Callable, Dict

import numpy as np
from control import DescribingFunctionNonlinearity


def sat_df(r: float) -> float:
    """Describing function of a unit-slope saturation with limit ``delta``.

    Parameters
    ----------
    r : float
        Ratio ``delta / A`` (dimensionless, >= 0).

    Returns
    -------
    float
        ``g(r) = (2/pi)(asin r + r sqrt(1 - r^2))`` for ``r < 1``, else 1.
    """
    if r >= 1.0:
        return 1.0
    return 2.0 / math.pi * (math.asin(r) + r * math.sqrt(1.0 - r * r))


def backlash_df(A: float, b: float) -> complex:
    """Describing function of friction-controlled backlash (play) of total width ``b``.

    Gelb and Vander Velde #48; the same formula as python-control's
    ``friction_backlash_nonlinearity``.

    Parameters
    ----------
    A : float
        Input amplitude (input units).
    b : float
        Total play width (input units, >= 0).

    Returns
    -------
    complex
        N(A) (dimensionless); 0 for ``A <= b/2``.
    """
    if b <= 0.0:
        return complex(1.0)
    if A <= b / 2.0:
        return 0j
    r = b / A
    x = 1.0 - r  # in (-1, 1]
    g = math.copysign(1.0, x) if abs(x) >= 1.0 else 2.0 / math.pi * (math.asin(x) + x * math.sqrt(1.0 - x * x))
    return complex(0.5 * (1.0 + g), -(2.0 * r - r * r) / math.pi)


def first_harmonic(samples: np.ndarray, A: float) -> complex:
    """First-harmonic gain of one period of samples of ``F(A sin theta)``.

    Parameters
    ----------
    samples : numpy.ndarray
        Output values at ``theta_k = 2 pi k / n``, k = 0..n-1 (output units).
    A : float
        Input amplitude (input units, > 0).

    Returns
    -------
    complex
        ``(b1 + j a1) / A`` (output units per input unit).
    """
    n = samples.size
    theta = 2.0 * np.pi * np.arange(n) / n
    b1 = 2.0 / n * float(samples @ np.sin(theta))
    a1 = 2.0 / n * float(samples @ np.cos(theta))
    return complex(b1, a1) / A


class HdNonlinearity(DescribingFunctionNonlinearity):
    """Base class: a named SISO nonlinearity with units and a describing function.

    Subclasses implement :meth:`__call__` (one input sample -> one output
    sample, updating internal state if any), :meth:`reset` (back to the virgin
    state) and, where a closed form exists, :meth:`describing_function`.
    The fallback :meth:`numerical_df` resets the state, runs one warm-up cycle
    and takes the first harmonic of the second, so a stateful element can be
    evaluated at any amplitude in any order.
    """

    #: short identifier used on the command line and in JSON
    kind: str = "nonlinearity"
    #: physical quantity and unit of the input and the output
    input_name: str = "x"
    input_unit: str = "1"
    output_name: str = "y"
    output_unit: str = "1"
    #: number of samples per cycle of the numerical first harmonic
    num_points: int = 2048

    def reset(self) -> None:
        """Return to the virgin (initial) state; static maps do nothing."""

    def _isstatic(self) -> bool:
        return False

    def numerical_df(self, A: float, num_points: int | None = None) -> complex:
        """Numerical first-harmonic DF at amplitude ``A`` from a fresh state.

        Parameters
        ----------
        A : float
            Input amplitude (input units, >= 0).
        num_points : int, optional
            Samples per cycle (default :attr:`num_points`).

        Returns
        -------
        complex
            N(A) (output units per input unit).
        """
        if A < 0:
            raise ValueError("cannot evaluate a describing function for A < 0")
        if A == 0:
            return self.small_signal_gain()
        n = int(num_points or self.num_points)
        s = A * np.sin(2.0 * np.pi * np.arange(n) / n)
        self.reset()
        for x in s:  # warm-up cycle: reach the periodic steady state
            self(float(x))
        y = np.array([float(self(float(x))) for x in s])
        self.reset()
        return first_harmonic(y, A)

    def small_signal_gain(self) -> complex:
        """Limit of N(A) as A -> 0 (output units per input unit)."""
        return self.describing_function(1e-12 * self.amplitude_scale())

    def amplitude_scale(self) -> float:
        """Typical input amplitude (input units): the centre of default sweeps."""
        return 1.0

    def describing_function(self, A: float) -> complex:
        """N(A); numerical first harmonic unless a subclass has a closed form."""
        return self.numerical_df(A)

    def to_dict(self) -> Dict[str, Any]:
        """Parameters for the JSON report."""
        return {"kind": self.kind, "input": f"{self.input_name} [{self.input_unit}]",
                "output": f"{self.output_name} [{self.output_unit}]"}

    def df_array(self, amplitudes: np.ndarray) -> np.ndarray:
        """N(A) for an array of amplitudes (complex array)."""
        return np.array([self.describing_function(float(a)) for a in np.atleast_1d(amplitudes)],
                        dtype=complex)


StaticMap = Callable[[float], float]
