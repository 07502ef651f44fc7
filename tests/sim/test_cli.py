"""The simulator and pilot CLIs as processes: start line, pilot switch, state log, clean SIGTERM exit."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.state_log import read_state_log
from tests.sim.conftest import free_udp_port

pytestmark = pytest.mark.e2e
ROOT = Path(__file__).resolve().parents[2]


def run_pilot(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "sim.pilot", *args], cwd=ROOT, capture_output=True, text=True, timeout=30
    )


def test_autopilot_cli_takes_a_pilot_switch_logs_it_and_exits_cleanly(tmp_path: Path) -> None:
    port, pilot_port = free_udp_port(), free_udp_port()
    state_log = tmp_path / "state.jsonl"
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim.autopilot", "--udp", f"127.0.0.1:{port}", "--pilot-port", str(pilot_port),
         "--seed", "3", "--state-log", str(state_log)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.strip() == f"sim.autopilot: sending to 127.0.0.1:{port}, pilot port {pilot_port}"
        status = run_pilot("--status", "--port", str(pilot_port))
        assert status.returncode == 0 and "mode HOLD" in status.stdout
        time.sleep(1.2)  # position modes need the GPS fix (1 s after boot)
        switch = run_pilot("--mode", "POSCTL", "--port", str(pilot_port), "--timeout-s", "5")
        assert switch.returncode == 0, switch.stdout + switch.stderr
        assert "POSCTL" in switch.stdout
        refused = run_pilot("--mode", "OFFBOARD", "--port", str(pilot_port), "--timeout-s", "2")
        assert refused.returncode == 1 and "DENIED" in refused.stdout
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    records = list(read_state_log(state_log))
    assert records[0]["event"] == "start" and records[-1]["event"] == "stop"
    modes = [(r["mode"], r["reason"]) for r in records if r["event"] == "mode"]
    assert modes == [("HOLD", "boot"), ("POSCTL", "pilot")]
    truths = [r for r in records if r["event"] == "truth"]
    assert truths and {"t_wall", "pos_ned_m", "vel_ned_mps", "mode", "armed"} <= truths[-1].keys()
    assert truths[-1]["mode"] == "POSCTL"


def test_autopilot_cli_stops_when_its_parent_is_gone_even_without_the_parent_death_signal(tmp_path: Path) -> None:
    """``--parent-pid``: app.main's simulator watches its parent; a parent that is gone (here: it never was — the
    test is the real parent) stops it, cleanly, within a poll or two — a simulator left behind would fly on."""
    port = free_udp_port()
    state_log = tmp_path / "state.jsonl"
    t0 = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "sim.autopilot", "--udp", f"127.0.0.1:{port}", "--pilot-port", "0",
         "--state-log", str(state_log), "--parent-pid", "1"],
        cwd=ROOT, capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    print(f"exited after {time.monotonic() - t0:.2f} s: {proc.stdout!r}")
    assert proc.returncode == 0 and "parent 1 is gone, stopping" in proc.stdout
    records = list(read_state_log(state_log))
    assert records[0]["event"] == "start" and records[-1]["event"] == "stop"
