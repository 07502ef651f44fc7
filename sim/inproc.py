"""An in-process vehicle: ``app.offboard.vehicle.Vehicle`` on the simulated flight stack, on the loop clock.

No MAVLink and no wall clock: time is ``asyncio.get_running_loop().time()``, so under looptime a whole
flight runs in virtual time. ``run()`` steps the physics at ``physics_hz`` with ``asyncio.sleep``;
every command also brings the simulation up to "now" first. Positions are the autopilot's local NED
(metres), yaw in radians.

It behaves like the MAVSDK adapter talking to the MAVLink endpoint would:

- commands the autopilot refuses raise ``VehicleError(command, result)`` with MAVSDK's result names
  ("COMMAND_DENIED", "UNSUPPORTED", "FAILED");
- like MAVSDK's offboard plugin it re-sends the last setpoint every 50 ms once one was set, and stops
  doing so when ``stop_offboard`` is called or when the vehicle has not been in OFFBOARD for 3 s since
  the stream started (MAVSDK's watchdog) — so the offboard-loss failsafe fires only if that happens;
- PX4 ``takeoff(alt)`` sets MIS_TAKEOFF_ALT then takes off; ArduPilot switches to GUIDED and takes
  off with the altitude in the command.
"""

from __future__ import annotations

import asyncio
import math

from app.errors import VehicleConnectionError, VehicleError
from app.messages import (
    AttitudeEuler,
    Autopilot,
    FlightMode,
    PositionVelocityNed,
    Stamped,
    TelemetrySnapshot,
    Vec3,
)
from sim.autopilot_modes import DEFAULT_ORIGIN, GeoPoint, MavResult, Mode, Profile, mode_for
from sim.dynamics import Dynamics, MultirotorParams
from sim.flight_stack import FlightStack
from sim.stack_types import PositionTarget, StackEvent, Truth
from sim.wind import Wind, WindConfig

SETPOINT_RESEND_S = 0.05  # MAVSDK offboard re-sends the last setpoint at 20 Hz
OFFBOARD_WATCHDOG_S = 3.0  # MAVSDK stops sending when the vehicle is not in OFFBOARD after this
_RESULT_NAMES = {
    MavResult.DENIED: "COMMAND_DENIED",
    MavResult.TEMPORARILY_REJECTED: "COMMAND_DENIED",
    MavResult.UNSUPPORTED: "UNSUPPORTED",
    MavResult.FAILED: "FAILED",
}


