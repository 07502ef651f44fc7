"""Poses for the camera renderer: the camera from the vehicle's state and mount, the object from the waves.

Frames: NED metres; a pose's rotation takes its body axes to NED. The camera frame is OpenCV's (x right, y down,
z out of the lens); the object's axes are x along the marker image's rows, y down its columns, z into the water.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.settings import CameraSettings
from sim.sea import FloatingObject

F64 = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Pose:
    """A rigid pose in NED: position (m) and the rotation from the body's axes to NED."""

    pos_ned_m: F64
    R_ned_from_body: F64


def euler_zyx(roll_rad: float, pitch_rad: float, yaw_rad: float) -> F64:
    """R = Rz(ψ) Ry(θ) Rx(φ) (thesis eq. 4.5)."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll_rad),
        math.sin(roll_rad),
        math.cos(pitch_rad),
        math.sin(pitch_rad),
        math.cos(yaw_rad),
        math.sin(yaw_rad),
    )
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def camera_pose(
    vehicle_pos_ned_m: F64, roll_rad: float, pitch_rad: float, yaw_rad: float, camera: CameraSettings
) -> Pose:
    """The camera's pose from the vehicle's position and attitude and the camera mount (Euler + lever arm)."""
    r_ned_body = euler_zyx(roll_rad, pitch_rad, yaw_rad)
    r_body_cam = euler_zyx(
        *(math.radians(a) for a in (camera.mount_roll_deg, camera.mount_pitch_deg, camera.mount_yaw_deg))
    )
    pos = np.asarray(vehicle_pos_ned_m, float) + r_ned_body @ np.asarray(camera.lever_arm_frd_m, float)
    return Pose(pos, r_ned_body @ r_body_cam)


def object_pose(obj: FloatingObject, t_s: float, yaw_rad: float = 0.0) -> Pose:
    """The floating object's pose: at its true position, tilted with the wave slope, turned by ``yaw_rad``.

    Object axes: x along the marker image's rows (east at yaw 0), y down the marker image (south at yaw 0),
    z into the water.
    """
    pos = np.array(obj.state(t_s).pos_ned_m)
    d = 0.05  # slope by central differences over ±5 cm
    eta = np.asarray(
        obj.sea.surface_elevation_m(t_s, pos[0] + np.array([d, -d, 0.0, 0.0]), pos[1] + np.array([0.0, 0.0, d, -d]))
    )
    slope_n, slope_e = (eta[0] - eta[1]) / (2 * d), (eta[2] - eta[3]) / (2 * d)
    z = np.array([slope_n, slope_e, 1.0])
    z /= np.linalg.norm(z)
    x = np.array([-math.sin(yaw_rad), math.cos(yaw_rad), 0.0])
    x -= z * (x @ z)
    x /= np.linalg.norm(x)
    return Pose(pos, np.column_stack([x, np.cross(z, x), z]))


def camera_seeing(
    camera: CameraSettings,
    obj: Pose,
    pixel: tuple[float, float],
    range_m: float,
    roll_rad: float = 0.0,
    pitch_rad: float = 0.0,
    yaw_rad: float = 0.0,
) -> Pose | None:
    """The camera pose with the given vehicle attitude that sees ``obj``'s centre at ``pixel`` from ``range_m``.

    None when that ray would not look down at the sea (more than ~72° off the vertical).
    """
    r_body_cam = euler_zyx(
        *(math.radians(a) for a in (camera.mount_roll_deg, camera.mount_pitch_deg, camera.mount_yaw_deg))
    )
    r_ned_cam = euler_zyx(roll_rad, pitch_rad, yaw_rad) @ r_body_cam
    ray_cam = np.array([(pixel[0] - camera.cx_px) / camera.fx_px, (pixel[1] - camera.cy_px) / camera.fy_px, 1.0])
    ray_ned = r_ned_cam @ (ray_cam / np.linalg.norm(ray_cam))
    if ray_ned[2] < 0.3:
        return None
    return Pose(obj.pos_ned_m - range_m * ray_ned, r_ned_cam)
