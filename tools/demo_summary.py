#!/usr/bin/env python3
"""Print a short table of tracking figures for demo logs (arcsec)."""
from __future__ import annotations

import sys

import numpy as np

from hdservo import logio

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


def main(paths: list[str]) -> int:
    print(f"{'log':<28}{'duration s':>12}{'RMS err arcsec':>16}{'max err arcsec':>16}{'final err arcsec':>18}")
    for path in paths:
        log = logio.read_log(path)
        cols = log.columns if hasattr(log, "columns") else log
        t = np.asarray(cols["t_s"])
        err = (np.asarray(cols["load_angle_rad"]) - np.asarray(cols["setpoint_rad"])) * ARCSEC_PER_RAD
        settled = t > t[0] + 0.2 * (t[-1] - t[0])
        e = err[settled]
        print(f"{path.split('/')[-1]:<28}{t[-1]:>12.2f}{np.sqrt(np.mean(e**2)):>16.3f}"
              f"{np.max(np.abs(e)):>16.3f}{err[-1]:>18.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
