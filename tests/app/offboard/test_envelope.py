"""The safety envelope clamps speeds, the geofence and heights, and says which limit acted."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from app.offboard.envelope import EnvelopeLimits, apply_envelope

L = EnvelopeLimits(
    max_horizontal_speed_mps=5.0,
    max_climb_speed_mps=2.0,
    max_descent_speed_mps=1.0,
    geofence_radius_m=100.0,
    max_height_m=60.0,
    min_height_m=1.0,
)
HOME = (0.0, 0.0, 0.0)
AT_10M = (0.0, 0.0, -10.0)


def test_inside_the_envelope_nothing_changes():
    c = apply_envelope((1.0, -2.0, 0.5), AT_10M, HOME, L)
    assert c.vel_ned_mps == (1.0, -2.0, 0.5) and c.limits == ()


def test_horizontal_speed_is_scaled_keeping_direction():
    c = apply_envelope((6.0, 8.0, 0.0), AT_10M, HOME, L)
    assert c.vel_ned_mps == pytest.approx((3.0, 4.0, 0.0))
    assert c.limits == ("max_horizontal_speed",)


def test_climb_and_descent_are_limited_separately():
    assert apply_envelope((0, 0, -7.0), AT_10M, HOME, L).vel_ned_mps[2] == -2.0
    assert apply_envelope((0, 0, 3.0), AT_10M, HOME, L).vel_ned_mps[2] == 1.0


def test_outside_geofence_outward_motion_is_removed_inward_kept():
    outside = (120.0, 0.0, -10.0)
    c = apply_envelope((2.0, 1.0, 0.0), outside, HOME, L)
    assert c.vel_ned_mps == pytest.approx((0.0, 1.0, 0.0)) and "geofence" in c.limits
    c = apply_envelope((-2.0, 1.0, 0.0), outside, HOME, L)
    assert c.vel_ned_mps == pytest.approx((-2.0, 1.0, 0.0)) and c.limits == ()


def test_below_min_height_no_descent_unless_touchdown_allowed():
    low = (0.0, 0.0, -0.5)
    assert apply_envelope((0, 0, 0.5), low, HOME, L).vel_ned_mps[2] == 0.0
    assert apply_envelope((0, 0, 0.5), low, HOME, L, allow_below_min=True).vel_ned_mps[2] == 0.5
    assert apply_envelope((0, 0, -0.5), low, HOME, L).vel_ned_mps[2] == -0.5  # climbing is fine


def test_above_max_height_no_climb():
    c = apply_envelope((0, 0, -1.0), (0, 0, -61.0), HOME, L)
    assert c.vel_ned_mps[2] == 0.0 and c.limits == ("max_height",)


def test_non_finite_input_becomes_zero_velocity():
    c = apply_envelope((math.nan, 0.0, 0.0), AT_10M, HOME, L)
    assert c.vel_ned_mps == (0.0, 0.0, 0.0) and c.limits == ("non_finite",)


@given(st.tuples(*[st.floats(-1e3, 1e3)] * 3), st.tuples(*[st.floats(-300, 300)] * 2), st.floats(-100, 0))
def test_output_always_within_limits(v, pos_ne, down):
    c = apply_envelope(v, (pos_ne[0], pos_ne[1], down), HOME, L)
    vn, ve, vd = c.vel_ned_mps
    assert math.hypot(vn, ve) <= 5.0 + 1e-9
    assert -2.0 - 1e-12 <= vd <= 1.0 + 1e-12
