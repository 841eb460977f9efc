"""hdservo: model, identify and compensate harmonic-drive servo axes.

The package talks to a drive only over CAN (python-can / canopen) and loads the
simulator through a small ctypes binding for offline work.  Files it needs at run
time (simulator, axis files, EDS, DBC) are found by :mod:`hdservo.resources`.
"""
from __future__ import annotations

__version__ = "0.1.0"
