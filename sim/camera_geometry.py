"""The camera simulator's geometric mode: marker corners projected through the true pose, plus pixel noise.

No image is drawn: the four corners of the object's square marker are placed at its true pose (on the
sea surface, optionally tilted by the wave slope), moved into the true camera frame (vehicle position and
attitude, camera lever arm and mounting) and projected through the true intrinsics and distortion. Gaussian
pixel noise is added; the noise-free pixels and the geometry come back alongside as ground truth. Fast
enough for Monte Carlo (no rendering, no detection).

Frames as in ``app.estimators.triangulation``: NED, body FRD, camera (x right, y down, z optical axis).
The pose chain is written out here on its own (explicit Euler matrices), not borrowed from the estimator,
so a test of one against the other checks something.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.messages import MIN_DEPTH_M, CameraModel, Vec3
from app.settings import CameraSettings

FloatArray = NDArray[np.float64]


def _euler_zyx(roll_rad: float, pitch_rad: float, yaw_rad: float) -> FloatArray:
    """R_a_b = Rz(yaw) Ry(pitch) Rx(roll), written out element by element."""
    cf, sf = math.cos(roll_rad), math.sin(roll_rad)
    ct, st = math.cos(pitch_rad), math.sin(pitch_rad)
    cp, sp = math.cos(yaw_rad), math.sin(yaw_rad)
    return np.array(
        [
            [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
            [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
            [-st, ct * sf, ct * cf],
        ]
    )


def marker_corners_ned(
    centre_ned_m: Vec3, size_m: float, yaw_rad: float = 0.0, roll_rad: float = 0.0, pitch_rad: float = 0.0
) -> FloatArray:
    """The 4 corners (ArUco order TL, TR, BR, BL seen from above) of a square marker, NED, 4×3.

    At yaw 0 the marker's top edge faces north and its right edge east, so a north-up camera sees it upright.
    Roll/pitch tilt it (wave slope) about its centre.
    """
    s = size_m / 2.0
    local = np.array([[s, -s, 0.0], [s, s, 0.0], [-s, s, 0.0], [-s, -s, 0.0]])  # N, E, D in the marker frame
    R = _euler_zyx(roll_rad, pitch_rad, yaw_rad)
    return np.asarray(centre_ned_m, dtype=np.float64) + local @ R.T


def _level_corners_ned(centre_ned_m: FloatArray, size_m: float) -> FloatArray:
    """``marker_corners_ned`` of a level marker at yaw 0 (its rotation the identity): the same corners, to the bit."""
    n, e, d = centre_ned_m.tolist()
    s = size_m / 2.0
    return np.array([[n + s, e - s, d], [n + s, e + s, d], [n - s, e + s, d], [n - s, e - s, d]])


def mean_edge_px(corners_px: FloatArray) -> float:
    """The mean edge of a quadrilateral's corners (4×2 pixels, in order): the apparent size of a marker or a buoy.
    In floats, summed in numpy's order (``np.mean(np.linalg.norm(c − roll(c), axis=1))`` to the last bit)."""
    c = corners_px.tolist()
    total = 0.0
    for (u0, v0), (u1, v1) in zip(c, c[1:] + c[:1], strict=True):
        du, dv = u0 - u1, v0 - v1
        total += math.sqrt(du * du + dv * dv)
    return total / len(c)


@dataclass(frozen=True, eq=False)
class GeometricFrame:
    """One simulated detection and its ground truth."""

    t_s: float
    visible: bool  # all four corners in front of the camera and inside the image (with the margin)
    corners_px: FloatArray  # 4×2, noisy (what a detector would report)
    corners_true_px: FloatArray  # 4×2, noise-free
    centre_true_px: FloatArray  # (2,), the projection of the marker centre, noise-free
    marker_centre_ned_m: Vec3
    corners_ned_m: FloatArray  # 4×3
    camera_pos_ned_m: Vec3
    R_ned_cam: FloatArray  # 3×3, true camera attitude
    camera_height_m: float  # camera above the sea surface at the marker, m
    radar_height_m: float  # radar above the sea surface under it (what a perfect radar reads), m


