"""Every command line answers bad input with one line on stderr and a non-zero exit, never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
UNWRITABLE = "/proc/seapick/out"  # cannot be created, even by root

CASES = [
    # (module and arguments, a fragment the one line must hold)
    ("app.replay radar /nonexistent.x4rec", "No such file"),
    ("app.replay radar README.md --fps -1", "argument --fps"),
    ("app.replay nope", "the first argument must be 'radar'"),
    ("app.bench nope", "unknown bench 'nope'"),
    ("app.bench radar --hover-s -1", "argument --hover-s: -1 is outside"),
    ("app.bench radar --sea-states 9", "argument --sea-states: 9: each must be in 0..5"),
    ("app.bench radar --data /nonexistent", "/nonexistent/manifest.json: No such file or directory"),
    ("app.bench perception --frames-per-scene -2", "argument --frames-per-scene: -2 is outside"),
    (f"app.bench perception --data {UNWRITABLE} --regenerate --scenes 1 --empty 0", "sim.camera_dataset failed"),
    ("app.bench triangulation --cases 0", "argument --cases: 0 is outside 1.."),
    ("app.bench triangulation --pixel-noise-px nan", "argument --pixel-noise-px: nan is outside"),
    ("app.calibrate camera /nonexistent", "/nonexistent"),
    ("app.calibrate camera . --square-m nan", "argument --square-m: nan is outside"),
    ("app.calibrate", "the following arguments are required"),
    ("sim.pilot --mode POSCTL --port 70000", "argument --port: 70000 is outside"),
    ("sim.pilot --mode POSCTL --timeout-s -1", "argument --timeout-s: -1 is outside"),
    ("sim.pilot --mode SPORT", "argument --mode: invalid choice"),
    (f"sim.radar_dataset --out {UNWRITABLE}", "/proc/seapick"),
    ("sim.radar_dataset --out /tmp/x --hover-s nan", "argument --hover-s: nan is outside"),
    ("sim.radar --height-m -3", "argument --height-m: -3 is outside"),
    ("sim.radar --profile abc", "is not t_s:height_m"),
    (f"sim.radar --link {UNWRITABLE}/radar --duration-s 0.1", "/proc/seapick"),
    (f"sim.camera_dataset --out {UNWRITABLE}", "/proc/seapick"),
    ("sim.camera_dataset --out /tmp/x --scenes -1", "argument --scenes: -1 is outside"),
    ("sim.evaluate filters --sea-state 9", "argument --sea-state: invalid choice: 9"),
    ("sim.evaluate filters --duration-s 0", "argument --duration-s: 0 is outside"),
    ("sim.autopilot --udp nonsense", "argument --udp: 'nonsense' is not HOST:PORT"),
    ("sim.autopilot --home 1,2", "argument --home: '1,2' is not LAT,LON,ALT"),
    ("sim.autopilot --param FOO", "argument --param: 'FOO' is not NAME=VALUE"),
    ("sim.autopilot --object-ne 40", "argument --object-ne: '40' is not N,E in metres"),
    ("sim.autopilot --object-ne nan,3", "argument --object-ne: 'nan,3': N and E must be finite, within ±10 km"),
    ("sim.autopilot --sea-state 7", "argument --sea-state: 7 is outside 0..5"),
    (f"sim.autopilot --pilot-port 0 --state-log {UNWRITABLE}/s.jsonl", "/proc/seapick"),
    ("sim.faults --jobs 0", "--jobs must be"),
    ("app.sensors.x4m03_record /nonexistent/tty out.x4rec --frames 1", "/nonexistent/tty: no such device"),
    ("app.sensors.x4m03_record /dev/null out.x4rec --frames 0", "argument --frames: 0 is outside"),
    ("app.sensors.x4m03_record /dev/null out.x4rec --settings {bad", "cannot record: [Errno 2] No such file"),
    ("app.main --mission circle.yaml --seed abc", "argument --seed: invalid int value"),
]


@pytest.mark.parametrize(("command", "fragment"), CASES, ids=[c for c, _ in CASES])
def test_bad_input_is_one_line_and_a_non_zero_exit(command, fragment):
    proc = subprocess.run(
        [sys.executable, "-m", *command.split()], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode != 0, (proc.stdout[-500:], proc.stderr[-500:])
    assert "Traceback" not in proc.stderr, proc.stderr[-1500:]
    assert len(lines) == 1, proc.stderr
    assert fragment in lines[0], lines[0]
