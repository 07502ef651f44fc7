"""An in-process vehicle: ``app.offboard.vehicle.Vehicle`` on the simulated flight stack, on the loop clock.

No MAVLink and no wall clock: time is ``asyncio.get_running_loop().time()``, so under looptime a whole
flight runs in virtual time. The physics ticks on its own fixed grid (``sim.flight_stack``), brought up to "now"
by every command and every look at the vehicle; ``run()`` wakes at ``wake_hz`` (twice the telemetry streams' 50 Hz)
to hand out the samples and poll the watchdogs on the way. Positions are the autopilot's local NED
(metres), yaw in radians.

It behaves like the MAVSDK adapter talking to the MAVLink endpoint would:

- commands the autopilot refuses raise ``VehicleError(command, result)`` with MAVSDK's result names
  ("COMMAND_DENIED", "UNSUPPORTED", "FAILED");
- like MAVSDK's offboard plugin it re-sends the last setpoint every 50 ms once one was set, and stops
  doing so when ``stop_offboard`` is called or when the vehicle has not been in OFFBOARD for 3 s since
  the stream started (MAVSDK's watchdog) — so the offboard-loss failsafe fires only if that happens;
- PX4 ``takeoff(alt)`` sets MIS_TAKEOFF_ALT then takes off; ArduPilot switches to GUIDED and takes
  off with the altitude in the command;
- the setpoint watchdog (``attach_watchdog``) is polled from the physics steps, on the simulated world's
  clock — the stand-in for the thread that polls it next to MAVSDK — and ``zero_velocity_now`` replaces
  the setpoint being re-sent, as the adapter does from that thread.

``records`` is the vehicle's side of the story, in the simulator's state-log format (``sim.state_log``):
every setpoint it receives (``setpoint``: ``vel_ned_mps``, ``yaw_rad``, ``origin`` app/resend/watchdog),
every command with its source (``command``: ``command``, ``mode``, ``result``, ``source`` link/pilot/
autopilot) and every mode, armed and landed-state change. ``sim.safety_rules`` checks the safety rules
on it; ``state_log`` also writes it to a file.
"""

from __future__ import annotations

import asyncio
import math
from typing import Any

from app.clock import sleep_on
from app.errors import VehicleConnectionError, VehicleError
from app.messages import (
    AttitudeEuler,
    Autopilot,
    BatteryLevel,
    FlightMode,
    PositionVelocityNed,
    Stamped,
    TelemetrySnapshot,
    Vec3,
)
from app.offboard.vehicle import SampleListener
from app.offboard.watchdog import SetpointWatchdog
from sim import airframes
from sim.autopilot_modes import DEFAULT_ORIGIN, GeoPoint, MavResult, Mode, Profile, mode_for
from sim.dynamics import Dynamics
from sim.estimator import EstimatorError, EstimatorErrorParams
from sim.flight_stack import FlightStack
from sim.multirotor import MultirotorParams
from sim.stack_types import PositionTarget, StackEvent, Truth
from sim.state_log import StateLog
from sim.wind import Wind, WindConfig

