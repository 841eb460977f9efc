"""Double-precision reference models of the firmware controllers.

Each module mirrors one firmware/core controller with the same equations in
real arithmetic; tests/python/test_control_*.py feed both the same inputs and
check the fixed-point result against the reference within a documented
quantisation tolerance (docs/control.md).
"""
