"""What the check_*.py ctest scripts share: the failures found so far and the check that records
one (printing it), and the test for a figure that must be a positive finite number. Each script
imports this from its own folder (Python puts a script's folder first on its path)."""
import math

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}")


def finite_positive(value):
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0
