"""The circle mission end to end: the real CLI, real MAVSDK, real UDP, the simulated PX4 autopilot.

These run in real time (about two minutes each for a whole mission).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.e2e.cliutil import ROOT

pytestmark = pytest.mark.e2e


def fly(tmp_path, *extra: str) -> tuple[subprocess.CompletedProcess[str], dict]:
    run_dir = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "app.main", "--mission", "circle.yaml", "--sim", "--run-dir", str(run_dir),
         "--pilot-port", "0", *extra],
        cwd=ROOT, capture_output=True, text=True, timeout=400,
    )  # fmt: skip
    summary = json.loads((run_dir / "summary.json").read_text())
    return proc, summary


def test_circle_mission_completes_with_default_wind(tmp_path):
    proc, s = fly(tmp_path, "--seed", "7")
    assert proc.returncode == 0, proc.stderr + json.dumps(s)
    assert s["outcome"] == "completed"
    assert s["states_visited"] == ["PREFLIGHT", "TAKEOFF", "TRACK", "LAND", "DONE"]
    assert s["autopilot"] == "PX4"
    assert s["tracking_samples"] > 1000  # 65 s after settle at ≥ 20 Hz
    assert s["tracking_error_p95_m"] <= 0.10, json.dumps(s)
    timing = s["timing"]  # samples stamped at the autopilot's time, not when they arrived
    assert timing["position_latency_p50_s"] < 0.02 and timing["setpoint_interval_p50_s"] < 0.03, json.dumps(s)
    events = (tmp_path / "run" / "events.jsonl").read_text().splitlines()
    kinds = {json.loads(line)["kind"] for line in events}
    assert {"state", "command", "setpoint", "vehicle", "run"} <= kinds


def test_circle_mission_without_wind_meets_the_thesis_anchor(tmp_path):
    proc, s = fly(tmp_path, "--no-wind")
    assert proc.returncode == 0, proc.stderr + json.dumps(s)
    assert s["outcome"] == "completed"
    assert s["tracking_error_p95_m"] <= 0.04, json.dumps(s)


def test_circle_mission_completes_against_the_ardupilot_profile(tmp_path):
    """ArduCopter semantics: nothing streams unasked, GUIDED is offboard, BRAKE is HOLD."""
    proc, s = fly(tmp_path, "--sim-profile", "ardupilot", "--seed", "5")
    assert proc.returncode == 0, proc.stderr + json.dumps(s)
    assert s["autopilot"] == "ARDUPILOT" and s["outcome"] == "completed"
    assert s["tracking_error_p95_m"] <= 0.10, json.dumps(s)
    lines = [json.loads(x) for x in (tmp_path / "run" / "events.jsonl").read_text().splitlines()]
    rates = {e["stream"] for e in lines if e.get("event") == "rate"}
    assert {"position_velocity_ned", "attitude_euler", "home", "landed_state"} <= rates


def test_invalid_mission_file_is_refused_before_connecting(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((ROOT / "app/missions/circle.yaml").read_text().replace("circle_laps_done", "laps_done"))
    proc = subprocess.run(
        [sys.executable, "-m", "app.main", "--mission", str(bad), "--connect", "udpin://0.0.0.0:1"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2
    assert "states.TRACK.transitions[4].when: unknown guard 'laps_done'" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
