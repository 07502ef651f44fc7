"""Triangulation on the sea plane: one camera ray meets the flat sea at the radar's height (thesis §3.2, §4.2.3).

Frames: camera ``_cam`` (OpenCV: x right in the image, y down, z along the optical axis), body ``_frd``
(forward, right, down), local ``_ned``. ``R_a_b`` rotates b-vectors into a.

    R_C^N = R_B^N · R_C^B                                      (eq. 4.4; R_C^B from the mounting Euler angles)
    d^N   = R_C^N · [x, y, 1]ᵀ, (x, y) the *undistorted* normalised pixel   (eqs. 4.7–4.9)
    P^N   = h_C / d_z · d^N                                    (eq. 4.10, relative to the camera)
    P_EF  = p_body + R_B^N · a_cam + P^N                       (eq. 4.11 plus the lever arm it neglected)

``h_C`` is the camera's height above the sea. The radar measures ``h_R``, its own height above the water
under it (tilt already corrected); on a flat sea the camera sits ``(R_B^N (a_cam − a_radar))_down`` lower:

    h_C = h_R − [R_B^N (a_cam − a_radar)]_z

Horizontal covariance (2×2, NE), first order in each independent error:

    Σ = J_xy Σ_xy J_xyᵀ + σ_h² g gᵀ + σ_att² J_att J_attᵀ,   g = d_h / d_z  (|g| = tan θ: thesis e_h = e_v tan θ)

``Σ_xy`` is the pixel noise σ_px carried into normalised image coordinates (through the undistortion and,
for a marker, the diagonal intersection); ``J_xy`` is ∂P_h/∂(x, y) and ``J_att`` ∂P_h/∂(small rotation of
the ray), both scaled by ``h_C``. σ_h is the height error (radar noise and, if the caller adds it, the wave height).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.estimators.rotations import euler_zyx_to_matrix, quat_to_matrix, skew
from app.messages import CameraModel, TargetObservation, Vec3, VehicleStateNed
from app.settings import CameraSettings

FloatArray = NDArray[np.float64]

DEFAULT_MAX_OFF_VERTICAL_RAD = math.radians(80.0)  # flatter rays: e_h = e_v tan θ explodes; no fix
MARKER_CORNERS = 4


def mount_rotation_frd_cam(roll_deg: float, pitch_deg: float, yaw_deg: float) -> FloatArray:
    """R_C^B from the camera's mounting Euler angles (thesis: 0, 0, 90 → image up = body forward)."""
    return euler_zyx_to_matrix(math.radians(roll_deg), math.radians(pitch_deg), math.radians(yaw_deg))


def rotation_ned_cam(q_ned_frd: ArrayLike, R_frd_cam: FloatArray) -> FloatArray:
    """Eq. 4.4: R_C^N = R_B^N R_C^B."""
    return quat_to_matrix(q_ned_frd) @ R_frd_cam


def camera_height_m(radar_height_m: float, R_ned_frd: FloatArray, cam_arm_frd_m: Vec3, radar_arm_frd_m: Vec3) -> float:
    """The camera's height above a flat sea from the radar's: h_C = h_R − [R_B^N (a_cam − a_radar)]_z."""
    arm_ned = R_ned_frd @ (np.asarray(cam_arm_frd_m) - np.asarray(radar_arm_frd_m))
    return float(radar_height_m - arm_ned[2])


def marker_centre_normalized(corners_xy: FloatArray) -> FloatArray:
    """The image of a flat square's centre: where its diagonals cross (projective, exact for any view).

    ``corners_xy`` are the 4 undistorted normalised corners in order (ArUco: TL, TR, BR, BL).
    """
    return marker_centres_normalized(np.asarray(corners_xy, dtype=np.float64).reshape(1, MARKER_CORNERS, 2))[0]


