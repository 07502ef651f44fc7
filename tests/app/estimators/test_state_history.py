"""Vehicle-state history: interpolation at a capture time, slerp, span/gap errors, bounded length."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.estimators.rotations import quat_from_euler_zyx, quat_to_euler_zyx
from app.estimators.state_history import OutsideHistoryError, StateHistory
from app.messages import AttitudeEuler, PositionVelocityNed


def pv(t, p, v=(0.0, 0.0, 0.0)):
    return PositionVelocityNed(t, p, v)


def att(t, roll_deg=0.0, pitch_deg=0.0, yaw_deg=0.0):
    return AttitudeEuler(t, math.radians(roll_deg), math.radians(pitch_deg), math.radians(yaw_deg))


def euler_deg(q):
    return np.degrees(quat_to_euler_zyx(q))


def linear_history(rate_hz=50.0, n=100, att_phase_s=0.0):
    """Constant velocity (1, −2, 0.5) m/s from (10, 20, −5) m; roll rising 10°/s; attitude at its own phase."""
    h = StateHistory(capacity=256)
    for k in range(n):
        t = k / rate_hz
        h.add_pos_vel(pv(t, (10 + t, 20 - 2 * t, -5 + 0.5 * t), (1.0, -2.0, 0.5)))
        ta = t + att_phase_s
        h.add_attitude(att(ta, roll_deg=10 * ta, yaw_deg=30.0))
    return h


@settings(max_examples=50, deadline=None)
@given(t=st.floats(0.01, 1.9))
def test_linear_motion_is_interpolated_exactly_at_any_time(t):
    s = linear_history(att_phase_s=0.007).at(t)
    np.testing.assert_allclose(s.pos_ned_m, (10 + t, 20 - 2 * t, -5 + 0.5 * t), atol=1e-9)
    np.testing.assert_allclose(s.vel_ned_mps, (1.0, -2.0, 0.5), atol=1e-12)
    np.testing.assert_allclose(euler_deg(s.q_ned_frd), (10 * t, 0.0, 30.0), atol=1e-6)
    assert s.t_s == t


def test_exactly_at_a_sample_gives_that_sample():
    h = linear_history()
    s = h.at(0.5)
    np.testing.assert_allclose(s.pos_ned_m, (10.5, 19.0, -4.75), atol=1e-12)


def test_a_time_asked_again_after_a_new_sample_is_interpolated_anew():
    # the answer for an instant is remembered until a sample arrives: one arriving later than the newest reshapes
    # the bracket a time past the old newest falls in (here: the newest position was a jump, now interpolated)
    h = StateHistory(max_gap_s=2.0)
    h.add_pos_vel(pv(0.0, (0.0, 0.0, 0.0)))
    h.add_attitude(att(0.0))
    h.add_pos_vel(pv(1.0, (1.0, 0.0, 0.0)))
    h.add_attitude(att(1.0, yaw_deg=10.0))
    assert h.at(0.5).pos_ned_m == (0.5, 0.0, 0.0)
    assert h.at(0.5) is h.at(0.5)
    with pytest.raises(OutsideHistoryError):
        h.at(1.2)
    h.add_pos_vel(pv(1.4, (5.0, 0.0, 0.0)))
    with pytest.raises(OutsideHistoryError, match="attitude"):
        h.at(1.2)
    h.add_attitude(att(1.4, yaw_deg=50.0))
    s = h.at(1.2)
    np.testing.assert_allclose(s.pos_ned_m, (3.0, 0.0, 0.0), atol=1e-12)
    np.testing.assert_allclose(euler_deg(s.q_ned_frd), (0.0, 0.0, 30.0), atol=1e-9)
    assert h.at(0.5).pos_ned_m == (0.5, 0.0, 0.0)


def test_attitude_slerp_takes_the_short_way_across_180_degrees():
    h = StateHistory()
    for t, yaw in ((0.0, 170.0), (0.1, -170.0)):
        h.add_pos_vel(pv(t, (0.0, 0.0, 0.0)))
        h.add_attitude(att(t, yaw_deg=yaw))
    yaw_mid = euler_deg(h.at(0.05).q_ned_frd)[2]
    assert abs(abs(yaw_mid) - 180.0) < 1e-6  # not 0° (the naive Euler average)
    assert euler_deg(h.at(0.025).q_ned_frd)[2] == pytest.approx(175.0, abs=1e-6)


def test_slerp_of_a_combined_rotation_stays_on_the_geodesic():
    """Half-way between identity and a 40° rotation about a tilted axis is 20° about the same axis."""
    h = StateHistory()
    for t, e in ((0.0, (0.0, 0.0, 0.0)), (0.2, (20.0, -15.0, 25.0))):
        h.add_pos_vel(pv(t, (0.0, 0.0, 0.0)))
        h.add_attitude(att(t, *e))
    q1 = np.array(quat_from_euler_zyx(*np.radians((20.0, -15.0, 25.0))))
    q_mid = np.array(h.at(0.1).q_ned_frd)
    half_angle = math.acos(q1[0])
    expected = np.concatenate([[math.cos(half_angle / 2)], q1[1:] / math.sin(half_angle) * math.sin(half_angle / 2)])
    np.testing.assert_allclose(q_mid, expected, atol=1e-12)


@pytest.mark.parametrize("t", [-0.001, 1.99, 5.0])
def test_times_outside_the_span_are_refused_with_the_span(t):
    h = linear_history(n=100)  # position 0 … 1.98 s, attitude 0 … 1.98 s
    with pytest.raises(OutsideHistoryError) as e:
        h.at(t)
    assert e.value.t_s == t and e.value.oldest_s == 0.0 and e.value.newest_s == pytest.approx(1.98)
    assert "outside the span" in str(e.value)


def test_the_stream_that_does_not_cover_the_time_is_named():
    h = StateHistory()
    for k in range(10):
        h.add_pos_vel(pv(k * 0.02, (0.0, 0.0, 0.0)))
    for k in range(5):
        h.add_attitude(att(k * 0.02))
    with pytest.raises(OutsideHistoryError) as e:
        h.at(0.15)  # position covers it, attitude stops at 0.08 s
    assert e.value.stream == "attitude"
    assert h.span_s() == (0.0, pytest.approx(0.08))


def test_a_telemetry_gap_longer_than_max_gap_is_refused():
    h = StateHistory(max_gap_s=0.2)
    for t in (0.0, 0.02, 0.5, 0.52):
        h.add_pos_vel(pv(t, (t, 0.0, 0.0)))
        h.add_attitude(att(t))
    assert h.at(0.01).pos_ned_m[0] == pytest.approx(0.01)
    with pytest.raises(OutsideHistoryError, match="gap"):
        h.at(0.3)


def test_empty_history_says_so():
    h = StateHistory()
    assert h.span_s() is None and len(h) == 0
    with pytest.raises(OutsideHistoryError):
        h.at(0.0)
    with pytest.raises(OutsideHistoryError):
        h.latest()


def test_length_is_bounded_and_the_oldest_samples_fall_out():
    h = StateHistory(capacity=16)
    for k in range(100):
        h.add_pos_vel(pv(k * 0.1, (k * 0.1, 0.0, 0.0)))
        h.add_attitude(att(k * 0.1))
    assert len(h) == 16
    assert h.span_s() == (pytest.approx(8.4), pytest.approx(9.9))
    with pytest.raises(OutsideHistoryError):
        h.at(8.3)
    assert h.at(9.05).pos_ned_m[0] == pytest.approx(9.05)


@settings(max_examples=30, deadline=None)
@given(capacity=st.integers(2, 40), n=st.integers(1, 300), f=st.floats(0.0, 1.0))
def test_ring_wraparound_keeps_the_newest_window_in_order(capacity, n, f):
    h = StateHistory(capacity=capacity, max_gap_s=2.0)
    for k in range(n):
        h.add_pos_vel(pv(float(k), (float(k), 0.0, 0.0)))
        h.add_attitude(att(float(k)))
    lo, hi = h.span_s() or (None, None)
    assert lo == max(0, n - capacity) and hi == n - 1
    t = lo + f * (hi - lo)
    assert h.at(t).pos_ned_m[0] == pytest.approx(t)


def test_old_or_repeated_samples_are_dropped_and_counted():
    h = StateHistory()
    assert h.add_pos_vel(pv(1.0, (1.0, 0.0, 0.0)))
    assert not h.add_pos_vel(pv(1.0, (9.0, 0.0, 0.0)))
    assert not h.add_pos_vel(pv(0.5, (9.0, 0.0, 0.0)))
    assert h.add_attitude(att(1.0))
    assert not h.add_attitude(att(0.9))
    assert h.dropped_out_of_order == 3
    assert h.at(1.0).pos_ned_m == (1.0, 0.0, 0.0)


def test_latest_is_the_newest_sample_of_each_stream_unchanged():
    h = linear_history(n=10, att_phase_s=0.005)
    s = h.latest()
    assert s.t_s == pytest.approx(0.185)
    np.testing.assert_allclose(s.pos_ned_m, (10.18, 19.64, -4.91), atol=1e-12)
    np.testing.assert_allclose(euler_deg(s.q_ned_frd), (1.85, 0.0, 30.0), atol=1e-9)