class InProcessVehicle:
    """The simulated vehicle behind the app's ``Vehicle`` protocol, stepped on the asyncio loop clock."""

    def __init__(
        self,
        *,
        seed: int = 0,
        wind: WindConfig | None = None,
        profile: Profile = Profile.PX4,
        origin: GeoPoint = DEFAULT_ORIGIN,
        params: dict[str, float] | None = None,
        vehicle_params: MultirotorParams | None = None,
        physics_hz: float = 100.0,
        gps_fix_delay_s: float = 1.0,
    ) -> None:
        """``wind`` None = the default wind (5 m/s from 240°, 1 m/s gusts); ``WindConfig.off()`` = still air."""
        dynamics = Dynamics(vehicle_params, Wind(wind if wind is not None else WindConfig(), seed=seed))
        self.events: list[StackEvent] = []
        self.stack = FlightStack(dynamics, profile, origin, params, gps_fix_delay_s, on_event=self.events.append)
        self._period_s = 1.0 / physics_hz
        self._stream: PositionTarget | None = None
        self._stream_started_s = 0.0
        self._next_resend_s = 0.0

    # -- the Vehicle protocol -------------------------------------------------------------------

    @property
    def autopilot(self) -> Autopilot:
        return Autopilot.ARDUPILOT if self.stack.profile is Profile.ARDUPILOT else Autopilot.PX4

    async def run(self) -> None:
        """Step the simulation until cancelled."""
        while True:
            self._advance()
            await asyncio.sleep(self._period_s)

    async def wait_ready(self, timeout_s: float) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout_s
        while True:
            self._advance()
            snap = self.telemetry()
            if snap.pos_vel is not None and snap.home_ned_m is not None:
                return
            if loop.time() >= deadline:
                missing = "position" if snap.pos_vel is None else "home"
                raise VehicleConnectionError("wait_ready", "TIMEOUT", f"no {missing} after {timeout_s} s")
            await asyncio.sleep(min(0.05, max(0.0, deadline - loop.time())))

    def telemetry(self) -> TelemetrySnapshot:
        st = self.stack
        if not st.started:
            return TelemetrySnapshot()
        t_s = st.t_s
        s = st.dyn.state
        return TelemetrySnapshot(
            pos_vel=PositionVelocityNed(t_s, s.pos_ned_m, s.vel_ned_mps),
            attitude=AttitudeEuler(t_s, s.roll_rad, s.pitch_rad, s.yaw_rad),
            flight_mode=Stamped(t_s, st.flight_mode),
            armed=Stamped(t_s, st.armed),
            landed_state=Stamped(t_s, st.landed_state),
            home_ned_m=st.home_ned_m,
        )

    def link_stats(self) -> dict[str, float | str | None]:
        return {}  # no link: samples are read straight from the physics

    async def arm(self) -> None:
        self._check("arm", self.stack.arm(self._advance()))
        await asyncio.sleep(0)

    async def takeoff(self, altitude_m: float) -> None:
        t_s = self._advance()
        if self.stack.profile is Profile.ARDUPILOT:
            self._check("takeoff", self.stack.set_mode(t_s, Mode.AP_GUIDED))
            self._check("takeoff", self.stack.takeoff(t_s, altitude_m))
        else:
            if not self.stack.params.set("MIS_TAKEOFF_ALT", altitude_m):
                raise VehicleError("takeoff", "PARAMETER_ERROR", f"altitude {altitude_m}")
            self._check("takeoff", self.stack.takeoff(t_s, math.nan))
        await asyncio.sleep(0)

    async def start_offboard(self, yaw_rad: float) -> None:
        await self.set_velocity_ned((0.0, 0.0, 0.0), yaw_rad)
        offboard = Mode.AP_GUIDED if self.stack.profile is Profile.ARDUPILOT else Mode.OFFBOARD
        self._check("start_offboard", self.stack.set_mode(self._advance(), offboard))
        await asyncio.sleep(0)

    async def set_velocity_ned(self, vel_ned_mps: Vec3, yaw_rad: float) -> None:
        t_s = self._advance()
        target = PositionTarget.velocity(vel_ned_mps, yaw_rad)
        if self._stream is None:
            self._stream_started_s = t_s
        self._stream = target
        self._next_resend_s = t_s + SETPOINT_RESEND_S
        self.stack.position_target(t_s, target)

    async def hold(self) -> None:
        self._check("hold", self.stack.hold(self._advance()))
        await asyncio.sleep(0)

    async def stop_offboard(self) -> None:
        await self.set_velocity_ned((0.0, 0.0, 0.0), self.stack.dyn.state.yaw_rad)
        self._stream = None
        self._check("stop_offboard", self.stack.hold(self._advance()))
        await asyncio.sleep(0)

    async def land(self) -> None:
        self._check("land", self.stack.land(self._advance()))
        await asyncio.sleep(0)

    # -- for tests and scenarios ----------------------------------------------------------------

    def pilot_set_mode(self, flight_mode: FlightMode) -> None:
        """Switch mode as the RC pilot would (ArduPilot HOLD = LOITER); raises ``VehicleError`` if refused."""
        profile = self.stack.profile
        mode = (
            Mode.AP_LOITER
            if (profile, flight_mode) == (Profile.ARDUPILOT, FlightMode.HOLD)
            else (mode_for(profile, flight_mode))
        )
        if mode is None:
            raise VehicleError("pilot_set_mode", "UNSUPPORTED", flight_mode.value)
        self._check("pilot_set_mode", self.stack.set_mode(self._advance(), mode, "pilot"))

    def truth(self) -> Truth:
        """The simulated truth, brought up to the loop's now when called inside a running loop."""
        try:
            self._advance()
        except RuntimeError:  # no running loop: the truth as of the last step
            pass
        return self.stack.truth()

    def stop_setpoint_stream(self) -> None:
        """Stop re-sending setpoints, as if the companion computer stalled (to trigger offboard loss)."""
        self._stream = None

    # -- internals ------------------------------------------------------------------------------

    def _advance(self) -> float:
        """Bring the simulation up to the loop's now, re-sending setpoints as MAVSDK does on the way."""
        t_s = asyncio.get_running_loop().time()
        st = self.stack
        while self._stream is not None and self._next_resend_s <= t_s:
            st.step(self._next_resend_s)
            if self._watchdog_expired(self._next_resend_s):
                self._stream = None
                break
            st.position_target(self._next_resend_s, self._stream)
            self._next_resend_s += SETPOINT_RESEND_S
        st.step(t_s)
        return t_s

    def _watchdog_expired(self, t_s: float) -> bool:
        in_offboard = self.stack.flight_mode is FlightMode.OFFBOARD
        return not in_offboard and t_s - self._stream_started_s > OFFBOARD_WATCHDOG_S

    @staticmethod
    def _check(command: str, result: MavResult) -> None:
        if result is not MavResult.ACCEPTED:
            raise VehicleError(command, _RESULT_NAMES.get(result, result.name))