def marker_centres_normalized(corners_xy: FloatArray) -> FloatArray:
    """``marker_centre_normalized`` of N quadrilaterals at once: N×4×2 corners → N×2 centres."""
    c = np.asarray(corners_xy, dtype=np.float64)
    ax, ay, bx, by = c[:, 0, 0], c[:, 0, 1], c[:, 1, 0], c[:, 1, 1]
    cx, cy, dx, dy = c[:, 2, 0], c[:, 2, 1], c[:, 3, 0], c[:, 3, 1]
    # lines through the diagonals, l = p × q in homogeneous coordinates (p = (x, y, 1)); centre = l1 × l2
    l1 = (ay - cy, cx - ax, ax * cy - ay * cx)
    l2 = (by - dy, dx - bx, bx * dy - by * dx)
    w = l1[0] * l2[1] - l1[1] * l2[0]
    degenerate = np.abs(w) < 1e-12
    safe_w = np.where(degenerate, 1.0, w)
    out = np.column_stack(((l1[1] * l2[2] - l1[2] * l2[1]) / safe_w, (l1[2] * l2[0] - l1[0] * l2[2]) / safe_w))
    if degenerate.any():  # degenerate quadrilateral: fall back to the corner mean (eq. 4.3)
        out[degenerate] = c[degenerate].mean(axis=1)
    return out


