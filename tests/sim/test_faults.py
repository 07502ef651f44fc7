"""The fault matrix, run as users run it: ``python -m sim.faults --json``."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_fault_matrix_has_no_violation():
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "sim.faults", "--json"], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    wall_s = time.perf_counter() - t0
    doc = json.loads(proc.stdout)
    print(f"{doc['cases']} cases, {doc['passed']} passed, {len(doc['violations'])} violations in {wall_s:.1f} s")
    assert doc["cases"] >= 40
    assert doc["violations"] == [], doc["violations"][:10]
    assert doc["passed"] == doc["cases"] and proc.returncode == 0, proc.stderr[-2000:]
    results = {r["case"]: r for r in doc["results"]}
    # Every case had its fault injected; the TRACK cases were checked against real setpoint traffic.
    assert all(r["injected_at_s"] is not None for r in results.values())
    # An abort while the arm is still on its way: nothing at all reaches the vehicle (defect 1).
    slow_arm = [r for name, r in results.items() if name.endswith("/TAKEOFF/abort_in_slow_command")]
    assert len(slow_arm) == 2 and all(r["commands"] == 0 for r in slow_arm)
    assert all(r["commands"] > 0 for r in results.values() if r not in slow_arm)
    assert all(r["setpoints"] > 0 for name, r in results.items() if "/TRACK/" in name)
    assert results["px4/TRACK/pilot_switch"]["outcome"] == "pilot"
    assert results["ardupilot/LAND/gcs_abort"]["outcome"] == "aborted"


def test_bad_option_is_one_line_and_non_zero():
    proc = subprocess.run(
        [sys.executable, "-m", "sim.faults", "--only", "no-such-case"], cwd=ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert "no case matches" in proc.stderr and "Traceback" not in proc.stderr
