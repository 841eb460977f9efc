"""Angle units, one home: radians are the SI unit of every host computation.

``ARCSEC`` and ``DEG`` are one arc second and one degree in rad; multiply a value in
those units by them to get rad, divide rad by them to get the unit back.
"""
from __future__ import annotations

import math

#: one turn, rad
TURN = 2.0 * math.pi
#: one degree, rad
DEG = math.pi / 180.0
#: one arc minute, rad
ARCMIN = DEG / 60.0
#: one arc second, rad
ARCSEC = DEG / 3600.0
#: arc seconds per rad
ARCSEC_PER_RAD = 1.0 / ARCSEC
