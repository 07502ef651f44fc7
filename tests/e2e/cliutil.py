"""Helpers for end-to-end tests: run the real CLI and the real simulator as processes, read their logs.

Times: the app stamps events with its loop clock (``time.monotonic`` of its process — CLOCK_MONOTONIC,
shared by every process on the machine); the simulator's state log uses ``time.time``. ``wall_minus_mono``
converts between them.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wall_minus_mono() -> float:
    return time.time() - time.monotonic()


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            pass  # a line being written
    return out


def states(events_path: Path) -> list[dict[str, Any]]:
    return [e for e in read_jsonl(events_path) if e.get("kind") == "state"]


def wait_for(predicate, timeout_s: float, period_s: float = 0.02):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(period_s)
    return None


def wait_for_state(events_path: Path, name: str, timeout_s: float) -> dict[str, Any] | None:
    return wait_for(lambda: next((s for s in states(events_path) if s["to"] == name), None), timeout_s)


def popen(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, *args], cwd=ROOT, stdout=log.open("wb"), stderr=subprocess.STDOUT, env=env)


def start_sim(tmp: Path, port: int, pilot_port: int, *extra: str) -> subprocess.Popen[bytes]:
    proc = popen(
        ["-m", "sim.autopilot", "--udp", f"127.0.0.1:{port}", "--pilot-port", str(pilot_port),
         "--state-log", str(tmp / "sim_state.jsonl"), *extra],
        tmp / "sim.log",
    )  # fmt: skip
    return proc


def pilot(pilot_port: int, mode: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "sim.pilot", "--port", str(pilot_port), "--mode", mode, "--timeout-s", "5"],
        cwd=ROOT, capture_output=True, text=True, timeout=30,
    )  # fmt: skip


def sim_modes(tmp: Path) -> list[dict[str, Any]]:
    return [e for e in read_jsonl(tmp / "sim_state.jsonl") if e.get("event") == "mode"]


def stop(proc: subprocess.Popen[bytes], sig: int = signal.SIGTERM, timeout_s: float = 10.0) -> int:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode
