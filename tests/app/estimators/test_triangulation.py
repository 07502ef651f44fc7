"""Sea-plane triangulation: thesis rotation chain, truth from the geometric camera, lever arms, capture-time
interpolation, and a covariance that grows with tan θ, height noise and height."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.estimators.rotations import euler_zyx_to_matrix, quat_from_euler_zyx
from app.estimators.state_history import StateHistory
from app.estimators.triangulation import (
    SeaPlaneTriangulator,
    camera_height_m,
    marker_centre_normalized,
    marker_centres_normalized,
    mount_rotation_frd_cam,
)
from app.messages import AttitudeEuler, PositionVelocityNed, VehicleStateNed
from app.settings import CameraSettings
from sim.camera_geometry import GeometricCamera

CAM = CameraSettings(distortion=(-0.15, 0.04, 0.0008, -0.0005, 0.0), lever_arm_frd_m=(0.06, -0.04, 0.1))
RADAR_ARM = (-0.1, 0.05, 0.15)
TRI = SeaPlaneTriangulator.from_settings(CAM, radar_arm_frd_m=RADAR_ARM)
LEVEL_CAM = CameraSettings(lever_arm_frd_m=(0.0, 0.0, 0.0))


def state(pos=(0.0, 0.0, -10.0), roll_deg=0.0, pitch_deg=0.0, yaw_deg=0.0, t_s=0.0):
    q = quat_from_euler_zyx(math.radians(roll_deg), math.radians(pitch_deg), math.radians(yaw_deg))
    return VehicleStateNed(t_s, pos, (0.0, 0.0, 0.0), q)


def horizontal(fix):
    return np.asarray(fix.observation.pos_ned_m[:2])


def cov(fix):
    return np.asarray(fix.observation.cov_ne_m2)


# -- the rotation chain (thesis eqs. 4.4–4.6, mounting 0/0/90) ---------------------------------------------


def test_default_mounting_puts_image_up_forward_and_image_right_to_the_right():
    R = mount_rotation_frd_cam(0.0, 0.0, 90.0)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-12)  # image right → body right
    np.testing.assert_allclose(R @ [0, -1, 0], [1, 0, 0], atol=1e-12)  # image up → body forward
    np.testing.assert_allclose(R @ [0, 0, 1], [0, 0, 1], atol=1e-12)  # optical axis → body down


@settings(max_examples=40, deadline=None)
@given(yaw_deg=st.floats(-180.0, 180.0))
def test_thesis_sanity_check_right_left_top_bottom_for_any_heading(yaw_deg):
    """A marker right of the image centre is to the vehicle's right; top is ahead; left, bottom likewise."""
    tri = SeaPlaneTriangulator.from_settings(LEVEL_CAM)
    s = state(yaw_deg=yaw_deg)
    psi = math.radians(yaw_deg)
    forward, right = np.array([math.cos(psi), math.sin(psi)]), np.array([-math.sin(psi), math.cos(psi)])
    cx, cy = LEVEL_CAM.cx_px, LEVEL_CAM.cy_px
    for pixel, direction in (
        ((cx + 200, cy), right),
        ((cx - 200, cy), -right),
        ((cx, cy - 200), forward),
        ((cx, cy + 200), -forward),
    ):
        fix = tri.fix_pixel(0.0, pixel, s, 10.0)
        assert fix is not None
        offset = horizontal(fix)
        assert offset @ direction == pytest.approx(2.0)  # 200 px at f = 1000 px from 10 m
        assert abs(offset @ np.array([[0, -1], [1, 0]]) @ direction) < 1e-9


def test_the_image_centre_of_a_level_camera_is_straight_below_it():
    s = state(pos=(5.0, -3.0, -12.0), yaw_deg=37.0)
    fix = TRI.fix_pixel(0.0, (CAM.cx_px, CAM.cy_px), s, 12.0)
    R = euler_zyx_to_matrix(0.0, 0.0, math.radians(37.0))
    cam_ned = np.array([5.0, -3.0, -12.0]) + R @ np.array(CAM.lever_arm_frd_m)
    np.testing.assert_allclose(horizontal(fix), cam_ned[:2], atol=1e-9)
    assert fix.off_vertical_rad == pytest.approx(0.0, abs=1e-12)
    # The sea is where the radar says: radar's down + its height.
    radar_down = -12.0 + (R @ np.array(RADAR_ARM))[2]
    assert fix.observation.pos_ned_m[2] == pytest.approx(radar_down + 12.0)


