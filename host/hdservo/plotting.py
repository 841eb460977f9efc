"""The one place that selects matplotlib's backend: files only (Agg), never a window.

Every plotting module takes pyplot from :func:`pyplot`, so the backend is chosen
once, before pyplot is first imported, and a command run without a display
(CI, a drive bench over SSH) never tries to open one.
"""
from __future__ import annotations

from types import ModuleType


def pyplot() -> ModuleType:
    """``matplotlib.pyplot`` with the Agg backend selected (idempotent)."""
    import matplotlib
    if matplotlib.get_backend().lower() != "agg":
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


__all__ = ["pyplot"]
