"""The circle target reproduces thesis eqs. 5.3–5.4; tracking error counts only after the settle time."""

import math

import pytest

from app.messages import PositionVelocityNed
from app.missions.circle import CircleTarget, TrackingErrors


def circle(errors=None):
    return CircleTarget((10.0, -2.0, -5.0), t0_s=100.0, radius_m=4.0, v_reduction_s=4.0, settle_s=10.0,
                        errors=errors or TrackingErrors())  # fmt: skip


def test_starts_at_the_origin_moving_east_at_r_over_v_reduction():
    t = circle().target_at(100.0)
    assert t.pos_ned_m == pytest.approx((10.0, -2.0, -5.0))
    assert t.vel_ned_mps == pytest.approx((0.0, 1.0, 0.0))


def test_quarter_lap_by_hand():
    # θ = (t − t0)/4 = π/2 at t = 100 + 2π: x = x0 + 4(−1 + 0) = 6, y = y0 + 4 = 2
    c = circle()
    t = c.target_at(100.0 + 2 * math.pi)
    assert t.pos_ned_m == pytest.approx((6.0, 2.0, -5.0))
    assert t.vel_ned_mps == pytest.approx((-1.0, 0.0, 0.0))
    assert t.acc_ned_mps2 == pytest.approx((0.0, -0.25, 0.0))  # centripetal, toward the centre (6, -2)
    assert c.laps(100.0 + 2 * math.pi) == pytest.approx(0.25)


def test_velocity_is_the_derivative_of_position():
    c, t, h = circle(), 117.3, 1e-5
    a, b = c.target_at(t - h).pos_ned_m, c.target_at(t + h).pos_ned_m
    assert c.target_at(t).vel_ned_mps == pytest.approx(
        tuple((y - x) / (2 * h) for x, y in zip(a, b, strict=True)), abs=1e-6
    )


def test_errors_only_after_settle_and_against_the_target_at_the_sample_time():
    errors = TrackingErrors()
    c = circle(errors)
    c.observe(PositionVelocityNed(105.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))  # before settle: ignored
    p = c.target_at(112.0).pos_ned_m
    c.observe(PositionVelocityNed(112.0, (p[0] + 0.03, p[1] - 0.04, p[2]), (0.0, 0.0, 0.0)))
    assert errors.err_m == pytest.approx([0.05])
    s = errors.summary()
    assert s["tracking_error_p95_m"] == pytest.approx(0.05) and s["tracking_samples"] == 1
