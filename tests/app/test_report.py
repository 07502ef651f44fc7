"""``report.png`` from a run directory's logs: the app's events and the simulator's truth, on one clock."""

from __future__ import annotations

import json
import math

import numpy as np

from app.report import RunTrace, render_report


def write_run(run_dir, boot_s=1000.0, cut_last_line=True):
    run_dir.mkdir()
    events = [
        {"t_s": boot_s + 1.0, "kind": "state", "from": None, "to": "WAIT_FOR_START", "reason": "start"},
        {"t_s": boot_s + 2.0, "kind": "state", "from": "WAIT_FOR_START", "to": "TRACK", "reason": "x"},
    ]
    sim = [{"t_s": 0.0, "event": "start", "boot_monotonic_s": boot_s}]
    for k in range(200):
        t = k * 0.1
        obj = (10.0 + 0.2 * t, 5.0)
        sim.append({"t_s": t, "event": "object", "pos_ned_m": [obj[0], obj[1], 0.0], "caught": False})
        sim.append({"t_s": t, "event": "truth", "pos_ned_m": [obj[0] - 0.1, obj[1], -3.0]})
        if k % 2 == 0:
            events.append(
                {
                    "t_s": boot_s + t,
                    "kind": "pickup",
                    "state": "TRACK",
                    "vehicle_ne_m": [obj[0] - 0.1, 5.0],
                    "estimate_ne_m": [obj[0] + 0.05, 5.0],
                    "height_above_sea_m": 3.0,
                    "fix_age_s": 0.1,
                }
            )
    sim.append({"t_s": 19.0, "event": "grab", "error_m": 0.04, "caught": True, "slipped": False})
    text = "\n".join(json.dumps(r) for r in events) + "\n"
    (run_dir / "events.jsonl").write_text(text + ('{"t_s": 5, "kind": "pick' if cut_last_line else ""))
    (run_dir / "sim_state.jsonl").write_text("\n".join(json.dumps(r) for r in sim) + "\n")


def test_the_trace_puts_the_simulators_truth_on_the_apps_clock(tmp_path):
    write_run(tmp_path / "run")
    tr = RunTrace.load(tmp_path / "run")  # the cut-off last line (a crash mid-write) is skipped
    assert [s for _, s in tr.states] == ["WAIT_FOR_START", "TRACK"] and len(tr.t_s) == 100
    truth = tr.object_at(np.array(tr.t_s))
    assert truth is not None
    est = np.array(tr.estimate_ne)
    err = np.hypot(*(est - truth).T)
    assert np.allclose(err, 0.05, atol=1e-6)  # the estimate 5 cm ahead, once the clocks line up
    assert tr.grabs[0]["t_s"] == 1019.0 and math.isclose(tr.grabs[0]["error_m"], 0.04)


def test_report_png_is_drawn(tmp_path):
    write_run(tmp_path / "run")
    out = render_report(tmp_path / "run")
    png = out.read_bytes()
    assert out.name == "report.png" and png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
