"""Describing-function analysis of the harmonic-drive axis (``hdservo df``).

Modules: :mod:`.dfbase` (base class, helpers), :mod:`.friction`,
:mod:`.stiffness`, :mod:`.hysteresis`, :mod:`.preisach` (the nonlinearities),
:mod:`.axis` (axis parameters and gains), :mod:`.loop` (the linear cascaded
loop and where each nonlinearity enters), :mod:`.limitcycle` (limit cycles,
Loeb criterion, margins versus amplitude), :mod:`.timesim` (an independent
time-domain simulation used to check the predictions), :mod:`.plots`.
"""
