"""The radar data set, its replay through the app, and the benchmark's JSON contract (small runs, real CLIs)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.sensors.x4m03_recording import read_recording

ROOT = Path(__file__).resolve().parents[2]


def run(*args: str) -> str:
    done = subprocess.run([sys.executable, *args], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("radar_bench")
    stdout = run("-m", "app.bench", "radar", "--json", "--out", str(out), "--hover-s", "1", "--sea-states", "1,3")
    return json.loads(stdout), out


def test_bench_prints_one_json_object_with_the_figures(bench):
    result, _ = bench
    assert {"calm_p95_m", "ss3_p95_m", "frames_per_s", "methods", "goals"} <= result.keys()
    assert 0.0 < result["calm_p95_m"] < 0.2 and 0.0 < result["ss3_p95_m"] < 0.5
    assert result["frames_per_s"] > 0
    assert {"background", "clutter_map", "background_le", "clutter_map_amplitude"} <= set(result["methods"]["ss3"])
    assert result["wire_frames_per_s"] > 0
    assert result["calm_best_method"] in result["methods"]["ss1"]


def test_data_set_runs_cover_the_heights_with_truth_and_attitude_per_frame(bench):
    _, out = bench
    manifest = json.loads((out / "manifest.json").read_text())
    assert [r["sea_state"] for r in manifest["runs"]] == [1] * 9 + [3] * 9
    run0 = manifest["runs"][0]
    recording = read_recording(out / run0["recording"])
    truth = np.load(out / run0["truth"])
    assert len(recording) == run0["frames"] == truth["t_s"].size == truth["roll_rad"].size
    assert np.allclose(recording.t_s, truth["t_s"])
    assert recording.axis.bins == 91
    assert truth["height_m"][0] > 7.0  # calibration with the sea out of range
    assert truth["height_m"][-1] == pytest.approx(run0["hover_height_m"], abs=0.2)


def test_replay_cli_reports_per_frame_echo_and_altitude_close_to_the_truth(bench):
    _, out = bench
    run0 = json.loads((out / "manifest.json").read_text())["runs"][3]  # sea state 1, 2 m
    stdout = run("-m", "app.replay", "radar", str(out / run0["recording"]), "--json", "--plot", "",
                 "--calibration-frames", str(run0["calibration_frames"]))  # fmt: skip
    result = json.loads(stdout)
    truth = np.load(out / run0["truth"])["height_m"]
    assert result["method"] == "background" and result["summary"]["frames"] == truth.size
    last = result["frames"][-1]
    assert {"t_s", "counter", "range_m", "amplitude", "altitude_m", "status"} <= last.keys()
    assert last["status"] == "tracking"
    assert last["altitude_m"] == pytest.approx(truth[-1] - 0.08, abs=0.05)  # no attitude in a recording


def test_replay_cli_refuses_a_calibration_with_the_sea_in_range(bench):
    _, out = bench
    run0 = json.loads((out / "manifest.json").read_text())["runs"][3]
    done = subprocess.run(
        [sys.executable, "-m", "app.replay", "radar", str(out / run0["recording"]), "--calibration-frames", "100"],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2
    assert "calibration failed: strong echo" in done.stderr and "the sea is too close" in done.stderr
