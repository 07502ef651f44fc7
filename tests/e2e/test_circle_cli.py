"""The circle mission end to end: the real CLI, real MAVSDK, real UDP, the simulated PX4 autopilot.

These run in real time (about a minute and a half each for a whole mission). The three flights are started
together (``flights``): each keeps ~0.28 of one core busy (app and simulator: 26.6 s of CPU in a 96 s
flight), so on two cores together they take the time of one — and fly under the others' load.
"""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.e2e.cliutil import ROOT, stop

pytestmark = pytest.mark.e2e

FLIGHTS = {
    "default_wind": ("--seed", "7"),
    "no_wind": ("--no-wind",),
    "ardupilot": ("--sim-profile", "ardupilot", "--seed", "5"),
}
FLIGHT_TIMEOUT_S = 400.0


@dataclass
class Flight:
    returncode: int
    stderr: str
    summary: dict
    run_dir: Path


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Callable[[str], Flight]]:
    """Every circle flight of ``FLIGHTS`` started at once; ``flights(name)`` waits for that one's end."""
    procs: dict[str, tuple[subprocess.Popen[bytes], Path]] = {}
    logs = contextlib.ExitStack()
    for name, extra in FLIGHTS.items():
        d = tmp_path_factory.mktemp(f"circle_{name}")
        out, err = logs.enter_context((d / "app.out").open("wb")), logs.enter_context((d / "app.err").open("wb"))
        procs[name] = (
            subprocess.Popen(
                [sys.executable, "-m", "app.main", "--mission", "circle.yaml", "--sim", "--run-dir", str(d / "run"),
                 "--pilot-port", "0", *extra],
                cwd=ROOT, stdout=out, stderr=err,
            ),
            d,
        )  # fmt: skip

    def result(name: str) -> Flight:
        proc, d = procs[name]
        code = proc.wait(timeout=FLIGHT_TIMEOUT_S)
        summary = json.loads((d / "run" / "summary.json").read_text())
        timing = summary.get("timing", {})
        print(name, summary.get("tracking_error_p95_m"), timing.get("setpoint_interval_p99_s"))  # beside the others
        return Flight(code, (d / "app.err").read_text(), summary, d / "run")

    try:
        yield result
    finally:
        for proc, _ in procs.values():
            stop(proc, signal.SIGKILL)
        logs.close()


def test_circle_mission_completes_with_default_wind(flights):
    f = flights("default_wind")
    s = f.summary
    assert f.returncode == 0, f.stderr + json.dumps(s)
    assert s["outcome"] == "completed"
    assert s["states_visited"] == ["PREFLIGHT", "TAKEOFF", "TRACK", "LAND", "DONE"]
    assert s["autopilot"] == "PX4"
    assert s["tracking_samples"] > 1000  # 65 s after settle at ≥ 20 Hz
    assert s["tracking_error_p95_m"] <= 0.10, json.dumps(s)
    timing = s["timing"]  # samples stamped at the autopilot's time, not when they arrived
    assert timing["position_latency_p50_s"] < 0.02 and timing["setpoint_interval_p50_s"] < 0.03, json.dumps(s)
    events = (f.run_dir / "events.jsonl").read_text().splitlines()
    kinds = {json.loads(line)["kind"] for line in events}
    assert {"state", "command", "setpoint", "vehicle", "run"} <= kinds


def test_circle_mission_without_wind_meets_the_thesis_anchor(flights):
    f = flights("no_wind")
    assert f.returncode == 0, f.stderr + json.dumps(f.summary)
    assert f.summary["outcome"] == "completed"
    assert f.summary["tracking_error_p95_m"] <= 0.04, json.dumps(f.summary)


def test_circle_mission_completes_against_the_ardupilot_profile(flights):
    """ArduCopter semantics: nothing streams unasked, GUIDED is offboard, BRAKE is HOLD."""
    f = flights("ardupilot")
    s = f.summary
    assert f.returncode == 0, f.stderr + json.dumps(s)
    assert s["autopilot"] == "ARDUPILOT" and s["outcome"] == "completed"
    assert s["tracking_error_p95_m"] <= 0.10, json.dumps(s)
    lines = [json.loads(x) for x in (f.run_dir / "events.jsonl").read_text().splitlines()]
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