# -- against the geometric camera's truth ----------------------------------------------------------------


def random_scene(rng, cam):
    """A vehicle 2–25 m up, attitude within ±20°, and a marker somewhere in the camera's view."""
    h = rng.uniform(2.0, 25.0)
    roll, pitch = rng.uniform(-0.35, 0.35, 2)
    yaw = rng.uniform(-math.pi, math.pi)
    R_ned_cam = euler_zyx_to_matrix(roll, pitch, yaw) @ mount_rotation_frd_cam(0, 0, 90)
    xy = rng.uniform(-0.5, 0.5, 2)
    d = R_ned_cam @ np.array([xy[0], xy[1], 1.0])
    marker = (np.array([1.0, 2.0, 0.0]) + h / d[2] * d) * np.array([1, 1, 0])
    return (1.0, 2.0, -h), roll, pitch, yaw, (float(marker[0]), float(marker[1]), 0.0)


def test_noise_free_geometric_frames_are_triangulated_to_the_truth():
    g = GeometricCamera(CAM, pixel_noise_std_px=0.0, radar_arm_frd_m=RADAR_ARM)
    rng = np.random.default_rng(11)
    n = 0
    for _ in range(60):
        pos, roll, pitch, yaw, marker = random_scene(rng, CAM)
        f = g.frame(0.0, pos, roll, pitch, yaw, marker, marker_yaw_rad=rng.uniform(-3, 3))
        if not f.visible:
            continue
        fix = TRI.fix_marker(0.0, f.corners_px, state(pos, *np.degrees((roll, pitch, yaw))), f.radar_height_m)
        assert fix is not None
        np.testing.assert_allclose(fix.observation.pos_ned_m, f.marker_centre_ned_m, atol=1e-6)
        assert fix.camera_height_m == pytest.approx(f.camera_height_m, abs=1e-9)
        n += 1
    assert n >= 40


def test_noisy_geometric_frames_land_within_their_covariance():
    g = GeometricCamera(CAM, pixel_noise_std_px=0.5, radar_arm_frd_m=RADAR_ARM, seed=2)
    rng = np.random.default_rng(12)
    nis, rel = [], []
    while len(nis) < 300:
        pos, roll, pitch, yaw, marker = random_scene(rng, CAM)
        f = g.frame(0.0, pos, roll, pitch, yaw, marker)
        if not f.visible:
            continue
        fix = TRI.fix_marker(0.0, f.corners_px, state(pos, *np.degrees((roll, pitch, yaw))), f.radar_height_m)
        e = horizontal(fix) - np.asarray(f.marker_centre_ned_m[:2])
        nis.append(e @ np.linalg.solve(cov(fix), e))
        rel.append(np.hypot(*e) / f.camera_height_m)
    assert np.mean(nis) == pytest.approx(2.0, rel=0.2)  # χ²₂: the covariance is honest, not just big
    assert np.percentile(rel, 95) < 0.01


def test_the_marker_centre_is_where_the_diagonals_cross_not_the_corner_mean():
    g = GeometricCamera(CAM, marker_size_m=2.0, pixel_noise_std_px=0.0)
    f = g.frame(0.0, (0.0, 0.0, -4.0), 0.3, -0.3, 0.0, (1.5, 1.5, 0.0))  # big, close and oblique
    xy = TRI.camera.undistort_to_normalized(f.corners_true_px)
    centre_px = TRI.camera.project(np.append(marker_centre_normalized(xy), 1.0))[0]
    mean_px = TRI.camera.project(np.append(xy.mean(axis=0), 1.0))[0]
    assert np.linalg.norm(centre_px - f.centre_true_px) < 1e-6
    assert np.linalg.norm(mean_px - f.centre_true_px) > 1.0  # eq. 4.3's mean is biased under perspective


