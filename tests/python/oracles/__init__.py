"""Reference implementations the tests compare the product with (test oracles).

They live with the tests, not in the package: the Python twins of the firmware kernels
(``compref``, ``refmodels``), the fault-injection runners (``faults``, ``faults_can``),
the describing-function checks against simulation (``simcheck``, ``timesim``) and the
synthetic discrepancy cases (``discrepancy_cases``).  ``make results`` uses some of them
too.
"""
