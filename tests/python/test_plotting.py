"""matplotlib's backend is chosen in one place (hdservo.plotting)."""
from __future__ import annotations

import subprocess
import sys


def test_pyplot_selects_agg_once_without_a_display() -> None:
    code = ("import os; os.environ.pop('DISPLAY', None); os.environ['MPLBACKEND'] = 'TkAgg'\n"
            "from hdservo.plotting import pyplot\n"
            "plt = pyplot(); assert plt is pyplot()\n"
            "import matplotlib; print(matplotlib.get_backend())\n"
            "fig = plt.figure(); plt.close(fig)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip().lower() == "agg"


def test_plot_modules_take_pyplot_from_plotting() -> None:
    code = ("import os; os.environ['MPLBACKEND'] = 'TkAgg'\n"
            "import hdservo.analysis.plots, hdservo.discrepancy.plots\n"
            "import matplotlib; print(matplotlib.get_backend())\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip().lower() == "agg"