# the marker centre's pixel-noise Jacobian: each of the 8 corner coordinates moved by ±0.5 px in turn (16 probes)
_CORNER_PROBE_STEP_PX = 0.5
_CORNER_PROBES_PX = np.zeros((4 * MARKER_CORNERS, MARKER_CORNERS, 2))
for _k in range(2 * MARKER_CORNERS):
    _CORNER_PROBES_PX[2 * _k, _k // 2, _k % 2] = _CORNER_PROBE_STEP_PX
    _CORNER_PROBES_PX[2 * _k + 1, _k // 2, _k % 2] = -_CORNER_PROBE_STEP_PX
_CORNER_PROBES_PX.flags.writeable = False


@dataclass(frozen=True, slots=True)
class SeaPlaneFix:
    """A triangulated fix and how it was made."""

    observation: TargetObservation
    camera_height_m: float  # h_C, m
    off_vertical_rad: float  # θ of the ray from the vertical, rad
    ray_ned: Vec3  # unit ray from the camera to the object, NED


@dataclass(frozen=True, eq=False)  # holds an array: compare by identity
class SeaPlaneTriangulator:
    """Pixel(s) + vehicle state at capture time + radar height → NED fix with horizontal covariance."""

    camera: CameraModel
    R_frd_cam: FloatArray = field(repr=False)
    cam_arm_frd_m: Vec3 = (0.0, 0.0, 0.0)
    radar_arm_frd_m: Vec3 = (0.0, 0.0, 0.0)
    pixel_std_px: float = 0.5
    attitude_std_rad: float = 0.0
    max_off_vertical_rad: float = DEFAULT_MAX_OFF_VERTICAL_RAD
    rejected: dict[str, int] = field(default_factory=lambda: {"non_finite": 0})  # fixes refused, by reason

    @classmethod
    def from_settings(
        cls,
        camera: CameraSettings,
        radar_arm_frd_m: Vec3 = (0.0, 0.0, 0.0),
        attitude_std_rad: float = 0.0,
        max_off_vertical_rad: float = DEFAULT_MAX_OFF_VERTICAL_RAD,
    ) -> SeaPlaneTriangulator:
        """Intrinsics, mounting, camera lever arm and pixel noise from ``camera``; the radar's arm given."""
        return cls(
            camera=CameraModel.from_settings(camera),
            R_frd_cam=mount_rotation_frd_cam(camera.mount_roll_deg, camera.mount_pitch_deg, camera.mount_yaw_deg),
            cam_arm_frd_m=camera.lever_arm_frd_m,
            radar_arm_frd_m=radar_arm_frd_m,
            pixel_std_px=camera.pixel_noise_std_px,
            attitude_std_rad=attitude_std_rad,
            max_off_vertical_rad=max_off_vertical_rad,
        )

    def fix_pixel(
        self,
        t_s: float,
        pixel_uv_px: ArrayLike,
        state: VehicleStateNed,
        radar_height_m: float,
        height_std_m: float = 0.0,
    ) -> SeaPlaneFix | None:
        """Fix from one raw (distorted) pixel; None when the ray misses the sea (above the horizon or flatter
        than ``max_off_vertical_rad``) or the camera is not above the sea."""
        px = np.asarray(pixel_uv_px, dtype=np.float64).reshape(2)
        xy = self.camera.undistort_to_normalized(px)[0]
        J = self._d_xy_d_px(px)
        return self._fix(t_s, xy, self.pixel_std_px**2 * (J @ J.T), state, radar_height_m, height_std_m)

    def fix_marker(
        self,
        t_s: float,
        corners_px: ArrayLike,
        state: VehicleStateNed,
        radar_height_m: float,
        height_std_m: float = 0.0,
    ) -> SeaPlaneFix | None:
        """Fix of a flat square marker's centre from its 4 raw corner pixels (ArUco order).

        The centre is where the undistorted diagonals cross (exact under perspective, unlike the corner
        mean of eq. 4.3). Each corner's pixel noise is carried through that construction (about σ_px/√2
        per axis for a square seen head-on).
        """
        corners = np.asarray(corners_px, dtype=np.float64).reshape(MARKER_CORNERS, 2)
        # the corners and, for ∂centre/∂(8 corner coordinates) by central differences, their probes: one
        # undistortion call
        probes = np.concatenate((corners[None], corners + _CORNER_PROBES_PX))
        xy_all = self.camera.undistort_to_normalized(probes.reshape(-1, 2)).reshape(-1, MARKER_CORNERS, 2)
        xy = marker_centre_normalized(xy_all[0])
        centres = marker_centres_normalized(xy_all[1:])
        J = ((centres[0::2] - centres[1::2]) / (2 * _CORNER_PROBE_STEP_PX)).T  # 2×8
        return self._fix(t_s, xy, self.pixel_std_px**2 * (J @ J.T), state, radar_height_m, height_std_m)

    # -- the equations ----------------------------------------------------------------------------

    def _d_xy_d_px(self, px: FloatArray) -> FloatArray:
        """∂(x, y)/∂(u, v) of the undistortion at ``px`` (central differences, ±0.5 px)."""
        step = 0.5
        probes = px + np.array([[step, 0.0], [-step, 0.0], [0.0, step], [0.0, -step]])
        xy = self.camera.undistort_to_normalized(probes)
        return np.column_stack([(xy[0] - xy[1]) / (2 * step), (xy[2] - xy[3]) / (2 * step)])

    def _fix(
        self,
        t_s: float,
        xy: FloatArray,
        cov_xy: FloatArray,
        state: VehicleStateNed,
        radar_height_m: float,
        height_std_m: float,
    ) -> SeaPlaneFix | None:
        inputs = (*xy, *state.q_ned_frd, *state.pos_ned_m, radar_height_m, height_std_m)
        if not all(map(math.isfinite, inputs)):
            self.rejected["non_finite"] += 1
            return None  # a NaN pixel, attitude, position or height gives no fix (and poisons no filter)
        R_ned_frd = quat_to_matrix(state.q_ned_frd)
        R_ned_cam = R_ned_frd @ self.R_frd_cam  # eq. 4.4
        d = R_ned_cam @ np.array([xy[0], xy[1], 1.0])  # eq. 4.9
        if d[2] <= 0.0:
            return None  # at or above the horizon
        g = d[:2] / d[2]  # horizontal metres per metre of height; |g| = tan θ
        theta = math.atan(float(np.hypot(g[0], g[1])))
        if theta > self.max_off_vertical_rad:
            return None
        h_c = camera_height_m(radar_height_m, R_ned_frd, self.cam_arm_frd_m, self.radar_arm_frd_m)
        if h_c <= 0.0:
            return None
        rel_ned = h_c / d[2] * d  # eq. 4.10
        cam_ned = np.asarray(state.pos_ned_m) + R_ned_frd @ np.asarray(self.cam_arm_frd_m)
        pos_ned = cam_ned + rel_ned  # eq. 4.11 with the camera's lever arm

        # First-order covariance: ∂(d_h/d_z)/∂d = [I₂ | −g] / d_z.
        A = np.hstack([np.eye(2), -g.reshape(2, 1)]) / d[2]
        J_xy = h_c * A @ R_ned_cam[:, :2]
        J_att = h_c * A @ (-skew(d))  # d' = d + δ × d for a small rotation δ (NED)
        cov = (
            J_xy @ cov_xy @ J_xy.T  # pixel noise, through the undistortion
            + height_std_m**2 * np.outer(g, g)  # e_h = e_v tan θ, along the ray's bearing
            + self.attitude_std_rad**2 * (J_att @ J_att.T)
        )
        cov = 0.5 * (cov + cov.T)
        obs = TargetObservation(
            t_s,
            (float(pos_ned[0]), float(pos_ned[1]), float(pos_ned[2])),
            ((float(cov[0, 0]), float(cov[0, 1])), (float(cov[1, 0]), float(cov[1, 1]))),
        )
        ray = d / np.linalg.norm(d)
        return SeaPlaneFix(obs, h_c, theta, (float(ray[0]), float(ray[1]), float(ray[2])))
