"""The calibrated airframes answer the recorded setpoint script like the real firmware did (issue 10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim import airframes
from sim.flight_stack import PHYSICS_DT_S
from sim.response_replay import load, residual_rms

DATA = Path(__file__).resolve().parents[1] / "data" / "autopilot_response"


@pytest.mark.parametrize(
    ("recording", "airframe", "limits"),
    [
        # the README's models: PX4 ≤ 0.08 horizontal, ≤ 0.05 vertical; ArduCopter ≤ 0.05
        ("px4_sih_velocity_response.csv", airframes.PX4_SIH, (0.08, 0.08, 0.05)),
        ("arducopter_velocity_response.csv", airframes.ARDUCOPTER, (0.05, 0.05, 0.05)),
    ],
)
def test_replayed_script_matches_the_recording(recording, airframe, limits):
    rec = load(DATA / recording)
    rms = residual_rms(rec, airframe)
    baseline = residual_rms(rec, airframes.DEFAULT)
    print(f"{recording}: RMS residual n/e/d {rms[0]:.3f} / {rms[1]:.3f} / {rms[2]:.3f} m/s "
          f"(uncalibrated {baseline[0]:.3f} / {baseline[1]:.3f} / {baseline[2]:.3f})")  # fmt: skip
    assert all(r <= lim for r, lim in zip(rms, limits, strict=True)), rms
    assert sum(rms) < sum(baseline)  # the calibration is what makes the difference


@pytest.mark.parametrize(
    ("recording", "airframe"),
    [
        ("px4_sih_velocity_response.csv", airframes.PX4_SIH),
        ("arducopter_velocity_response.csv", airframes.ARDUCOPTER),
    ],
)
def test_the_physics_rate_barely_changes_the_answer(recording, airframe):
    """The flight stack ticks at 100 Hz: against the recording, within 2 mm/s RMS of what 200 Hz and 1 kHz give."""
    rec = load(DATA / recording)
    assert PHYSICS_DT_S == 0.01
    at_100 = residual_rms(rec, airframe)
    for dt_s in (0.005, 0.001):
        finer = residual_rms(rec, airframe, dt_s)
        print(f"{recording}: RMS residual n/e/d at 100 Hz {at_100[0]:.4f} / {at_100[1]:.4f} / {at_100[2]:.4f}, "
              f"at {1 / dt_s:.0f} Hz {finer[0]:.4f} / {finer[1]:.4f} / {finer[2]:.4f} m/s")  # fmt: skip
        assert all(abs(a - b) <= 0.002 for a, b in zip(at_100, finer, strict=True))


def test_px4_sih_leaves_a_fifth_of_a_step_after_four_seconds():
    """The slow integrator mode the README describes: on the north 1 m/s step, 20–30 % is still missing."""
    rec = load(DATA / "px4_sih_velocity_response.csv")
    from sim.response_replay import replay

    v = replay(rec, airframes.PX4_SIH)
    step = rec.segment == "north_1"
    last_s = rec.t_s[step][-1]
    tail = step & (rec.t_s > last_s - 1.0)
    missing = 1.0 - float(v[tail, 0].mean())
    print(f"north step: {missing:.2f} of the step missing in its last second (recording: 0.23)")
    assert 0.15 <= missing <= 0.35


def _drift_in_a_gust_m(params) -> float:
    """Zero velocity commanded while a 5 m/s gust sets in: how far the vehicle ends up from where it was."""
    from sim.dynamics import Dynamics
    from sim.multirotor import ControlInput
    from sim.wind import Wind, WindConfig

    dyn = Dynamics(params, Wind(WindConfig(mean_mps=5.0, gust_sigma_mps=0.0, vertical_sigma_mps=0.0)))
    dyn._p = [0.0, 0.0, -10.0]  # airborne, at rest: the gust hits at t = 0
    dyn.start_airborne((0.0, 0.0, 0.0))
    for _ in range(3000):  # 30 s
        dyn.step(0.01, ControlInput((0.0, 0.0, 0.0)))
    n, e, _ = dyn.state.pos_ned_m
    return float(np.hypot(n, e))


def test_arducopter_guided_flies_back_to_its_position_target_px4_velocity_control_does_not():
    """ArduCopter integrates velocity setpoints into a position target; PX4 offboard velocity does not."""
    ardu, px4 = _drift_in_a_gust_m(airframes.ARDUCOPTER), _drift_in_a_gust_m(airframes.PX4_SIH)
    print(f"zero velocity in a 5 m/s gust, 30 s: ArduCopter ends {ardu:.3f} m away, PX4 SIH {px4:.3f} m")
    assert ardu < 0.05
    assert px4 > 0.5
