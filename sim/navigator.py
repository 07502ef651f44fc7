"""Where the autonomous modes fly: hold point, takeoff target, landing spot and RTL legs (like PX4's navigator).

Frames and units: local NED about the boot point, metres; the outputs are velocity setpoints (NED, m/s)
for ``Dynamics``, from PX4's position P-controller (``velocity_from_position``). Pure: state in, state
and setpoints out, no clock.

- HOLD brakes first (zero velocity until the horizontal speed is below 0.3 m/s), then holds where it
  stopped, at the altitude it had when the hold began;
- takeoff climbs at the takeoff speed to the target and reports done within 0.2 m of it;
- landing holds the horizontal spot and descends at the profile's landing speed for the height;
- RTL climbs to the return altitude (if lower), flies home at cruise speed, then lands.
"""

from __future__ import annotations

import math

from app.messages import Vec3
from sim.autopilot_params import Tuning
from sim.dynamics import Dynamics, velocity_from_position

BRAKED_MPS = 0.3
TAKEOFF_DONE_M = 0.2
RTL_ALT_REACHED_M = 0.3
RTL_HOME_REACHED_M = 0.5


class Navigator:
    """The targets of the autonomous modes and the velocity setpoints that fly them."""

    def __init__(self, dynamics: Dynamics, tuning: Tuning) -> None:
        self.dyn = dynamics
        self.tuning = tuning
        s = dynamics.estimate
        self.hold_pos_ned_m: Vec3 = s.pos_ned_m
        self.yaw_hold_rad = s.yaw_rad
        self.braking = False
        self.takeoff_target_ned_m: Vec3 | None = None
        self.rtl_phase = "climb"  # "climb", "return", "land"
        self._rtl_alt_down_m = 0.0
        self._land_xy_m = (0.0, 0.0)

    def hold_here(self) -> None:
        """Hold where the vehicle is (braking first when it is flying) and keep its heading."""
        s = self.dyn.estimate
        self.hold_pos_ned_m = s.pos_ned_m
        self.yaw_hold_rad = s.yaw_rad
        self.braking = not s.on_ground

    def hold_at(self, pos_ned_m: Vec3) -> None:
        self.hold_pos_ned_m, self.braking = pos_ned_m, False

    def start_landing(self) -> None:
        p = self.dyn.estimate.pos_ned_m
        self._land_xy_m = (p[0], p[1])

    def start_rtl(self, home_ned_m: Vec3, on_ground: bool) -> None:
        p = self.dyn.estimate.pos_ned_m
        self._rtl_alt_down_m = min(p[2], home_ned_m[2] - self.tuning.rtl_alt_m())
        self.rtl_phase = "land" if on_ground else "climb"
        self._land_xy_m = (p[0], p[1]) if on_ground else (home_ned_m[0], home_ned_m[1])

    def takeoff_velocity(self) -> tuple[Vec3, bool]:
        """Velocity towards the takeoff target, and whether it has been reached."""
        assert self.takeoff_target_ned_m is not None
        target, p = self.takeoff_target_ned_m, self.dyn.estimate_pos_vel()[0]
        v = velocity_from_position(target, p, self.dyn.params, max_up_mps=self.tuning.takeoff_speed_mps())
        return v, p[2] - target[2] <= TAKEOFF_DONE_M

    def hold_velocity(self) -> Vec3:
        p, v = self.dyn.estimate_pos_vel()
        if self.braking:
            if math.hypot(v[0], v[1]) > BRAKED_MPS:
                return (0.0, 0.0, 0.0)
            self.braking = False
            self.hold_pos_ned_m = (p[0], p[1], self.hold_pos_ned_m[2])
        return velocity_from_position(self.hold_pos_ned_m, p, self.dyn.params, self.tuning.cruise_mps())

    def landing_velocity(self) -> Vec3:
        p = self.dyn.estimate_pos_vel()[0]
        target = (self._land_xy_m[0], self._land_xy_m[1], p[2])
        v = velocity_from_position(target, p, self.dyn.params, self.tuning.cruise_mps())
        return (v[0], v[1], self.tuning.land_speed_mps(self.dyn.ground_down_m - p[2]))

    def rtl_velocity(self) -> Vec3:
        if self.rtl_phase == "land":
            return self.landing_velocity()
        s = self.dyn.estimate
        p = s.pos_ned_m
        if self.rtl_phase == "climb":
            target = (self.hold_pos_ned_m[0], self.hold_pos_ned_m[1], self._rtl_alt_down_m)
            if abs(p[2] - self._rtl_alt_down_m) < RTL_ALT_REACHED_M:
                self.rtl_phase = "return"
        else:
            target = (self._land_xy_m[0], self._land_xy_m[1], self._rtl_alt_down_m)
            home_dist_m = math.hypot(target[0] - p[0], target[1] - p[1])
            if home_dist_m < RTL_HOME_REACHED_M and math.hypot(*s.vel_ned_mps[:2]) < RTL_HOME_REACHED_M:
                self.rtl_phase = "land"
        return velocity_from_position(target, p, self.dyn.params, self.tuning.cruise_mps())
