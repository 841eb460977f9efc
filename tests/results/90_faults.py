#!/usr/bin/env python3
"""Fault-injection table -> build/results/faults.json (tests/python/oracles/faults.py):
encoder jumps and dropouts, current saturation, load-torque shocks,
parameter-store corruption at boot and power loss in the middle of a save.
Exit status 1 if any case shows a reaction other than the expected one."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "python"))

from oracles.faults import main  # noqa: E402

sys.exit(main())
