"""Pilot takeover and an app killed mid-flight, through the real CLI against the standalone simulator."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from tests.e2e.cliutil import (
    free_udp_port,
    pilot,
    popen,
    read_jsonl,
    sim_modes,
    start_sim,
    states,
    stop,
    wait_for,
    wait_for_state,
    wall_minus_mono,
)

pytestmark = pytest.mark.e2e


def is_zero(setpoint):
    return all(v == 0.0 for v in setpoint["vel_ned_mps"])


@pytest.fixture
def sim(tmp_path):
    port, pilot_port = free_udp_port(), free_udp_port()
    proc = start_sim(tmp_path, port, pilot_port, "--seed", "3")
    yield port, pilot_port
    stop(proc)


@pytest.fixture
def tracking_app(tmp_path, sim):
    """The real CLI connected to the simulator, 3 s into TRACK; killed at the end of the test."""
    port, _ = sim
    app = popen(
        ["-m", "app.main", "--mission", "circle.yaml", "--connect", f"udpin://0.0.0.0:{port}",
         "--run-dir", str(tmp_path / "run")],
        tmp_path / "app.log",
    )  # fmt: skip
    events = tmp_path / "run" / "events.jsonl"
    try:
        assert wait_for_state(events, "TRACK", 60), (tmp_path / "app.log").read_text()
        time.sleep(3.0)
        yield app, events
    finally:
        stop(app, signal.SIGKILL)


def test_pilot_takeover_is_seen_at_once_never_overridden_and_handback_resumes(tmp_path, sim, tracking_app):
    _, pilot_port = sim
    app, events = tracking_app
    assert pilot(pilot_port, "POSCTL").returncode == 0
    switch = next(m for m in reversed(sim_modes(tmp_path)) if m["mode"] == "POSCTL")
    manual = wait_for_state(events, "MANUAL", 5)
    assert manual is not None
    latency_s = manual["t_s"] + wall_minus_mono() - switch["t_wall"]
    assert latency_s <= 1.0, f"MANUAL {latency_s:.3f} s after the switch"  # measured 21–60 ms; generous
    assert "pilot switched to POSCTL" in manual["reason"]
    # Seen through CURRENT_MODE, not the 1 Hz heartbeat (which would take up to a second).
    asked = [e for e in read_jsonl(events) if e.get("event") in ("rate", "rate_refused")]
    assert {"stream": "current_mode", "event": "rate"}.items() <= next(
        e for e in asked if e["stream"] == "current_mode"
    ).items()

    # The app must never switch the mode back: the vehicle stays in POSCTL.
    time.sleep(5.0)
    after = [m for m in sim_modes(tmp_path) if m["t_wall"] > switch["t_wall"]]
    assert after == [], after
    commands = [
        e
        for e in read_jsonl(tmp_path / "sim_state.jsonl")
        if e.get("event") == "command" and e.get("source") == "link" and e["t_wall"] > switch["t_wall"]
    ]
    assert commands == [], commands  # the app sent no command at all while the pilot had control
    # Setpoints: within the detection window some may still be the guidance's; after it only the zero standby.
    window_end = switch["t_wall"] + latency_s + 0.1
    sps = [e for e in read_jsonl(tmp_path / "sim_state.jsonl") if e.get("event") == "setpoint"]
    in_window = [e for e in sps if switch["t_wall"] < e["t_wall"] <= window_end]
    after_window = [e for e in sps if e["t_wall"] > window_end]
    print(f"{sum(not is_zero(e) for e in in_window)} non-zero of {len(in_window)} setpoints in the detection window")
    assert len(after_window) >= 10 and all(is_zero(e) for e in after_window), [
        e for e in after_window if not is_zero(e)
    ][:3]
    print(f"takeover seen by the app {latency_s * 1000:.0f} ms after the pilot's switch")
    assert states(events)[-1]["to"] == "MANUAL"

    # Handback: the pilot selects OFFBOARD (possible on PX4 thanks to the standby stream).
    assert pilot(pilot_port, "OFFBOARD").returncode == 0
    resumed = wait_for(lambda: [s for s in states(events) if s["from"] == "MANUAL"], 5)
    assert resumed and resumed[0]["to"] == "TRACK"
    time.sleep(3.0)
    assert sim_modes(tmp_path)[-1]["mode"] == "OFFBOARD"

    # Ctrl-C: ABORT → zero velocity, then HOLD; the run ends "aborted".
    t_sigint = time.time()
    app.send_signal(signal.SIGINT)
    assert app.wait(timeout=20) == 1
    assert sim_modes(tmp_path)[-1]["mode"] == "HOLD"
    sim_log = read_jsonl(tmp_path / "sim_state.jsonl")
    command = next(
        e for e in sim_log
        if e.get("event") == "command" and e.get("source") == "link" and e["t_wall"] > t_sigint
    )  # fmt: skip
    hold = next(m for m in sim_modes(tmp_path) if m["t_wall"] > t_sigint)
    assert command["command"] == "DO_SET_MODE" and hold["mode"] == "HOLD", (command, hold)
    before = [e for e in sim_log if e.get("event") == "setpoint" and t_sigint < e["t_wall"] <= hold["t_wall"]]
    assert before and is_zero(before[-1]), before[-3:]  # the last setpoint before HOLD is zero velocity
    zero_run = [e for e in before if e["t_wall"] >= hold["t_wall"] - 0.4]
    assert len(zero_run) >= 5 and all(is_zero(e) for e in zero_run), zero_run
    assert any(not is_zero(e) for e in sim_log if e.get("event") == "setpoint" and e["t_wall"] < t_sigint)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "aborted"
    assert summary["states_visited"][-3:] == ["MANUAL", "TRACK", "ABORT"]


def test_killed_app_leaves_the_vehicle_in_hold_within_1_5_s(tmp_path, tracking_app):
    app, _ = tracking_app
    assert sim_modes(tmp_path)[-1]["mode"] == "OFFBOARD"
    t_kill_wall = time.time()
    app.send_signal(signal.SIGKILL)
    app.wait(timeout=5)
    hold = wait_for(
        lambda: next((m for m in sim_modes(tmp_path) if m["t_wall"] > t_kill_wall and m["mode"] == "HOLD"), None),
        5,
    )
    assert hold is not None
    assert hold.get("reason") == "offboard_loss"
    # On the vehicle's own clock: HOLD COM_OF_LOSS_T (1 s) after the last setpoint it received.
    last = [e for e in read_jsonl(tmp_path / "sim_state.jsonl") if e.get("event") == "setpoint"][-1]
    loss_s = hold["t_s"] - last["t_s"]
    print(
        f"vehicle in HOLD {hold['t_wall'] - t_kill_wall:.3f} s after the kill, {loss_s:.3f} s after its last setpoint"
    )
    assert 1.0 <= loss_s <= 1.0 + 0.05  # the simulator steps in 5 ms substeps: within a few


def test_an_app_killed_outright_takes_its_simulator_with_it(tmp_path):
    """``--sim``: the simulator is the app's child; SIGKILL on the app (no cleanup runs) must not leave it flying
    and eating CPU (it dies with its parent: PR_SET_PDEATHSIG)."""
    app = popen(
        ["-m", "app.main", "--mission", "circle.yaml", "--sim", "--pilot-port", "0",
         "--run-dir", str(tmp_path / "run")],
        tmp_path / "app.log",
    )  # fmt: skip
    try:
        assert wait_for_state(tmp_path / "run" / "events.jsonl", "TAKEOFF", 60), (tmp_path / "app.log").read_text()
        children = subprocess.run(["pgrep", "-P", str(app.pid), "-f", "sim.autopilot"], capture_output=True, text=True)
        sim_pids = [int(p) for p in children.stdout.split()]
        assert len(sim_pids) == 1, children
        app.send_signal(signal.SIGKILL)
        app.wait(timeout=5)
        gone = wait_for(lambda: not os.path.exists(f"/proc/{sim_pids[0]}") or _zombie(sim_pids[0]), 5.0)
        assert gone, f"simulator {sim_pids[0]} still running after the app was killed"
    finally:
        stop(app, signal.SIGKILL)


def _zombie(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] == "Z"
    except OSError:
        return True
