"""The simulated multirotor's parameters (PX4 names), the command one physics step takes, the truth it gives and
its battery: the value types ``sim.dynamics`` steps and the flight stack, the in-process vehicle and the
airframe presets share. Frames and units as in ``sim.dynamics``: local NED about home, SI units, ZYX Euler.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sim.poscontrol import PosControlParams
from sim.wind import Vec3

G_MPS2 = 9.80665


@dataclass(frozen=True, slots=True)
class BatteryParams:
    """A LiPo pack: ``cells`` in series; the current scales with thrust^1.5 around hover."""

    cells: int = 4
    capacity_mah: float = 5000.0
    hover_current_a: float = 15.0  # 5 Ah / 15 A = 20 min hover endurance
    idle_current_a: float = 1.5
    disarmed_current_a: float = 0.3
    internal_resistance_ohm: float = 0.06
    full_cell_v: float = 4.2
    empty_cell_v: float = 3.5


@dataclass(frozen=True, slots=True)
class MultirotorParams:
    """Controller gains and limits (PX4 parameter names in comments) and the airframe."""

    xy_vel_p_acc: float = 1.8  # MPC_XY_VEL_P_ACC, 1/s
    xy_vel_i_acc: float = 0.4  # MPC_XY_VEL_I_ACC, 1/s²
    xy_vel_d_acc: float = 0.2  # MPC_XY_VEL_D_ACC, s (on the measured acceleration)
    z_vel_p_acc: float = 4.0  # MPC_Z_VEL_P_ACC
    z_vel_i_acc: float = 2.0  # MPC_Z_VEL_I_ACC
    acc_up_max_mps2: float = 4.0  # MPC_ACC_UP_MAX
    acc_down_max_mps2: float = 3.0  # MPC_ACC_DOWN_MAX
    tilt_max_deg: float = 35.0  # MPC_TILT_MAX_AIR
    vel_hor_max_mps: float = 12.0  # MPC_XY_VEL_MAX
    vel_up_max_mps: float = 3.0  # MPC_Z_VEL_MAX_UP
    vel_down_max_mps: float = 1.5  # MPC_Z_VEL_MAX_DN
    xy_pos_p: float = 0.95  # MPC_XY_P, 1/s
    z_pos_p: float = 1.0  # MPC_Z_P, 1/s
    cruise_hor_mps: float = 5.0  # MPC_XY_CRUISE
    attitude_tau_s: float = 0.08
    yaw_p: float = 2.8  # MC_YAW_P, 1/s
    yaw_rate_max_dps: float = 60.0  # MPC_YAWRAUTO_MAX-ish
    drag_per_s: float = 0.3  # linear drag towards the air-relative velocity
    thrust_to_weight: float = 2.0
    pos_control: PosControlParams | None = None  # ArduCopter GUIDED trajectory + position target (None: PX4)
    battery: BatteryParams = field(default_factory=BatteryParams)


@dataclass(frozen=True, slots=True)
class ControlInput:
    """What the flight stack asks of the vehicle for one step.

    ``vel_sp_ned_mps`` is the velocity setpoint (NED, m/s); ``yaw_sp_rad`` an absolute yaw or ``None``
    to keep the heading; ``yaw_rate_sp_radps`` overrides it when given. ``motors_on`` False = no thrust
    (disarmed, or spinning at idle on the ground). ``shaped`` False: the velocity comes from the autopilot's
    own position modes (takeoff, hold, land, RTL), which ArduCopter does not pass through its velocity shaping.
    """

    vel_sp_ned_mps: Vec3 = (0.0, 0.0, 0.0)
    yaw_sp_rad: float | None = None
    yaw_rate_sp_radps: float | None = None
    motors_on: bool = True
    shaped: bool = True  # a velocity setpoint from outside (ArduCopter shapes it); False: the autopilot's own modes


@dataclass(frozen=True, slots=True)
class VehicleState:
    """A snapshot of the truth (NED about home, SI units)."""

    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rates_radps: Vec3  # roll, pitch, yaw rates (Euler-angle derivatives)
    on_ground: bool
    thrust_mps2: float  # collective specific thrust
    wind_ned_mps: Vec3


def ahead(s: VehicleState, dt_s: float) -> VehicleState:
    """``s`` carried ``dt_s`` on at its acceleration and angular rates (the vehicle between two physics ticks, as
    seen at a time in between); on the ground, as it is."""
    if dt_s <= 0.0 or s.on_ground:
        return s
    p, v, a, r = s.pos_ned_m, s.vel_ned_mps, s.acc_ned_mps2, s.rates_radps
    h = 0.5 * dt_s * dt_s
    return VehicleState(
        pos_ned_m=(p[0] + v[0] * dt_s + a[0] * h, p[1] + v[1] * dt_s + a[1] * h, p[2] + v[2] * dt_s + a[2] * h),
        vel_ned_mps=(v[0] + a[0] * dt_s, v[1] + a[1] * dt_s, v[2] + a[2] * dt_s),
        acc_ned_mps2=a,
        roll_rad=s.roll_rad + r[0] * dt_s,
        pitch_rad=s.pitch_rad + r[1] * dt_s,
        yaw_rad=wrap_pi(s.yaw_rad + r[2] * dt_s),
        rates_radps=r,
        on_ground=False,
        thrust_mps2=s.thrust_mps2,
        wind_ned_mps=s.wind_ned_mps,
    )


def wrap_pi(angle_rad: float) -> float:
    """Wrap to [−π, π)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


class Battery:
    """Pack state: remaining charge drains with current; voltage = OCV(remaining) − R·I."""

    def __init__(self, params: BatteryParams) -> None:
        self.params = params
        self.consumed_mah = 0.0
        self.current_a = params.disarmed_current_a
        self.voltage_v = self._ocv_v(1.0) - params.internal_resistance_ohm * self.current_a

    @property
    def remaining_frac(self) -> float:
        return clamp(1.0 - self.consumed_mah / self.params.capacity_mah, 0.0, 1.0)

    def _ocv_v(self, remaining: float) -> float:
        p = self.params
        # A LiPo-like curve: flat in the middle, dropping towards empty.
        cell_v = p.empty_cell_v + (p.full_cell_v - p.empty_cell_v) * (0.3 * remaining + 0.7 * remaining**2)
        return p.cells * cell_v

    def step(self, dt_s: float, thrust_mps2: float, motors_on: bool, armed: bool) -> None:
        p = self.params
        if motors_on and thrust_mps2 > 0.0:
            self.current_a = max(p.idle_current_a, p.hover_current_a * (thrust_mps2 / G_MPS2) ** 1.5)
        else:
            self.current_a = p.idle_current_a if armed else p.disarmed_current_a
        self.consumed_mah += self.current_a * dt_s / 3.6
        self.voltage_v = self._ocv_v(self.remaining_frac) - p.internal_resistance_ohm * self.current_a