def test_many_marker_centres_at_once_are_each_quadrilateral_s_own():
    # where the diagonals cross, row by row; a quadrilateral whose diagonals are parallel (all corners on one
    # line) falls back to its corner mean without spoiling the others
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    kite = np.array([[0.0, -1.0], [2.0, 0.0], [0.0, 3.0], [-2.0, 0.0]])  # diagonals cross at (0, 0)
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [5.0, 0.0]])
    centres = marker_centres_normalized(np.stack([0.1 * square + (0.3, -0.2), kite, line]))
    assert centres == pytest.approx(np.array([[0.3, -0.2], [0.0, 0.0], [2.0, 0.0]]), abs=1e-12)
    for quad, centre in zip((kite, line), centres[1:], strict=True):
        assert np.array_equal(marker_centre_normalized(quad), centre)


# -- lever arms ------------------------------------------------------------------------------------------


@settings(max_examples=30, deadline=None)
@given(yaw_deg=st.floats(-180, 180), arm_f=st.floats(-0.5, 0.5), arm_r=st.floats(-0.5, 0.5))
def test_a_horizontal_camera_lever_arm_moves_the_fix_by_the_rotated_arm(yaw_deg, arm_f, arm_r):
    base = SeaPlaneTriangulator.from_settings(LEVEL_CAM)
    moved = SeaPlaneTriangulator.from_settings(LEVEL_CAM.model_copy(update={"lever_arm_frd_m": (arm_f, arm_r, 0.0)}))
    s = state(yaw_deg=yaw_deg)
    shift = horizontal(moved.fix_pixel(0.0, (900, 300), s, 10.0)) - horizontal(base.fix_pixel(0.0, (900, 300), s, 10.0))
    expected = (euler_zyx_to_matrix(0, 0, math.radians(yaw_deg)) @ [arm_f, arm_r, 0.0])[:2]
    np.testing.assert_allclose(shift, expected, atol=1e-9)


def test_the_radar_height_is_carried_to_the_camera_through_the_tilted_arms():
    R = euler_zyx_to_matrix(0.0, math.radians(15.0), 0.0)  # nose up
    # Camera 0.3 m ahead of the radar: it is 0.3·sin 15° higher above the sea.
    assert camera_height_m(8.0, R, (0.3, 0.0, 0.0), (0.0, 0.0, 0.0)) == pytest.approx(
        8.0 + 0.3 * math.sin(0.2618), 1e-4
    )
    assert camera_height_m(8.0, np.eye(3), (0.0, 0.0, 0.2), (0.0, 0.0, 0.05)) == pytest.approx(7.85)


def test_ignoring_the_lever_arms_costs_what_they_are_worth():
    g = GeometricCamera(CAM, pixel_noise_std_px=0.0, radar_arm_frd_m=RADAR_ARM)
    f = g.frame(0.0, (0.0, 0.0, -3.0), 0.2, 0.1, 0.5, (0.8, 0.5, 0.0))
    s = state((0.0, 0.0, -3.0), *np.degrees((0.2, 0.1, 0.5)))
    naive = SeaPlaneTriangulator.from_settings(CAM.model_copy(update={"lever_arm_frd_m": (0.0, 0.0, 0.0)}))
    e_with = np.linalg.norm(
        horizontal(TRI.fix_marker(0.0, f.corners_px, s, f.radar_height_m)) - f.marker_centre_ned_m[:2]
    )
    e_without = np.linalg.norm(
        horizontal(naive.fix_marker(0.0, f.corners_px, s, f.radar_height_m)) - f.marker_centre_ned_m[:2]
    )
    assert e_with < 1e-9 and e_without > 0.05


# -- capture-time interpolation --------------------------------------------------------------------------


