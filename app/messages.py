"""Frozen messages and value types that travel between the parts of the app.

Every message carries ``t_s``: the loop-clock time it was *measured* (for telemetry: when the autopilot took
the sample, or when it was received — never when it was read), not the time it was used. Vectors are
``(north, east, down)`` tuples in metres or metres per second, as their names say (``_ned_m``, ``_ned_mps``).

The sensors produce these and the estimators consume them, so they live here rather than in either: data
flows one way, from ``app.sensors`` to ``app.estimators``, and neither imports the other.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from app.settings import CameraSettings

Vec3 = tuple[float, float, float]
FloatArray = NDArray[np.float64]
T = TypeVar("T")

# Points closer to the image plane than this (along z_cam) cannot be projected, m.
MIN_DEPTH_M = 1e-9


class FlightMode(StrEnum):
    """Flight modes as MAVSDK reports them (ArduPilot GUIDED reads as OFFBOARD, BRAKE/LOITER as HOLD)."""

    UNKNOWN = "UNKNOWN"
    READY = "READY"
    TAKEOFF = "TAKEOFF"
    HOLD = "HOLD"
    MISSION = "MISSION"
    RETURN_TO_LAUNCH = "RETURN_TO_LAUNCH"
    LAND = "LAND"
    OFFBOARD = "OFFBOARD"
    FOLLOW_ME = "FOLLOW_ME"
    MANUAL = "MANUAL"
    ALTCTL = "ALTCTL"
    POSCTL = "POSCTL"
    ACRO = "ACRO"
    STABILIZED = "STABILIZED"
    RATTITUDE = "RATTITUDE"


# Modes only an RC pilot selects: seeing one of them means a human has the sticks.
PILOT_MODES = frozenset(
    {
        FlightMode.MANUAL,
        FlightMode.ALTCTL,
        FlightMode.POSCTL,
        FlightMode.ACRO,
        FlightMode.STABILIZED,
        FlightMode.RATTITUDE,
    }
)


class LandedState(StrEnum):
    UNKNOWN = "UNKNOWN"
    ON_GROUND = "ON_GROUND"
    IN_AIR = "IN_AIR"
    TAKING_OFF = "TAKING_OFF"
    LANDING = "LANDING"


class Autopilot(StrEnum):
    PX4 = "PX4"
    ARDUPILOT = "ARDUPILOT"
    UNKNOWN = "UNKNOWN"


@dataclass(frozen=True, slots=True)
class PositionVelocityNed:
    """Local position and velocity of the vehicle (autopilot's local NED frame)."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3


@dataclass(frozen=True, slots=True)
class AttitudeEuler:
    t_s: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float


@dataclass(frozen=True, slots=True)
class Stamped(Generic[T]):
    """A value with the loop time it was received."""

    t_s: float
    value: T


@dataclass(frozen=True, slots=True)
class BatteryLevel:
    """The autopilot's battery report: voltage and remaining charge (``None`` when it does not say)."""

    voltage_v: float | None
    remaining_frac: float | None


@dataclass(frozen=True, slots=True)
class TelemetrySnapshot:
    """The latest of every telemetry stream, each stamped; ``None`` until the first sample arrived.

    ``heartbeat_t_s``: when the autopilot's last HEARTBEAT was received (the link is alive).
    """

    pos_vel: PositionVelocityNed | None = None
    attitude: AttitudeEuler | None = None
    flight_mode: Stamped[FlightMode] | None = None
    armed: Stamped[bool] | None = None
    landed_state: Stamped[LandedState] | None = None
    home_ned_m: Vec3 | None = None
    heartbeat_t_s: float | None = None
    battery: Stamped[BatteryLevel] | None = None

    def mode(self) -> FlightMode:
        return self.flight_mode.value if self.flight_mode else FlightMode.UNKNOWN

    def is_armed(self) -> bool:
        return bool(self.armed and self.armed.value)

    def height_above_home_m(self) -> float | None:
        """Height above home (positive up), or ``None`` while position or home are unknown."""
        if self.pos_vel is None:
            return None
        home_down_m = self.home_ned_m[2] if self.home_ned_m else 0.0
        return home_down_m - self.pos_vel.pos_ned_m[2]


@dataclass(frozen=True, slots=True)
class VelocitySetpointNed:
    """What the setpoint loop sent (or decided to send) to the autopilot."""

    t_s: float
    vel_ned_mps: Vec3
    yaw_rad: float


@dataclass(frozen=True, slots=True)
class TargetState:
    """Where the target is (NED, metres) and how it moves, valid at ``t_s``; ``yaw_rad`` the heading to fly
    there (None: the loop keeps the one it has)."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3 = (0.0, 0.0, 0.0)
    yaw_rad: float | None = None
    precise: bool = False  # follow it as tightly as the autopilot allows (``guidance``'s precise Δ), e.g. landing on it

    def predict(self, t_s: float) -> TargetState:
        """Constant-velocity extrapolation to ``t_s`` (acceleration kept, not integrated)."""
        dt_s = t_s - self.t_s
        p = tuple(p + v * dt_s for p, v in zip(self.pos_ned_m, self.vel_ned_mps, strict=True))
        return TargetState(t_s, (p[0], p[1], p[2]), self.vel_ned_mps, self.acc_ned_mps2, self.yaw_rad, self.precise)


def norm(v: Vec3) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@dataclass(frozen=True, slots=True)
class TargetObservation:
    """One fix of the object on the sea plane, at the camera frame's capture time ``t_s``.

    ``cov_ne_m2`` is the horizontal covariance ((nn, ne), (en, ee)) the triangulation assigns to it.
    """

    t_s: float
    pos_ned_m: Vec3
    cov_ne_m2: tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True, slots=True)
class TargetEstimate:
    """A filter's estimate of the object at ``t_s`` (horizontal; down copied from the last fix)."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3
    cov_ne_m2: tuple[tuple[float, float], tuple[float, float]]

    def as_target(self) -> TargetState:
        return TargetState(self.t_s, self.pos_ned_m, self.vel_ned_mps, self.acc_ned_mps2)


@dataclass(frozen=True, slots=True)
class VehicleStateNed:
    """Vehicle position, velocity and attitude valid at ``t_s`` (e.g. interpolated from the state history).

    ``q_ned_frd`` is the unit quaternion (w, x, y, z) that rotates body (forward, right, down) vectors into NED.
    """

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    q_ned_frd: tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class PixelDetection:
    """The object found in one camera frame, in *raw* (distorted) pixels, at the frame's capture time ``t_s``.

    ``corners_px`` are a marker's four corners in ArUco order (top-left, top-right, bottom-right, bottom-left of
    the marker image; empty for a buoy) and ``center_px`` their mean (thesis eq. 4.3) or the buoy circle's
    centre. Undistortion happens later, on these points only (``CameraModel.undistort_to_rays``).
    """

    t_s: float
    center_px: tuple[float, float]
    corners_px: tuple[tuple[float, float], ...]
    size_px: float  # marker: mean edge length; buoy: diameter, px
    size_m: float  # the physical edge length / diameter of what was seen, m
    marker_id: int  # the marker's ID (a nested one near touchdown); -1 for a buoy
    tracked: bool  # found in the tracking window (False: by a full-frame search)


@dataclass(frozen=True, slots=True)
class RangeAxis:
    """Ranges of a radar frame's bins: ``r[k] = start_m + k·bin_m`` for k in 0..bins−1."""

    start_m: float
    bin_m: float
    bins: int

    @property
    def end_m(self) -> float:
        return self.start_m + (self.bins - 1) * self.bin_m

    def ranges_m(self) -> np.ndarray:
        return self.start_m + self.bin_m * np.arange(self.bins)

    def bin_of(self, range_m: float) -> float:
        """Fractional bin index of ``range_m``."""
        return (range_m - self.start_m) / self.bin_m


@dataclass(frozen=True, slots=True, eq=False)
class RadarFrame:
    """One radar frame: complex baseband ``I + jQ`` per bin (the X4 sends Q negated: only the phase sign).

    It carries its own range axis, so a consumer never guesses the geometry.
    """

    t_s: float  # loop time the frame was measured (the driver: received minus the sweep's half)
    frame_counter: int
    axis: RangeAxis
    baseband: np.ndarray  # complex64, shape (axis.bins,)

    @staticmethod
    def from_floats(t_s: float, frame_counter: int, axis: RangeAxis, values: np.ndarray) -> RadarFrame:
        """From the DataFloat values of downconversion 1: the I block, then the Q block."""
        if values.size != 2 * axis.bins:
            raise ValueError(f"a {axis.bins}-bin baseband frame has {2 * axis.bins} floats, got {values.size}")
        baseband = (values[: axis.bins] + 1j * values[axis.bins :]).astype(np.complex64)
        return RadarFrame(t_s, frame_counter, axis, baseband)

    def amplitude(self) -> np.ndarray:
        """|I + jQ| per bin (thesis §4.2.2)."""
        return np.abs(self.baseband)


@dataclass(frozen=True, slots=True)
class CameraModel:
    """The pinhole camera with OpenCV lens distortion (thesis §2.3.2, eqs. 2.6–2.9): intrinsics ``K`` (px) and
    distortion ``k1 k2 p1 p2 [k3 …]`` of one camera.

    Camera frame ``_cam``: OpenCV convention — x right in the image, y down in the image, z along the
    optical axis (out of the lens). Pixels ``(u, v)``: u to the right, v down, origin at the top-left
    pixel's corner as OpenCV counts it.

    Only *points* are undistorted (``cv2.undistortPoints``), never whole images: a detector finds corners
    in the raw image, and this model turns those pixels into rays. OpenCV is imported by the methods that
    need it: most importers of these messages (the simulated autopilot, the offboard link) never project a
    point and should not pay for loading it.
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    width_px: int = 1280
    height_px: int = 960

    @classmethod
    def from_settings(cls, cam: CameraSettings) -> CameraModel:
        return cls(
            fx_px=cam.fx_px,
            fy_px=cam.fy_px,
            cx_px=cam.cx_px,
            cy_px=cam.cy_px,
            distortion=tuple(float(d) for d in cam.distortion),
            width_px=cam.width_px,
            height_px=cam.height_px,
        )

    @property
    def K(self) -> FloatArray:
        """The 3×3 projection matrix of eq. 2.6."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]], dtype=np.float64
        )

    @property
    def dist_coeffs(self) -> FloatArray:
        return np.asarray(self.distortion, dtype=np.float64)

    def undistort_to_normalized(self, pixels: ArrayLike) -> FloatArray:
        """Raw (distorted) pixels N×2 → ideal normalized image coordinates ``(x/z, y/z)`` N×2."""
        import cv2

        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if px.shape[0] == 0:
            return np.zeros((0, 2))
        # Iterative inverse of eq. 2.9 (OpenCV default: 5 iterations is too coarse for strong distortion).
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        K, dist = _cv_intrinsics(self)
        xy = cv2.undistortPointsIter(px, K, dist, _EYE3, _EYE3, criteria)
        return np.asarray(xy, dtype=np.float64).reshape(-1, 2)

    def undistort_to_rays(self, pixels: ArrayLike) -> FloatArray:
        """Raw pixels N×2 → unit rays in the camera frame N×3 (z > 0)."""
        xy = self.undistort_to_normalized(pixels)
        rays = np.column_stack([xy, np.ones(len(xy))])
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    def project(self, points_cam: ArrayLike) -> FloatArray:
        """Points in the camera frame N×3 (m, z > 0) → raw (distorted) pixels N×2 (eqs. 2.6 + 2.9).

        Points behind the camera (z ≤ 0) give NaN pixels.
        """
        import cv2

        p = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
        front = p[:, 2] > MIN_DEPTH_M
        K, dist = _cv_intrinsics(self)
        if len(p) and front.all():  # the usual case: no points to leave out
            img, _ = cv2.projectPoints(p.reshape(-1, 1, 3), _ZERO3, _ZERO3, K, dist)
            return np.asarray(img, dtype=np.float64).reshape(-1, 2)
        out = np.full((len(p), 2), np.nan)
        if np.any(front):
            img, _ = cv2.projectPoints(p[front].reshape(-1, 1, 3), _ZERO3, _ZERO3, K, dist)
            out[front] = img.reshape(-1, 2)
        return out

    def in_image(self, pixels: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Which pixels N×2 fall inside the image (with ``margin_px`` kept clear of the border)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        u, v = px[:, 0], px[:, 1]
        return (
            np.isfinite(u)
            & np.isfinite(v)
            & (u >= margin_px)
            & (v >= margin_px)
            & (u <= self.width_px - 1 - margin_px)
            & (v <= self.height_px - 1 - margin_px)
        )


def _read_only(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


_EYE3, _ZERO3 = _read_only(np.eye(3)), _read_only(np.zeros(3))


@functools.lru_cache(maxsize=16)
def _cv_intrinsics(model: CameraModel) -> tuple[FloatArray, FloatArray]:
    """``model.K`` and ``model.dist_coeffs`` as OpenCV takes them, built once per camera (read-only)."""
    return _read_only(model.K), _read_only(model.dist_coeffs)
