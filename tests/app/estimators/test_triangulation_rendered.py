"""Sea-plane triangulation end to end on rendered pixels: the renderer draws the marker at its true pose, the real
ArUco detector finds it, and the triangulator (at the true vehicle state and radar height) puts it back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.estimators.rotations import euler_zyx_to_matrix, quat_from_euler_zyx
from app.estimators.triangulation import SeaPlaneTriangulator
from app.messages import VehicleStateNed
from app.sensors.camera import ExposureControls
from app.sensors.detect_marker import MarkerDetector
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions
from sim.camera_render_poses import camera_pose, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

CAM = CameraSettings(distortion=(-0.15, 0.04, 0.0008, -0.0005, 0.0), lever_arm_frd_m=(0.06, -0.04, 0.1))
MARKER = DetectorSettings()
RADAR_ARM = (-0.1, 0.05, 0.15)
T_S = 20.0


def glassy_object() -> FloatingObject:
    return FloatingObject(SeaWorld(SeaConfig(sea_state=0), seed=3), start_ne_m=(4.0, -2.0))


@pytest.mark.parametrize(
    ("height_m", "offset_ne_m", "roll_deg", "pitch_deg", "yaw_deg", "blur_px"),
    [
        (3.0, (0.4, -0.3), 4.0, -6.0, 30.0, 0.0),
        (6.0, (1.5, 1.0), -10.0, 8.0, -120.0, 2.0),
        (10.0, (-1.0, 1.5), 15.0, 12.0, 170.0, 0.0),
        (15.0, (3.0, -1.0), -5.0, -15.0, 75.0, 1.0),
    ],
)
def test_a_rendered_marker_is_triangulated_onto_its_true_position(
    height_m, offset_ne_m, roll_deg, pitch_deg, yaw_deg, blur_px
) -> None:
    obj = object_pose(glassy_object(), T_S, yaw_rad=0.6)
    truth_ned = obj.pos_ned_m
    vehicle = np.array([truth_ned[0] + offset_ne_m[0], truth_ned[1] + offset_ne_m[1], truth_ned[2] - height_m])
    roll, pitch, yaw = (math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg))
    frame = CameraRenderer(CAM, MARKER, seed=2).render(
        T_S,
        camera_pose(vehicle, roll, pitch, yaw, CAM),
        obj,
        ExposureControls(),
        Conditions(blur_px=blur_px, blur_angle_rad=0.4),
    )
    assert frame.truth.in_view

    found = MarkerDetector(MARKER, CAM).detect(frame.image, T_S)
    assert found is not None

    R = euler_zyx_to_matrix(roll, pitch, yaw)
    radar_height_m = truth_ned[2] - (vehicle[2] + (R @ np.array(RADAR_ARM))[2])  # vertical, radar to sea
    state = VehicleStateNed(T_S, tuple(vehicle), (0.0, 0.0, 0.0), quat_from_euler_zyx(roll, pitch, yaw))
    fix = SeaPlaneTriangulator.from_settings(CAM, radar_arm_frd_m=RADAR_ARM).fix_marker(
        T_S, found.corners_px, state, radar_height_m
    )
    assert fix is not None

    error = np.asarray(fix.observation.pos_ned_m[:2]) - truth_ned[:2]
    # Sub-pixel corners: the fix is within a few millimetres per metre of height …
    assert np.hypot(*error) < 0.003 * height_m
    # … and inside its own 99.9 % covariance ellipse (χ²₂ = 13.8).
    assert error @ np.linalg.solve(np.asarray(fix.observation.cov_ne_m2), error) < 13.8
    assert fix.observation.pos_ned_m[2] == pytest.approx(truth_ned[2], abs=1e-6)
