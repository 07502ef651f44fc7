"""Constant-bearing guidance reproduces thesis eqs. 2.19–2.21."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from app.offboard.guidance import ConstantBearingParams, approach_speed_mps, constant_bearing_velocity

P = ConstantBearingParams(approach_speed_max_mps=2.0, transient_distance_m=0.5)


def test_kappa_matches_eq_2_21_by_hand():
    # ‖p̃‖ = 1.2 m: κ = 2.0·1.2/sqrt(1.44 + 0.25) = 2.4/1.3 = 1.846153…
    assert approach_speed_mps(1.2, P) == pytest.approx(2.4 / 1.3, rel=1e-12)


def test_far_from_target_approach_speed_tends_to_u_max():
    assert approach_speed_mps(1000.0, P) == pytest.approx(2.0, rel=1e-6)


def test_near_target_law_is_proportional_with_gain_u_over_delta():
    assert approach_speed_mps(1e-3, P) == pytest.approx(1e-3 * 2.0 / 0.5, rel=1e-5)


def test_velocity_points_at_target_plus_target_velocity_feedforward():
    # Vehicle 3 m south and 4 m west of the target: p̃ = (-3, -4, 0), ‖p̃‖ = 5.
    v = constant_bearing_velocity((0.0, 0.0, -5.0), (3.0, 4.0, -5.0), (0.5, -0.25, 0.0), P)
    kappa = 2.0 * 5.0 / math.sqrt(25.0 + 0.25)
    assert v == pytest.approx((kappa * 3 / 5 + 0.5, kappa * 4 / 5 - 0.25, 0.0), rel=1e-12)


def test_on_target_only_the_feedforward_remains():
    assert constant_bearing_velocity((1.0, 2.0, -3.0), (1.0, 2.0, -3.0), (0.3, 0.1, 0.0), P) == (0.3, 0.1, 0.0)


@given(
    st.tuples(*[st.floats(-500, 500)] * 3),
    st.tuples(*[st.floats(-500, 500)] * 3),
)
def test_approach_component_never_exceeds_u_max(p, pt):
    v = constant_bearing_velocity(p, pt, (0.0, 0.0, 0.0), P)
    assert math.sqrt(sum(c * c for c in v)) <= 2.0 + 1e-9


def test_lead_adds_tau_times_target_acceleration_to_the_feedforward():
    lead = ConstantBearingParams(2.0, 0.5, velocity_lead_s=0.6)
    v = constant_bearing_velocity((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), lead, (0.0, -0.25, 0.0))
    assert v == pytest.approx((1.0, -0.15, 0.0))
    # Without lead the acceleration is ignored (thesis eq. 2.19).
    assert constant_bearing_velocity((0, 0, 0), (0, 0, 0), (1.0, 0, 0), P, (0, -0.25, 0)) == (1.0, 0, 0)


def test_damping_acts_on_the_horizontal_error_predicted_tau_d_ahead():
    """τ_d = 0.1 s: 0.1 m north of a still target and closing at 0.5 m/s, the error the law sees is
    0.1 − 0.1·0.5 = 0.05 m; the vertical error is left as it is; a vehicle moving with the target is not damped."""
    damped = ConstantBearingParams(2.0, 0.4, separate_vertical=True, damping_s=0.1)
    v = constant_bearing_velocity(
        (0.1, 0.0, -4.0), (0.0, 0.0, -5.0), (0.0, 0.0, 0.0), damped, vel_ned_mps=(-0.5, 0.0, 0.8)
    )
    assert v[0] == pytest.approx(-2.0 * 0.05 / math.hypot(0.05, 0.4), rel=1e-12)
    assert v[1] == 0.0 and v[2] == pytest.approx(-2.0 / math.hypot(1.0, 0.4), rel=1e-12)
    moving = constant_bearing_velocity(
        (0.1, 0.0, -5.0), (0.0, 0.0, -5.0), (0.3, -0.2, 0.0), damped, vel_ned_mps=(0.3, -0.2, 0.0)
    )
    assert moving[0] == pytest.approx(0.3 - 2.0 * 0.1 / math.hypot(0.1, 0.4), rel=1e-12)
    # Without the vehicle's velocity, or with τ_d = 0, the law is the plain one.
    plain = ConstantBearingParams(2.0, 0.4, separate_vertical=True)
    assert constant_bearing_velocity((0.1, 0.0, -5.0), (0.0, 0.0, -5.0), (0.0, 0.0, 0.0), damped) == pytest.approx(
        constant_bearing_velocity((0.1, 0.0, -5.0), (0.0, 0.0, -5.0), (0.0, 0.0, 0.0), plain, vel_ned_mps=(-0.5, 0, 0))
    )


def test_only_a_precise_target_gets_the_precise_damping():
    params = ConstantBearingParams(2.0, 0.4, precise_damping_s=0.1)
    assert params.damping_s == 0.0 and params.for_target(False).damping_s == 0.0
    assert params.for_target(True).damping_s == 0.1
    # Unset, a precise target keeps the plain τ_d, as the other precise settings fall back to theirs.
    assert ConstantBearingParams(2.0, 0.4, damping_s=0.05).for_target(True).damping_s == 0.05


# ---- integral action on the position error (issue 10) ---------------------------------------------------

from app.offboard.guidance import PositionIntegral  # noqa: E402

PI = ConstantBearingParams(2.0, 0.4, integral_gain_per_s2=3.0, integral_max_mps=0.5, integral_within_m=1.0)


def test_integral_builds_against_the_error_by_k_i_times_error_times_dt():
    i = PositionIntegral(PI)
    v = i.update((0.2, -0.1, 0.05), 0.02, saturated=False)  # 0.2 m north of the target ...
    assert v == pytest.approx((-3.0 * 0.2 * 0.02, 3.0 * 0.1 * 0.02, -3.0 * 0.05 * 0.02))  # ... pushes south
    v = i.update((0.2, -0.1, 0.05), 0.02, saturated=False)
    assert v[0] == pytest.approx(-2 * 3.0 * 0.2 * 0.02)


def test_integral_is_bounded_horizontally_by_norm_and_vertically():
    i = PositionIntegral(PI)
    for _ in range(10_000):
        v = i.update((0.6, 0.6, -0.5), 0.02, saturated=False)
    assert math.hypot(v[0], v[1]) == pytest.approx(0.5) and v[2] == pytest.approx(0.5)


def test_integral_freezes_while_saturated_far_away_or_across_a_gap_and_resets():
    i = PositionIntegral(PI)
    v0 = i.update((0.2, 0.0, 0.0), 0.02, saturated=False)
    assert i.update((0.2, 0.0, 0.0), 0.02, saturated=True) == v0  # the envelope clamped the last setpoint
    assert i.update((1.5, 0.0, 0.0), 0.02, saturated=False) == v0  # beyond integral_within_m
    assert i.update((0.2, 0.0, 0.0), 3.0, saturated=False) == v0  # a gap in the loop: no 3 s step
    i.reset()
    assert i.v_ned_mps == (0.0, 0.0, 0.0)


def test_integral_off_by_default():
    i = PositionIntegral(P)
    assert i.update((0.5, 0.5, 0.5), 0.02, saturated=False) == (0.0, 0.0, 0.0)


# ---- the horizontal and the vertical apart ----------------------------------------------------------------

P_04 = ConstantBearingParams(2.0, 0.4)
SEP = ConstantBearingParams(2.0, 0.4, separate_vertical=True)


def test_apart_a_climb_leaves_the_horizontal_hold_as_it_is():
    """0.15 m off the target and 1.5 m under it: the one 3-D law spends κ mostly on the climb (0.2 m/s north);
    apart, the horizontal law closes 0.15 m as if there were no climb, and the climb gets its own κ."""
    below = (0.0, 0.0, 1.5)  # NED: 1.5 m under the target
    target = (0.15, 0.0, 0.0)
    one = constant_bearing_velocity(below, target, (0.0, 0.0, 0.0), P_04)
    apart = constant_bearing_velocity(below, target, (0.0, 0.0, 0.0), SEP)
    level = constant_bearing_velocity((0.0, 0.0, 0.0), target, (0.0, 0.0, 0.0), P_04)
    assert one[0] == pytest.approx(approach_speed_mps(math.hypot(0.15, 1.5), P_04) * 0.15 / math.hypot(0.15, 1.5))
    assert one[0] < 0.2 < 0.7 < apart[0]
    assert apart[0] == pytest.approx(level[0]) == pytest.approx(approach_speed_mps(0.15, P_04))
    assert apart[1] == 0.0 and apart[2] == pytest.approx(-approach_speed_mps(1.5, P_04))  # up, at its own κ


@given(
    st.tuples(*[st.floats(-500, 500)] * 3),
    st.tuples(*[st.floats(-500, 500)] * 3),
)
def test_apart_each_part_is_bounded_by_u_max_and_points_at_the_target(p, pt):
    v = constant_bearing_velocity(p, pt, (0.0, 0.0, 0.0), SEP)
    assert math.hypot(v[0], v[1]) <= 2.0 + 1e-9 and abs(v[2]) <= 2.0 + 1e-9
    # each part points from the vehicle at the target (or is zero)
    assert (pt[0] - p[0]) * v[0] + (pt[1] - p[1]) * v[1] >= 0.0 and (pt[2] - p[2]) * v[2] >= 0.0


# ---- climbing at its own speed ----------------------------------------------------------------------------

ARDU = ConstantBearingParams(1.2, 0.24, separate_vertical=True)  # ArduPilot's U_a,max and Δ: 5 1/s
ARDU_CLIMB = ConstantBearingParams(1.2, 0.24, separate_vertical=True, climb_speed_max_mps=2.0)


def test_a_climb_saturates_at_the_climb_speed_with_the_same_gain_near_the_target():
    """4 m under the target (GRAB given up on the water, TRACK's height above): 1.198 m/s up at ArduPilot's 1.2 m/s
    saturation, 1.99 m/s at the climb speed; 1 cm under it, the same 5 1/s either way; the horizontal law and a
    descent are left as they were."""

    def up(params: ConstantBearingParams, under_m: float) -> float:
        return -constant_bearing_velocity((0.3, 0.0, under_m), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), params)[2]

    assert up(ARDU, 4.0) == pytest.approx(1.198, abs=1e-3)
    assert up(ARDU_CLIMB, 4.0) == pytest.approx(2.0 * 4.0 / math.hypot(4.0, 0.4))
    assert up(ARDU_CLIMB, 0.01) == pytest.approx(up(ARDU, 0.01), rel=2e-3) == pytest.approx(0.05, rel=2e-3)
    assert up(ARDU_CLIMB, -1.0) == up(ARDU, -1.0) == pytest.approx(-1.2 / math.hypot(1.0, 0.24))  # going down
    above = constant_bearing_velocity((0.3, 0.0, 4.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), ARDU_CLIMB)
    level = constant_bearing_velocity((0.3, 0.0, 4.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), ARDU)
    assert above[:2] == level[:2]


def test_the_climb_speed_is_no_brake_and_no_3d_law():
    """Under U_a,max it changes nothing (PX4's 2 m/s); the thesis's one 3-D law has no vertical law of its own."""
    px4 = ConstantBearingParams(2.0, 0.4, separate_vertical=True)
    slower = ConstantBearingParams(2.0, 0.4, separate_vertical=True, climb_speed_max_mps=1.0)
    one = ConstantBearingParams(1.2, 0.24, climb_speed_max_mps=2.0)
    for p in ((0.0, 0.0, 3.0), (0.1, -0.2, 0.05), (0.0, 0.0, -2.0)):
        assert constant_bearing_velocity(p, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), slower) == constant_bearing_velocity(
            p, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), px4
        )
        assert constant_bearing_velocity(p, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), one) == constant_bearing_velocity(
            p, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), ConstantBearingParams(1.2, 0.24)
        )