def test_the_state_interpolated_at_capture_time_beats_the_latest_sample():
    """2 m/s and 30°/s yaw, 200 ms between capture and processing: the stale pose misplaces the fix."""
    g = GeometricCamera(CAM, pixel_noise_std_px=0.5, radar_arm_frd_m=RADAR_ARM, seed=3)

    def pose(t):
        return (2.0 * t, 0.0, -10.0), math.radians(5.0) * math.sin(2 * t), 0.0, math.radians(30.0) * t

    hist = StateHistory()
    for k in range(100):  # 50 Hz up to 1.98 s
        t = k * 0.02
        (n, e, d), roll, pitch, yaw = pose(t)
        hist.add_pos_vel(PositionVelocityNed(t, (n, e, d), (2.0, 0.0, 0.0)))
        hist.add_attitude(AttitudeEuler(t + 0.005, *pose(t + 0.005)[1:]))
    errors_interp, errors_latest = [], []
    for t_c in np.linspace(1.0, 1.77, 12):
        pos, roll, pitch, yaw = pose(t_c)
        f = g.frame(t_c, pos, roll, pitch, yaw, (2.0 * t_c + 1.0, 1.0, 0.0))
        assert f.visible
        fi = TRI.fix_marker(t_c, f.corners_px, hist.at(t_c), f.radar_height_m)
        stale = hist.at(t_c + 0.2)  # what "latest" was when the frame got processed
        fl = TRI.fix_marker(t_c, f.corners_px, stale, f.radar_height_m)
        errors_interp.append(np.linalg.norm(horizontal(fi) - f.marker_centre_ned_m[:2]))
        errors_latest.append(np.linalg.norm(horizontal(fl) - f.marker_centre_ned_m[:2]))
        assert fi.observation.t_s == t_c
    assert max(errors_interp) < 0.03
    assert min(errors_latest) > 0.2  # 0.4 m of travel and 6° of yaw, partly cancelling
    assert np.median(errors_latest) > 20 * np.median(errors_interp)


# -- covariance ------------------------------------------------------------------------------------------


def test_height_noise_spreads_the_fix_along_the_ray_by_tan_theta():
    tri = SeaPlaneTriangulator.from_settings(LEVEL_CAM.model_copy(update={"pixel_noise_std_px": 0.05}))
    s = state(yaw_deg=20.0)
    radial_std = []
    tans = []
    for du in (0.0, 150.0, 300.0, 600.0):
        fix = tri.fix_pixel(0.0, (LEVEL_CAM.cx_px + du, LEVEL_CAM.cy_px), s, 10.0, height_std_m=0.2)
        bearing = (horizontal(fix) / np.linalg.norm(horizontal(fix))) if du else np.array([1.0, 0.0])
        radial_std.append(math.sqrt(bearing @ cov(fix) @ bearing))
        tans.append(math.tan(fix.off_vertical_rad))
    assert tans == pytest.approx([0.0, 0.15, 0.3, 0.6])
    assert all(a < b for a, b in itertools.pairwise(radial_std))
    # Height alone: e_h = e_v tan θ exactly.
    no_px = SeaPlaneTriangulator(tri.camera, tri.R_frd_cam, pixel_std_px=0.0)
    fix = no_px.fix_pixel(0.0, (LEVEL_CAM.cx_px + 600.0, LEVEL_CAM.cy_px), s, 10.0, height_std_m=0.2)
    assert np.sqrt(np.linalg.eigvalsh(cov(fix))[-1]) == pytest.approx(0.2 * 0.6)


@settings(max_examples=30, deadline=None)
@given(
    sigma_h=st.floats(0.0, 0.5),
    extra=st.floats(0.01, 0.5),
    u=st.floats(100, 1180),
    v=st.floats(100, 860),
    roll_deg=st.floats(-20, 20),
    height_m=st.floats(2, 25),
)
def test_more_height_noise_never_shrinks_the_covariance(sigma_h, extra, u, v, roll_deg, height_m):
    s = state(pos=(0.0, 0.0, -height_m), roll_deg=roll_deg)
    a = TRI.fix_pixel(0.0, (u, v), s, height_m, height_std_m=sigma_h)
    b = TRI.fix_pixel(0.0, (u, v), s, height_m, height_std_m=sigma_h + extra)
    assert np.linalg.eigvalsh(cov(b) - cov(a)).min() > -1e-12
    assert np.linalg.eigvalsh(cov(a)).min() > 0.0


