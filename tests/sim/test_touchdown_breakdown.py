"""``sim.touchdown_breakdown``: a grab's touchdown error split into tracking and estimate error, on a run directory
written here with known numbers (the simulator's clock offset from the app's, the autopilot's estimate offset)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from sim.touchdown_breakdown import breakdown, main

BOOT_S = 100.0  # the simulator booted at app loop time 100 s
OFFSET = (0.3, -0.2)  # the autopilot's position estimate minus the truth


def vehicle_true(t_s: float) -> tuple[float, float]:
    return (10.0 + 0.5 * t_s, 20.0)


def object_true(t_s: float) -> tuple[float, float]:
    return (10.0 + 0.5 * t_s + 0.05, 20.0 - 0.1 * t_s)


def write_run(d: Path, estimate_error: tuple[float, float], grabs_s: tuple[float, ...] = (1.5,)) -> None:
    state = [{"event": "start", "t_s": 0.0, "boot_monotonic_s": BOOT_S}]
    for i in range(31):  # truth and object at 10 Hz over 3 s of simulator time
        t = i / 10.0
        state.append({"event": "truth", "t_s": t, "pos_ned_m": [*vehicle_true(t), -1.0]})
        state.append({"event": "object", "t_s": t, "pos_ned_m": [*object_true(t), 0.0]})
    state += [{"event": "grab", "t_s": g, "error_m": 0.111} for g in grabs_s]
    events = [
        {"t_s": BOOT_S + 1.0, "kind": "fix", "ne_m": [0, 0], "result": "fused"},
        {"t_s": BOOT_S + 1.2, "kind": "fix", "ne_m": [0, 0], "result": "fused"},
        {"t_s": BOOT_S + 1.25, "kind": "fix", "ne_m": [0, 0], "result": "outlier"},  # not fused: not a fix seen
    ]
    for t in (1.2, 1.4):  # pickup records (5 Hz) in the autopilot's frame
        v, o = vehicle_true(t), object_true(t)
        err = estimate_error if t == 1.4 else (0.01, 0.0)
        events.append(
            {
                "t_s": BOOT_S + t,
                "kind": "pickup",
                "vehicle_ne_m": [v[0] + OFFSET[0], v[1] + OFFSET[1]],
                "estimate_ne_m": [o[0] + OFFSET[0] + err[0], o[1] + OFFSET[1] + err[1]],
            }
        )
    d.mkdir(parents=True, exist_ok=True)
    (d / "sim_state.jsonl").write_text("".join(json.dumps(r) + "\n" for r in state))
    (d / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))


def test_the_split_at_the_last_record_before_the_grab(tmp_path: Path) -> None:
    write_run(tmp_path, estimate_error=(0.03, 0.04))
    (g,) = breakdown(tmp_path)
    assert g.t_s == pytest.approx(BOOT_S + 1.5)
    assert g.touchdown_error_m == pytest.approx(0.111)
    assert g.blind_s == pytest.approx(0.3)  # the outlier at 1.25 s was not fused
    assert g.record_lead_s == pytest.approx(0.1)
    assert g.estimate_error_m == pytest.approx(0.05, abs=1e-4)  # the offset is taken off the estimate
    # the vehicle over the estimate: vehicle − (object + error), the offsets cancel
    v, o = vehicle_true(1.4), object_true(1.4)
    want = math.hypot(v[0] - o[0] - 0.03, v[1] - o[1] - 0.04)
    assert g.tracking_error_m == pytest.approx(want, abs=1e-4)
    assert g.estimate_error_at_last_fix_m == pytest.approx(0.01, abs=1e-4)


def test_a_grab_without_a_recent_record_is_left_out(tmp_path: Path) -> None:
    write_run(tmp_path, estimate_error=(0.0, 0.0), grabs_s=(1.5, 2.5))  # the last record is 1.1 s before 2.5 s
    assert [g.t_s for g in breakdown(tmp_path)] == [pytest.approx(BOOT_S + 1.5)]


def test_cli_json_and_a_missing_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_run(tmp_path / "run", estimate_error=(0.0, 0.05))
    assert main([str(tmp_path / "run"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out[str(tmp_path / "run")][0]["estimate_error_m"] == pytest.approx(0.05, abs=1e-4)
    with pytest.raises(FileNotFoundError):
        main([str(tmp_path / "nothing")])
