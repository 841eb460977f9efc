"""Test procedures ``hdservo test ...``: catalogue gear tests, frequency responses, closed-loop figures.

Modules: :mod:`.runner` (bench, rigs, virtual drive), :mod:`.metrics` (figure-of-merit
calculators), :mod:`.gear`, :mod:`.frequency`, :mod:`.closedloop`, :mod:`.results`
(result records, JSON, plots).  See docs/procedures.md.
"""
