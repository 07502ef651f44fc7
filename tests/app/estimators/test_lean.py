"""The vehicle's mean lean and the heading that lays it along the image's wider side (``app.estimators.lean``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.estimators.lean import MeanLean, camera_axis_ne
from app.estimators.rotations import euler_zyx_to_matrix
from app.messages import AttitudeEuler

ACROSS = math.radians(90.0)  # the default mount (yaw 90°): the image's 1280 px side runs along the body's right
MIN_TILT = math.radians(3.0)


@pytest.mark.parametrize(
    ("roll", "pitch", "yaw"), [(0.2, 0.0, 0.0), (0.0, -0.3, 0.0), (0.1, 0.25, 2.0), (-0.3, 0.1, -1.2)]
)
def test_the_camera_axis_is_the_body_z_axis_in_ned(roll, pitch, yaw):
    z = euler_zyx_to_matrix(roll, pitch, yaw)[:, 2]
    n, e = camera_axis_ne(AttitudeEuler(0.0, roll, pitch, yaw))
    assert (n, e) == pytest.approx((z[0], z[1]), abs=1e-12)
    assert math.hypot(n, e) == pytest.approx(math.sin(math.acos(z[2])), abs=1e-12)  # the sine of the tilt


def test_a_nose_up_vehicle_looks_ahead_and_a_right_side_down_one_to_its_left():
    n, e = camera_axis_ne(AttitudeEuler(0.0, 0.0, math.radians(10.0), 0.0))  # nose up, heading north
    assert n > 0.17 and abs(e) < 1e-12
    n, e = camera_axis_ne(AttitudeEuler(0.0, math.radians(10.0), 0.0, 0.0))  # rolled right, heading north
    assert e < -0.17 and abs(n) < 1e-12


def lean_steadily(lean: MeanLean, towards_rad: float, tilt_rad: float, yaw_rad: float, seconds: float) -> None:
    """Attitude samples at 50 Hz of a vehicle whose camera axis leans ``tilt_rad`` towards ``towards_rad`` (NED
    bearing), whatever its heading, swinging ±10° around that on a 5 s wave orbit."""
    for k in range(int(seconds * 50)):
        t_s = k / 50.0
        swing = math.radians(10.0) * math.sin(2.0 * math.pi * t_s / 5.0)
        n, e = math.sin(tilt_rad) * math.cos(towards_rad), math.sin(tilt_rad) * math.sin(towards_rad)
        n += math.sin(swing) * math.cos(towards_rad + 1.0)  # the orbit swings it across too
        e += math.sin(swing) * math.sin(towards_rad + 1.0)
        # the attitude with heading yaw_rad whose body z has that horizontal part: solve for roll and pitch
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        fwd, right = c * n + s * e, -s * n + c * e  # in the heading's frame
        roll = -math.asin(right)
        pitch = math.asin(fwd / math.cos(roll))
        lean.add(AttitudeEuler(t_s, roll, pitch, yaw_rad))


@pytest.mark.parametrize("towards_deg", [0.0, 37.0, 90.0, 200.0, -120.0])
def test_the_heading_puts_the_mean_lean_across_the_picture_whichever_way_the_wind_blows(towards_deg):
    lean = MeanLean(tau_s=5.0)
    towards = math.radians(towards_deg)
    lean_steadily(lean, towards, math.radians(15.0), yaw_rad=0.3, seconds=60.0)
    assert lean.tilt_rad() == pytest.approx(math.radians(15.0), abs=math.radians(1.5))  # the swing averages out
    yaw = lean.across_yaw_rad(ACROSS, 0.3, MIN_TILT)
    assert yaw is not None
    # at that heading the body's right (the image's wide side) points along the lean, one way or the other, give
    # or take what is left of the ±10° swing after the 5 s low-pass (±6° at a 5 s period: 1/√(1 + (ωτ)²) = 0.16)
    right = yaw + ACROSS
    assert abs(math.sin(right - towards)) < math.sin(math.radians(8.0))
    assert abs(math.remainder(yaw - 0.3, 2.0 * math.pi)) <= math.pi / 2.0  # the nearer of the two
    # flown at that heading the camera axis leans along the body's right: a roll, hardly any pitch
    lean2 = MeanLean(tau_s=5.0)
    lean_steadily(lean2, towards, math.radians(15.0), yaw_rad=yaw, seconds=60.0)
    assert lean2.across_yaw_rad(ACROSS, yaw, MIN_TILT) == pytest.approx(yaw, abs=math.radians(8.0))


def test_no_heading_in_calm_air_and_none_before_a_sample():
    lean = MeanLean()
    assert lean.across_yaw_rad(ACROSS, 0.0, MIN_TILT) is None
    lean_steadily(lean, 1.0, math.radians(1.0), yaw_rad=0.0, seconds=60.0)
    # swinging ±10° on the waves around a 1° mean: the mean is under 3°, the heading is kept
    assert lean.tilt_rad() < MIN_TILT
    assert lean.across_yaw_rad(ACROSS, 0.0, MIN_TILT) is None


def test_bad_and_old_samples_change_nothing_and_a_long_gap_starts_over():
    lean = MeanLean(tau_s=5.0)
    lean.add(AttitudeEuler(1.0, 0.0, math.radians(20.0), 0.0))
    before = lean.ne
    lean.add(AttitudeEuler(1.02, math.nan, 0.0, 0.0))
    lean.add(AttitudeEuler(0.5, math.radians(30.0), 0.0, 0.0))  # older than the last one
    assert lean.ne == before
    lean.add(AttitudeEuler(1.04, 0.0, 0.0, 0.0))  # level for one sample: a small step towards it
    assert lean.ne is not None and 0.9 * before[0] < lean.ne[0] < before[0]
    lean.add(AttitudeEuler(30.0, math.radians(10.0), 0.0, 0.0))  # after 29 s without samples: that one alone
    assert lean.ne == pytest.approx(camera_axis_ne(AttitudeEuler(30.0, math.radians(10.0), 0.0, 0.0)))
    assert np.isfinite(lean.tilt_rad())


def test_no_heading_until_the_average_spans_its_time_constant():
    lean = MeanLean(tau_s=5.0)
    for k in range(200):  # 4 s of a 20° nose-down lean
        lean.add(AttitudeEuler(k / 50.0, 0.0, math.radians(-20.0), 0.0))
    assert lean.across_yaw_rad(ACROSS, 0.0, MIN_TILT) is None  # 4 s of samples: not yet a mean
    for k in range(200, 300):
        lean.add(AttitudeEuler(k / 50.0, 0.0, math.radians(-20.0), 0.0))
    yaw = lean.across_yaw_rad(ACROSS, 0.0, MIN_TILT)
    assert yaw is not None and abs(yaw) == pytest.approx(math.pi / 2.0)  # side on to the lean