class GeometricCamera:
    """The true camera (settings = truth) and the pixel noise of the simulated detector."""

    def __init__(
        self,
        camera: CameraSettings,
        marker_size_m: float = 0.30,
        pixel_noise_std_px: float = 0.5,
        radar_arm_frd_m: Vec3 = (0.0, 0.0, 0.0),
        margin_px: float = 2.0,
        seed: int | None = 0,
    ) -> None:
        self.model = CameraModel.from_settings(camera)
        mount_rad = (camera.mount_roll_deg, camera.mount_pitch_deg, camera.mount_yaw_deg)
        self.R_frd_cam = _euler_zyx(*(math.radians(a) for a in mount_rad))
        self.cam_arm_frd_m = np.asarray(camera.lever_arm_frd_m, dtype=np.float64)
        self.radar_arm_frd_m = np.asarray(radar_arm_frd_m, dtype=np.float64)
        self.marker_size_m = marker_size_m
        self.pixel_noise_std_px = pixel_noise_std_px
        self.margin_px = margin_px
        self.rng = np.random.default_rng(seed)
        if len(self.model.distortion) > 8:
            raise ValueError("the geometric camera takes up to 8 distortion coefficients (k1 k2 p1 p2 k3 k4 k5 k6)")
        k = (*self.model.distortion, 0.0, 0.0, 0.0, 0.0)
        self._k = (k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7])

    def frame(
        self,
        t_s: float,
        vehicle_pos_ned_m: Vec3,
        roll_rad: float,
        pitch_rad: float,
        yaw_rad: float,
        marker_centre_ned_m: Vec3,
        marker_yaw_rad: float = 0.0,
        marker_roll_rad: float = 0.0,
        marker_pitch_rad: float = 0.0,
        sea_down_under_radar_m: float | None = None,
        marker_size_m: float | None = None,
    ) -> GeometricFrame:
        """Project the marker at its true pose from the vehicle's true pose at ``t_s``.

        ``sea_down_under_radar_m`` is the sea surface's down coordinate below the radar (waves); by default
        the sea is flat at the marker's down coordinate. ``marker_size_m`` overrides the marker's edge (a nested
        marker in the same place).
        """
        R_ned_frd = _euler_zyx(roll_rad, pitch_rad, yaw_rad)
        R_ned_cam = R_ned_frd @ self.R_frd_cam
        body = np.asarray(vehicle_pos_ned_m, dtype=np.float64)
        cam_ned = body + R_ned_frd @ self.cam_arm_frd_m
        radar_ned = body + R_ned_frd @ self.radar_arm_frd_m
        centre = np.asarray(marker_centre_ned_m, dtype=np.float64)
        sea_down = centre[2] if sea_down_under_radar_m is None else sea_down_under_radar_m

        size_m = self.marker_size_m if marker_size_m is None else marker_size_m
        if marker_yaw_rad == 0.0 and marker_roll_rad == 0.0 and marker_pitch_rad == 0.0:
            corners_ned = _level_corners_ned(centre, size_m)
        else:
            corners_ned = marker_corners_ned(
                marker_centre_ned_m, size_m, marker_yaw_rad, marker_roll_rad, marker_pitch_rad
            )
        points_ned = np.vstack([corners_ned, centre])
        points_cam: list[list[float]] = ((points_ned - cam_ned) @ R_ned_cam).tolist()  # R_cam_ned = R_ned_camᵀ
        pixels = [self._project(p[0], p[1], p[2]) for p in points_cam]
        visible = all(p[2] > 0.0 for p in points_cam[:4]) and all(self._in_image(u, v) for u, v in pixels[:4])
        noise: list[list[float]] = self.rng.normal(0.0, self.pixel_noise_std_px, size=(4, 2)).tolist()
        corners_true = pixels[:4]
        return GeometricFrame(
            t_s=t_s,
            visible=visible,
            corners_px=np.array([[u + du, v + dv] for (u, v), (du, dv) in zip(corners_true, noise, strict=True)]),
            corners_true_px=np.array(corners_true),
            centre_true_px=np.array(pixels[4]),
            marker_centre_ned_m=(float(centre[0]), float(centre[1]), float(centre[2])),
            corners_ned_m=corners_ned,
            camera_pos_ned_m=(float(cam_ned[0]), float(cam_ned[1]), float(cam_ned[2])),
            R_ned_cam=R_ned_cam,
            camera_height_m=float(centre[2] - cam_ned[2]),
            radar_height_m=float(sea_down - radar_ned[2]),
        )

    def _project(self, x_m: float, y_m: float, z_m: float) -> tuple[float, float]:
        """``CameraModel.project`` of one point, in floats: OpenCV's ``projectPoints`` (no rotation, no translation)
        term by term in its order, so the same pixels to the last bit (tests/sim/test_camera_geometry.py); a point
        not in front of the camera gives NaN pixels, as there."""
        if not z_m > MIN_DEPTH_M:
            return math.nan, math.nan
        k0, k1, k2, k3, k4, k5, k6, k7 = self._k
        iz = 1.0 / z_m
        x, y = x_m * iz, y_m * iz
        r2 = x * x + y * y
        r4 = r2 * r2
        r6 = r4 * r2
        a1, a2, a3 = 2 * x * y, r2 + 2 * x * x, r2 + 2 * y * y
        cdist = 1 + k0 * r2 + k1 * r4 + k4 * r6
        icdist2 = 1.0 / (1 + k5 * r2 + k6 * r4 + k7 * r6)
        xd = x * cdist * icdist2 + k2 * a1 + k3 * a2
        yd = y * cdist * icdist2 + k2 * a3 + k3 * a1
        m = self.model
        return xd * m.fx_px + m.cx_px, yd * m.fy_px + m.cy_px

    def _in_image(self, u: float, v: float) -> bool:
        """``CameraModel.in_image`` of one pixel, with this camera's margin."""
        m, margin = self.model, self.margin_px
        return (
            math.isfinite(u)
            and math.isfinite(v)
            and u >= margin
            and v >= margin
            and u <= m.width_px - 1 - margin
            and v <= m.height_px - 1 - margin
        )
