"""Values the flight stack takes and gives: setpoints, events and the truth snapshot.

Frames and units: local NED about the boot point, metres, m/s, radians. ``PositionTarget`` is the
content of SET_POSITION_TARGET_LOCAL_NED; ``type_mask`` bits say what to *ignore* (MAVLink
POSITION_TARGET_TYPEMASK): 0-2 position, 3-5 velocity, 6-8 acceleration, 10 yaw, 11 yaw rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from app.messages import FlightMode, LandedState, Vec3
from sim.autopilot_modes import Mode
from sim.dynamics import Dynamics
from sim.multirotor import VehicleState

IGNORE_POS = (0x1, 0x2, 0x4)
IGNORE_VEL = (0x8, 0x10, 0x20)
IGNORE_YAW = 0x400
IGNORE_YAW_RATE = 0x800
VELOCITY_YAW_MASK = 0x9C7  # what MAVSDK's set_velocity_ned sends (2503)


class Frame(IntEnum):
    """MAV_FRAME values a local setpoint may use."""

    LOCAL_NED = 1
    LOCAL_OFFSET_NED = 7
    BODY_NED = 8
    BODY_OFFSET_NED = 9


@dataclass(frozen=True, slots=True)
class ResolvedSetpoint:
    """A setpoint in the local NED frame; ``None`` per axis = not commanded."""

    pos_ned_m: tuple[float | None, float | None, float | None]
    vel_ned_mps: tuple[float | None, float | None, float | None]
    yaw_rad: float | None
    yaw_rate_radps: float | None

    @classmethod
    def zero(cls) -> ResolvedSetpoint:
        return cls((None, None, None), (0.0, 0.0, 0.0), None, None)

    @property
    def is_velocity(self) -> bool:
        """True when no axis carries a position (a pure velocity setpoint)."""
        p = self.pos_ned_m
        return p[0] is None and p[1] is None and p[2] is None

    def velocity(self, pos_ned_m: Vec3, k_xy: float, k_z: float, cruise_mps: float) -> Vec3:
        """v_sp = K (p_sp − p) + v_ff per axis; position-only horizontal motion capped at cruise."""
        out = [0.0, 0.0, 0.0]
        for i in range(3):
            p_sp, v_ff = self.pos_ned_m[i], self.vel_ned_mps[i]
            k = k_z if i == 2 else k_xy
            out[i] = (k * (p_sp - pos_ned_m[i]) if p_sp is not None else 0.0) + (v_ff or 0.0)
        if self.vel_ned_mps[0] is None and self.vel_ned_mps[1] is None:
            v_h = math.hypot(out[0], out[1])
            if v_h > cruise_mps > 0.0:
                out[0], out[1] = out[0] * cruise_mps / v_h, out[1] * cruise_mps / v_h
        return (out[0], out[1], out[2])


@dataclass(frozen=True, slots=True)
class PositionTarget:
    """SET_POSITION_TARGET_LOCAL_NED as received (default: MAVSDK's velocity + yaw)."""

    frame: int = Frame.LOCAL_NED
    type_mask: int = VELOCITY_YAW_MASK
    pos_ned_m: Vec3 = (0.0, 0.0, 0.0)
    vel_ned_mps: Vec3 = (0.0, 0.0, 0.0)
    yaw_rad: float = 0.0
    yaw_rate_radps: float = 0.0

    @classmethod
    def velocity(cls, vel_ned_mps: Vec3, yaw_rad: float) -> PositionTarget:
        """What MAVSDK's ``offboard.set_velocity_ned`` sends."""
        return cls(vel_ned_mps=vel_ned_mps, yaw_rad=yaw_rad)

    def resolve(self, pos_ned_m: Vec3, yaw_rad: float) -> ResolvedSetpoint:
        """Into local NED: body frames are rotated by the current yaw, offset frames add the position."""
        m = self.type_mask
        body = self.frame in (Frame.BODY_NED, Frame.BODY_OFFSET_NED)
        offset = self.frame != Frame.LOCAL_NED  # body and offset frames: relative to the vehicle
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)

        def rotate(v: Vec3) -> Vec3:
            return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]) if body else v

        pos = rotate(self.pos_ned_m)
        if offset:
            pos = (pos[0] + pos_ned_m[0], pos[1] + pos_ned_m[1], pos[2] + pos_ned_m[2])
        vel = rotate(self.vel_ned_mps)
        pos_sp = tuple(None if m & IGNORE_POS[i] or math.isnan(pos[i]) else pos[i] for i in range(3))
        vel_sp = tuple(None if m & IGNORE_VEL[i] or math.isnan(vel[i]) else vel[i] for i in range(3))
        yaw = None if m & IGNORE_YAW or math.isnan(self.yaw_rad) else self.yaw_rad
        yaw_rate = None if m & IGNORE_YAW_RATE or math.isnan(self.yaw_rate_radps) else self.yaw_rate_radps
        return ResolvedSetpoint(pos_sp, vel_sp, yaw, yaw_rate)  # type: ignore[arg-type]


@dataclass(frozen=True, slots=True)
class StackEvent:
    """Something the outside should hear about at once.

    ``kind``: "mode" (``mode``, ``reason``), "armed" (``armed``, ``reason``), "landed_state",
    "statustext" (``text``, ``severity`` as MAV_SEVERITY), "home", "gripper" (``text``).
    """

    t_s: float
    kind: str
    reason: str = ""
    mode: Mode | None = None
    armed: bool | None = None
    landed_state: LandedState | None = None
    text: str = ""
    severity: int = 6


@dataclass(frozen=True, slots=True)
class Truth:
    """The simulated vehicle as it really is (local NED about the boot point, SI units)."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rates_radps: Vec3
    armed: bool
    mode: Mode
    flight_mode: FlightMode
    landed_state: LandedState
    home_ned_m: Vec3 | None
    on_ground: bool
    wind_ned_mps: Vec3
    battery_v: float
    battery_a: float
    battery_remaining: float
    gripper_closed: bool

    @classmethod
    def of(
        cls,
        t_s: float,
        dyn: Dynamics,
        armed: bool,
        mode: Mode,
        landed_state: LandedState,
        home_ned_m: Vec3 | None,
        gripper_closed: bool,
        state: VehicleState | None = None,
    ) -> Truth:
        """The snapshot at ``t_s``: ``dyn``'s state (or ``state``) and battery, and the flight stack's own state."""
        s = dyn.state if state is None else state
        b = dyn.battery
        return cls(
            t_s=t_s,
            pos_ned_m=s.pos_ned_m,
            vel_ned_mps=s.vel_ned_mps,
            acc_ned_mps2=s.acc_ned_mps2,
            roll_rad=s.roll_rad,
            pitch_rad=s.pitch_rad,
            yaw_rad=s.yaw_rad,
            rates_radps=s.rates_radps,
            armed=armed,
            mode=mode,
            flight_mode=mode.flight_mode,
            landed_state=landed_state,
            home_ned_m=home_ned_m,
            on_ground=s.on_ground,
            wind_ned_mps=s.wind_ned_mps,
            battery_v=b.voltage_v,
            battery_a=b.current_a,
            battery_remaining=b.remaining_frac,
            gripper_closed=gripper_closed,
        )
