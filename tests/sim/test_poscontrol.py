"""ArduCopter's GUIDED velocity shaping (AC_PosControl) in ``sim.poscontrol``."""

from __future__ import annotations

import math

import pytest

from sim.poscontrol import GuidedVelocityShaper, PosControlParams, sqrt_controller


def test_sqrt_controller_is_linear_near_zero_then_square_root_and_continuous():
    p, lim, dt = 2.0, 5.0, 0.0025
    lin = lim / p**2  # 1.25
    assert sqrt_controller(0.5, p, lim, dt) == pytest.approx(1.0)
    assert sqrt_controller(-0.5, p, lim, dt) == pytest.approx(-1.0)
    assert sqrt_controller(3.0, p, lim, dt) == pytest.approx(math.sqrt(2 * lim * (3.0 - lin / 2)))
    below, above = sqrt_controller(lin - 1e-9, p, lim, dt), sqrt_controller(lin + 1e-9, p, lim, dt)
    assert above == pytest.approx(below, abs=1e-6)
    assert sqrt_controller(1e-4, 1000.0, 0.0, dt) == pytest.approx(1e-4 / dt)  # never past the target in a step


def test_a_velocity_step_is_shaped_within_the_acceleration_and_jerk_limits():
    pr = PosControlParams()
    shaper = GuidedVelocityShaper(pr)
    shaper.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    dt, prev_a, max_jerk, max_acc = 0.0025, 0.0, 0.0, 0.0
    for _ in range(int(4.0 / dt)):
        shaper.step(dt, (2.0, 0.0, 0.0), tuple(shaper.pos_target))  # the vehicle on its target
        a = shaper.accel_desired[0]
        max_jerk, max_acc = max(max_jerk, abs(a - prev_a) / dt), max(max_acc, abs(a))
        prev_a = a
    assert max_acc <= pr.accel_xy_mps2 + 1e-9
    assert max_jerk <= pr.jerk_xy_mps3 + 1e-6
    assert shaper.vel_desired[0] == pytest.approx(2.0, abs=0.01)
    # the position target is the integral of the shaped velocity: behind a pure 2 m/s ramp by the shaping lag,
    assert 8.0 - 2.0 < shaper.pos_target[0] < 8.0 - 1.0  # 0.5–1 s: the jerk-limited S-curve


def test_the_position_loop_pulls_a_vehicle_that_fell_behind_back_to_the_target():
    shaper = GuidedVelocityShaper(PosControlParams())
    shaper.reset((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    v_target, _ = shaper.step(0.0025, (0.0, 0.0, 0.0), (-0.3, 0.0, 0.1))  # blown 0.3 m south, 0.1 m low
    assert v_target[0] == pytest.approx(0.3, abs=1e-3) and v_target[2] == pytest.approx(-0.1, abs=1e-3)
    v_target, _ = shaper.step(0.0025, (0.0, 0.0, 0.0), (-30.0, 0.0, 0.0))  # far off: the leash holds
    assert v_target[0] == pytest.approx(PosControlParams().leash_xy_m * PosControlParams().pos_xy_p, rel=1e-3)