def test_pixel_noise_covariance_scales_with_height_squared():
    s10, s20 = state(pos=(0, 0, -10.0), pitch_deg=8.0), state(pos=(0, 0, -20.0), pitch_deg=8.0)
    c10 = cov(TRI.fix_pixel(0.0, (800, 300), s10, 10.0))
    c20 = cov(TRI.fix_pixel(0.0, (800, 300), s20, 20.0))
    np.testing.assert_allclose(c20, 4 * c10, rtol=0.03)  # ~ (h_C ratio)², arms make it not exact


def test_the_covariance_matches_monte_carlo_of_pixel_height_and_attitude_noise():
    tri = SeaPlaneTriangulator.from_settings(CAM, radar_arm_frd_m=RADAR_ARM, attitude_std_rad=math.radians(0.3))
    rng = np.random.default_rng(7)
    s = state(pos=(0, 0, -15.0), roll_deg=12.0, pitch_deg=-6.0, yaw_deg=40.0)
    pixel, sigma_h = np.array([1000.0, 200.0]), 0.1
    nominal = horizontal(tri.fix_pixel(0.0, pixel, s, 15.0, sigma_h))
    samples = []
    for _ in range(3000):
        dq = quat_from_euler_zyx(*rng.normal(0.0, tri.attitude_std_rad, 3))
        q = _qmul(dq, s.q_ned_frd)  # small rotation in NED applied to the attitude
        noisy = VehicleStateNed(0.0, s.pos_ned_m, s.vel_ned_mps, q)
        f = tri.fix_pixel(0.0, pixel + rng.normal(0, tri.pixel_std_px, 2), noisy, 15.0 + rng.normal(0, sigma_h))
        samples.append(horizontal(f) - nominal)
    empirical = np.cov(np.array(samples).T)
    predicted = cov(tri.fix_pixel(0.0, pixel, s, 15.0, sigma_h))
    np.testing.assert_allclose(np.linalg.eigvalsh(empirical), np.linalg.eigvalsh(predicted), rtol=0.1)


def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


# -- no fix ----------------------------------------------------------------------------------------------


def test_rays_at_or_above_the_horizon_or_too_flat_give_no_fix():
    # Rolled right, the camera looks left; a pixel at the left edge is 30.4° further out.
    assert TRI.fix_pixel(0.0, (80, 480), state(roll_deg=45.0), 10.0).off_vertical_rad == pytest.approx(
        math.radians(75.4), abs=1e-3
    )
    assert TRI.fix_pixel(0.0, (80, 480), state(roll_deg=55.0), 10.0) is None  # θ ≈ 85° > 80°
    assert TRI.fix_pixel(0.0, (80, 480), state(roll_deg=70.0), 10.0) is None  # above the horizon
    low_cam = SeaPlaneTriangulator.from_settings(LEVEL_CAM.model_copy(update={"lever_arm_frd_m": (0.0, 0.0, 0.3)}))
    assert low_cam.fix_pixel(0.0, (640, 480), state(), 0.2) is None  # camera 0.3 m under the radar: in the sea


def test_a_nan_pixel_height_or_attitude_gives_no_fix_and_is_counted():
    tri = SeaPlaneTriangulator.from_settings(CAM, radar_arm_frd_m=RADAR_ARM)
    s = state()
    assert tri.fix_pixel(0.0, (math.nan, CAM.cy_px), s, 10.0) is None
    assert tri.fix_pixel(0.0, (CAM.cx_px, CAM.cy_px), s, math.inf) is None
    bad = VehicleStateNed(0.0, s.pos_ned_m, s.vel_ned_mps, (math.nan, 0.0, 0.0, 1.0))
    assert tri.fix_pixel(0.0, (CAM.cx_px, CAM.cy_px), bad, 10.0) is None
    assert tri.rejected["non_finite"] == 3
    assert tri.fix_pixel(0.0, (CAM.cx_px, CAM.cy_px), s, 10.0) is not None  # and the next good one works
