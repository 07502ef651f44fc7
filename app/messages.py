"""Frozen messages that travel between the parts of the app.

Every message carries ``t_s``: the loop-clock time it was *measured* (for telemetry: when the autopilot took
the sample, or when it was received — never when it was read), not the time it was used. Vectors are
``(north, east, down)`` tuples in metres or metres per second, as their names say (``_ned_m``, ``_ned_mps``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

Vec3 = tuple[float, float, float]
T = TypeVar("T")


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
    """Where the target is (NED, metres) and how it moves, valid at ``t_s``."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3 = (0.0, 0.0, 0.0)

    def predict(self, t_s: float) -> TargetState:
        """Constant-velocity extrapolation to ``t_s`` (acceleration kept, not integrated)."""
        dt_s = t_s - self.t_s
        p = tuple(p + v * dt_s for p, v in zip(self.pos_ned_m, self.vel_ned_mps, strict=True))
        return TargetState(t_s, (p[0], p[1], p[2]), self.vel_ned_mps, self.acc_ned_mps2)


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
