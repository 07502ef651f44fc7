"""``python -m app.main`` answers bad input with one line and exit status 2, before connecting to anything."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--mission", "nope.yaml"], "no such mission file"),
        (["--mission", "circle.yaml", "--run-dir", "/proc/seapick-run"], "--run-dir /proc/seapick-run"),
        (["--mission", "circle.yaml", "--seed", "abc"], "argument --seed: invalid int value"),
        (["--mission", "circle.yaml", "--wind-mps", "nan"], "argument --wind-mps: nan is outside 0..30 m/s"),
        (["--mission", "circle.yaml", "--pilot-port", "70000"], "70000 is outside 0..65535 (UDP port)"),
        (["--mission", "circle.yaml", "--foxglove-port", "70000"], "70000 is outside 0..65535 (TCP port)"),
        (["--mission", "circle.yaml", "--sim", "--connect", "udpin://0.0.0.0:1"], "exclude each other"),
        (["--mission", "circle.yaml", "--settings", "/etc/hostname"], "top level must be a mapping"),
        ([], "the following arguments are required: --mission"),
        (["--mission", "pickup.yaml", "--sim", "--sea-state", "9"], "argument --sea-state: 9 is outside 0..5"),
        (["--mission", "pickup.yaml", "--sim", "--object", "boat"], "argument --object: invalid choice: 'boat'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args, expected):
    proc = subprocess.run(
        [sys.executable, "-m", "app.main", *args], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and expected in lines[0], proc.stderr