TELEMETRY_PERIOD_S = 0.02  # position and attitude samples for listeners: the 50 Hz streams
SAMPLE_SLACK_S = 1e-6  # a wake a rounding error early for the next sample still gives it
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
        estimator: EstimatorErrorParams | None = None,
        wake_hz: float = 100.0,
        gps_fix_delay_s: float = 1.0,
        state_log: StateLog | None = None,
    ) -> None:
        """``wind`` None = the default wind (5 m/s from 240°, 1 m/s gusts); ``WindConfig.off()`` = still air.
        ``vehicle_params`` / ``estimator`` None = the calibrated ones for ``profile`` (``sim.airframes``)."""
        calibrated = airframes.default_for(profile)
        dynamics = Dynamics(
            vehicle_params if vehicle_params is not None else calibrated.airframe,
            Wind(wind if wind is not None else WindConfig(), seed=seed),
            estimator=EstimatorError(estimator if estimator is not None else calibrated.estimator, seed),
        )
        self.events: list[StackEvent] = []
        self.records: list[dict[str, Any]] = []
        self._state_log = state_log
        self.stack = FlightStack(  # on a fixed grid: a run is the same whoever watches it
            dynamics, profile, origin, params, gps_fix_delay_s, on_event=self._on_event, fixed_grid=True
        )
        self._period_s = 1.0 / wake_hz
        self._loop: asyncio.AbstractEventLoop | None = None  # while ``run`` runs: its loop (``LoopClock`` says why)
        self._stream: PositionTarget | None = None
        self._stream_started_s = 0.0
        self._next_resend_s = 0.0
        self._watchdogs: list[SetpointWatchdog] = []
        self._listeners: list[SampleListener] = []
        self._next_sample_s = 0.0
        # the last snapshot and what it was built from: read far more often than the physics steps
        self._snapshot = TelemetrySnapshot()
        self._snapshot_of: tuple[Any, ...] = ()
        boot = self.stack.mode
        self._record("mode", 0.0, mode=boot.flight_mode.value, autopilot_mode=boot.label, reason="boot")

    # -- the Vehicle protocol -------------------------------------------------------------------

    @property
    def autopilot(self) -> Autopilot:
        return Autopilot.ARDUPILOT if self.stack.profile is Profile.ARDUPILOT else Autopilot.PX4

    async def run(self) -> None:
        """Bring the simulation up to now every ``1/wake_hz`` until cancelled."""
        self._loop = loop = asyncio.get_running_loop()
        try:
            while True:
                self._advance()
                await sleep_on(loop, self._period_s)
        finally:
            self._loop = None

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
        est = st.dyn.estimate  # a new object after every physics step (with the battery's new state)
        of = self._snapshot_of
        if of and of[0] == t_s and of[1] is est and of[2] is st.mode and of[3] is st.armed and of[4] is st.landed_state:
            if of[5] is st.home_ned_m:
                return self._snapshot  # nothing moved since it was built
        self._snapshot_of = (t_s, est, st.mode, st.armed, st.landed_state, st.home_ned_m)
        s = st.estimate()  # the tick's carried on to now
        self._snapshot = TelemetrySnapshot(
            pos_vel=PositionVelocityNed(t_s, s.pos_ned_m, s.vel_ned_mps),
            attitude=AttitudeEuler(t_s, s.roll_rad, s.pitch_rad, s.yaw_rad),
            flight_mode=Stamped(t_s, st.flight_mode),
            armed=Stamped(t_s, st.armed),
            landed_state=Stamped(t_s, st.landed_state),
            home_ned_m=st.home_ned_m,
            heartbeat_t_s=t_s,
            battery=Stamped(t_s, BatteryLevel(st.dyn.battery.voltage_v, st.dyn.battery.remaining_frac)),
        )
        return self._snapshot

    def add_sample_listener(self, listener: SampleListener) -> None:
        """Position and attitude samples of the estimate at ``TELEMETRY_PERIOD_S`` (as the MAVLink streams)."""
        self._listeners.append(listener)

    def link_stats(self) -> dict[str, float | str | None]:
        return {}  # no link: samples are read straight from the physics

    async def set_param(self, name: str, value: float) -> None:
        """As MAVSDK's param plugin: an unknown name is ``DOES_NOT_EXIST``; a set one is logged (``param``)."""
        t_s = self._advance()
        store = self.stack.params
        if name not in store:
            raise VehicleError("set_param", "DOES_NOT_EXIST", name)
        if not store.set(name, value):
            raise VehicleError("set_param", "VALUE_OUT_OF_RANGE", f"{name} {value}")
        self._record("param", t_s, name=name, value=store.get(name))
        await asyncio.sleep(0)

    async def arm(self) -> None:
        t_s = self._advance()
        self._check("arm", self._command(t_s, "COMPONENT_ARM_DISARM", self.stack.arm(t_s)))
        await asyncio.sleep(0)

    async def takeoff(self, altitude_m: float) -> None:
        t_s = self._advance()
        st = self.stack
        if st.profile is Profile.ARDUPILOT:
            self._check("takeoff", self._command(t_s, "DO_SET_MODE", st.set_mode(t_s, Mode.AP_GUIDED), Mode.AP_GUIDED))
            self._check("takeoff", self._command(t_s, "NAV_TAKEOFF", st.takeoff(t_s, altitude_m)))
        else:
            if not st.params.set("MIS_TAKEOFF_ALT", altitude_m):
                raise VehicleError("takeoff", "PARAMETER_ERROR", f"altitude {altitude_m}")
            self._check("takeoff", self._command(t_s, "NAV_TAKEOFF", st.takeoff(t_s, math.nan)))
        await asyncio.sleep(0)

    async def start_offboard(self, yaw_rad: float) -> None:
        await self.set_velocity_ned((0.0, 0.0, 0.0), yaw_rad)
        offboard = Mode.AP_GUIDED if self.stack.profile is Profile.ARDUPILOT else Mode.OFFBOARD
        t_s = self._advance()
        self._check("start_offboard", self._command(t_s, "DO_SET_MODE", self.stack.set_mode(t_s, offboard), offboard))
        await asyncio.sleep(0)

    async def set_velocity_ned(self, vel_ned_mps: Vec3, yaw_rad: float) -> None:
        self._set_stream(self._advance(), PositionTarget.velocity(vel_ned_mps, yaw_rad), "app")

    def zero_velocity_now(self, yaw_rad: float) -> None:
        """What the adapter does from the watchdog's thread: the re-sent setpoint becomes zero velocity."""
        if self._stream is not None:
            self._set_stream(self.stack.t_s, PositionTarget.velocity((0.0, 0.0, 0.0), yaw_rad), "watchdog")

    def attach_watchdog(self, watchdog: SetpointWatchdog) -> None:
        self._watchdogs.append(watchdog)

    async def hold(self) -> None:
        t_s = self._advance()
        self._check("hold", self._command(t_s, "DO_SET_MODE", self.stack.hold(t_s), self._hold_mode()))
        await asyncio.sleep(0)

    async def stop_offboard(self) -> None:
        await self.set_velocity_ned((0.0, 0.0, 0.0), self.stack.dyn.state.yaw_rad)
        self._stream = None
        t_s = self._advance()
        self._check("stop_offboard", self._command(t_s, "DO_SET_MODE", self.stack.hold(t_s), self._hold_mode()))
        await asyncio.sleep(0)

    async def grip(self, closed: bool) -> None:
        t_s = self._advance()
        self._check("gripper", self._command(t_s, "DO_GRIPPER", self.stack.set_gripper(t_s, grab=closed)))
        await asyncio.sleep(0)

    async def land(self) -> None:
        t_s = self._advance()
        self._check("land", self._command(t_s, "NAV_LAND", self.stack.land(t_s)))
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
        t_s = self._advance()
        result = self.stack.set_mode(t_s, mode, "pilot")
        self._check("pilot_set_mode", self._command(t_s, "DO_SET_MODE", result, mode, source="pilot"))

    def pilot_kill(self) -> None:
        """The pilot's emergency stop (RC kill switch / forced disarm): the motors stop wherever the vehicle is."""
        t_s = self._advance()
        self._check(
            "pilot_kill",
            self._command(t_s, "COMPONENT_ARM_DISARM", self.stack.disarm(t_s, force=True), None, source="pilot"),
        )

    def autopilot_failsafe(self, flight_mode: FlightMode) -> None:
        """The autopilot switches mode on its own (a battery, RC- or link-loss failsafe): RTL or LAND."""
        mode = mode_for(self.stack.profile, flight_mode)
        if mode is None:
            raise VehicleError("autopilot_failsafe", "UNSUPPORTED", flight_mode.value)
        self.stack.set_mode(self._advance(), mode, "failsafe")

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
        """Bring the simulation up to the loop's now, re-sending setpoints as MAVSDK does on the way.

        The setpoint watchdogs are polled at every re-send and at ``now`` (on the world's clock).
        """
        t_s = (self._loop or asyncio.get_running_loop()).time()
        st = self.stack
        while self._stream is not None and self._next_resend_s <= t_s:
            t_resend_s = self._next_resend_s
            st.step(t_resend_s)
            self._poll_watchdogs(t_resend_s)  # may replace the stream (and push the next re-send)
            if self._stream is None or self._next_resend_s != t_resend_s:
                continue
            if self._watchdog_expired(t_resend_s):
                self._stream = None
                break
            self._record("setpoint", t_resend_s, **_setpoint_fields(self._stream), origin="resend")
            st.position_target(t_resend_s, self._stream)
            self._next_resend_s += SETPOINT_RESEND_S
        st.step(t_s)
        self._poll_watchdogs(t_s)
        if self._listeners and st.started and t_s >= self._next_sample_s:
            self._next_sample_s = t_s + TELEMETRY_PERIOD_S - SAMPLE_SLACK_S  # the next wake, rounding and all
            snap = self.telemetry()
            assert snap.pos_vel is not None and snap.attitude is not None
            for listener in self._listeners:
                listener(snap.pos_vel, t_s)
                listener(snap.attitude, t_s)
        return t_s

    def _poll_watchdogs(self, t_s: float) -> None:
        for w in self._watchdogs:
            w.poll(t_s)

    def _set_stream(self, t_s: float, target: PositionTarget, origin: str) -> None:
        if self._stream is None:
            self._stream_started_s = t_s
        self._stream = target
        self._next_resend_s = t_s + SETPOINT_RESEND_S
        self._record("setpoint", t_s, **_setpoint_fields(target), origin=origin)
        self.stack.position_target(t_s, target)

    def _hold_mode(self) -> Mode:
        return Mode.AP_BRAKE if self.stack.profile is Profile.ARDUPILOT else Mode.AUTO_LOITER

    def _command(
        self, t_s: float, command: str, result: MavResult, mode: Mode | None = None, source: str = "link"
    ) -> MavResult:
        fields: dict[str, Any] = {"command": command, "result": result.name, "source": source}
        if mode is not None:
            fields["mode"] = mode.flight_mode.value
        self._record("command", t_s, **fields)
        return result

    def _on_event(self, ev: StackEvent) -> None:
        self.events.append(ev)
        if ev.kind == "mode" and ev.mode is not None:
            self._record("mode", ev.t_s, mode=ev.mode.flight_mode.value, autopilot_mode=ev.mode.label, reason=ev.reason)
        elif ev.kind == "armed":
            self._record("armed", ev.t_s, armed=ev.armed, reason=ev.reason)
        elif ev.kind == "landed_state" and ev.landed_state is not None:
            self._record("landed_state", ev.t_s, landed_state=ev.landed_state.value)

    def _record(self, event: str, t_s: float, **fields: Any) -> None:
        self.records.append({"t_s": t_s, "event": event, **fields})
        if self._state_log is not None:
            self._state_log.write(event, t_s, **fields)

    def _watchdog_expired(self, t_s: float) -> bool:
        in_offboard = self.stack.flight_mode is FlightMode.OFFBOARD
        return not in_offboard and t_s - self._stream_started_s > OFFBOARD_WATCHDOG_S

    @staticmethod
    def _check(command: str, result: MavResult) -> None:
        if result is not MavResult.ACCEPTED:
            raise VehicleError(command, _RESULT_NAMES.get(result, result.name))


def _setpoint_fields(target: PositionTarget) -> dict[str, Any]:
    return {"vel_ned_mps": list(target.vel_ned_mps), "yaw_rad": target.yaw_rad}
