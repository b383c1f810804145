"""What the check_*.py ctest scripts share: the failures found so far and the check that records
one (printing it), the test for a figure that must be a positive finite number, and a run of
rtc-bench with its JSON lines. Each script imports this from its own folder (Python puts a
script's folder first on its path)."""
import json
import math
import subprocess

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}")


def finite_positive(value):
    return isinstance(value, (int, float)) and math.isfinite(value) and value > 0


def bench_json(bench, args, timeout=240):
    """Runs rtc-bench `bench` with `args` and --json, recording a failure unless it exits with
    status 0. Returns its standard output and the JSON lines in it, parsed."""
    run = subprocess.run([bench, *args, "--json"], capture_output=True, text=True, timeout=timeout)
    check(run.returncode == 0, f"rtc-bench {' '.join(args)}: exit status {run.returncode}: {run.stderr[-2000:]}")
    return run.stdout, [json.loads(line) for line in run.stdout.splitlines() if line.startswith("{")]
