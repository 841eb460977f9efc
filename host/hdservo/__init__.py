"""hdservo: model, identify and compensate harmonic-drive servo axes.

The package talks to a drive only over CAN (python-can / canopen) and loads the
simulator through a small ctypes binding for offline work.
"""
from __future__ import annotations

from pathlib import Path

__version__ = "0.1.0"

#: Repository root when running from a checkout (host/ is installed editable).
REPO_ROOT = Path(__file__).resolve().parents[2]
