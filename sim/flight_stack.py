"""The autopilot's logic (PX4 or ArduCopter semantics), pure and time-injected.

Shared by the MAVLink endpoint (``sim.autopilot``, wall clock) and the in-process vehicle
(``sim.inproc``, loop clock): every entry point takes ``t_s`` (seconds on the caller's clock) and
``step(t_s)`` advances the physics to it in ticks of ``PHYSICS_DT_S`` (``fixed_grid``: see ``step``).
Positions are local NED about the point where the vehicle booted (metres), velocities m/s, angles radians.

What it emulates (PX4 names; ArduCopter differences in brackets):

- arming needs pre-arm OK (GPS fix after ``gps_fix_delay_s``) and the vehicle on the ground, not in
  LAND/RTL [nor BRAKE]; home is set at the first fix and again at arming;
- disarm is denied in the air unless forced (21196); auto-disarm COM_DISARM_PRFLT after arming without
  takeoff and COM_DISARM_LAND after landing [DISARM_DELAY; LAND/RTL disarm at touchdown];
- takeoff: NaN/0 altitude → MIS_TAKEOFF_ALT, AUTO.TAKEOFF climbs at MPC_TKO_SPEED then AUTO.LOITER
  [GUIDED only, param7 = altitude, stays in GUIDED; a setpoint while still on the ground cancels it];
- LAND descends (fast above 10 m, MPC_LAND_SPEED below 5 m), RTL climbs to RTL_RETURN_ALT, flies home
  at cruise speed and lands; PX4 switches to HOLD when it disarms after an autonomous landing;
- OFFBOARD needs a setpoint in the last 0.5 s and falls back to HOLD after COM_OF_LOSS_T without one
  ("offboard lost") [GUIDED needs no stream; GUID_TIMEOUT without a velocity setpoint → stop and hold];
- pilot modes (MANUAL, ALTCTL, POSCTL, STABILIZED…) hold position: a pilot-less sim has centred sticks.

Refusals to arm or switch mode come from ``sim.command_checks``, land detection, spool-up and
auto-disarm from ``sim.land_detector``, the setpoint-loss verdict from ``sim.failsafe``; this module
acts on them (events, mode switches, disarming).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from app.messages import FlightMode, LandedState, Vec3
from sim.autopilot_modes import (
    DEFAULT_ORIGIN,
    Behaviour,
    GeoPoint,
    MavResult,
    Mode,
    Profile,
    hold_mode,
    initial_mode,
)
from sim.autopilot_params import ParamStore, Tuning
from sim.command_checks import arming_denial, mode_switch_denial
from sim.dynamics import Dynamics
from sim.failsafe import SetpointLoss, setpoint_loss
from sim.land_detector import LandDetector, Spoolup
from sim.multirotor import ControlInput, VehicleState, ahead
from sim.navigator import Navigator
from sim.stack_types import Frame, PositionTarget, ResolvedSetpoint, StackEvent, Truth

# 100 Hz: the calibrated airframes answer the recorded setpoint scripts (``sim.response_replay``) within 2 mm/s RMS
# of what they do at 200 Hz (the attitude lag is stepped exactly, τ 0.08 s), at half the CPU
PHYSICS_DT_S = 0.01
CLIMB_INTENT_MPS = 0.3  # upward velocity setpoint that spins up from the ground
SEVERITY_WARNING, SEVERITY_NOTICE, SEVERITY_INFO = 4, 5, 6


class FlightStack:
    """Modes, arming, failsafes and setpoints on top of ``Dynamics``; see the module docstring."""

    def __init__(
        self,
        dynamics: Dynamics | None = None,
        profile: Profile = Profile.PX4,
        origin: GeoPoint = DEFAULT_ORIGIN,
        params: dict[str, float] | None = None,
        gps_fix_delay_s: float = 1.0,
        on_event: Callable[[StackEvent], None] | None = None,
        fixed_grid: bool = False,
    ) -> None:
        self.fixed_grid = fixed_grid
        self.dyn = dynamics if dynamics is not None else Dynamics()
        self.profile = profile
        self.origin = origin
        self.params = ParamStore(profile, params)
        self.tuning = Tuning(self.params)
        self._params_version = -1  # the parameter set the physics was last given (``_apply_params``)
        self.gps_fix_delay_s = gps_fix_delay_s
        self._on_event = on_event
        self._t_s: float | None = None
        self._t0_s = 0.0
        self._ticks = 0  # physics ticks since the first step
        self._tick_t_s = 0.0  # the last tick's time
        self.mode = initial_mode(profile)
        self.armed = False
        self.landed_state = LandedState.ON_GROUND
        self.home_ned_m: Vec3 | None = None
        self.gripper_closed = False
        self._prearm_failure: str | None = None
        self._sp: ResolvedSetpoint | None = None
        self._sp_t_s = -math.inf
        self.nav = Navigator(self.dyn, self.tuning)
        self._guided_sub = "hold"  # ArduCopter GUIDED: "hold", "takeoff", "setpoint"
        self.land_detector = LandDetector()
        self.spoolup = Spoolup()

    # -- time -----------------------------------------------------------------------------------

    @property
    def t_s(self) -> float:
        return self._t_s if self._t_s is not None else 0.0

    @property
    def started(self) -> bool:
        """True once ``step`` has been called (the boot time is the first ``t_s``)."""
        return self._t_s is not None

    @property
    def time_since_boot_s(self) -> float:
        return self.t_s - self._t0_s

    def step(self, t_s: float) -> None:
        """Advance physics and logic to ``t_s`` (never backwards).

        ``fixed_grid`` (the in-process vehicle, virtual time): ticks fall on a fixed grid, ``PHYSICS_DT_S`` apart
        from the first ``step``, as an autopilot's loop runs at its own rate, so who looks at the vehicle, and
        when, changes nothing of its flight (a run replayed with an observer more, e.g. a truth trace for the
        run's report, flies exactly as the run without it). A setpoint or a command given between ticks takes
        effect at the next one; ``truth`` and ``estimate`` see the last tick carried on to ``t_s``. Otherwise
        (the MAVLink endpoint, wall clock, never repeatable anyway) equal substeps of at most ``PHYSICS_DT_S``
        end exactly at ``t_s``.
        """
        if self._t_s is None:
            self._t_s = self._t0_s = self._tick_t_s = t_s
            return
        if not self.fixed_grid:
            span_s = t_s - self._t_s
            if span_s <= 1e-9:
                return
            n = math.ceil(span_s / PHYSICS_DT_S - 1e-6)
            t0_s = self._t_s
            for i in range(1, n + 1):
                self._t_s = self._tick_t_s = t0_s + span_s * i / n
                self._tick(self._t_s, span_s / n)
            return
        n = math.floor((t_s - self._t0_s) / PHYSICS_DT_S + 1e-6)
        while self._ticks < n:
            self._ticks += 1
            self._t_s = self._tick_t_s = min(self._t0_s + self._ticks * PHYSICS_DT_S, t_s)  # not after now
            self._tick(self._t_s, PHYSICS_DT_S)
        self._t_s = max(self._t_s, t_s)  # now: what a command given now is stamped with (its effect: next tick)

    # -- observation ----------------------------------------------------------------------------

    @property
    def flight_mode(self) -> FlightMode:
        return self.mode.flight_mode

    @property
    def gps_ok(self) -> bool:
        return self._t_s is not None and self.time_since_boot_s >= self.gps_fix_delay_s

    @property
    def prearm_ok(self) -> bool:
        return self.gps_ok and self.home_ned_m is not None and self._prearm_failure is None

    @property
    def home_geo(self) -> GeoPoint | None:
        return None if self.home_ned_m is None else self.origin.offset(self.home_ned_m)

    def inject_prearm_failure(self, reason: str | None) -> None:
        """Make pre-arm checks fail with ``reason`` (``None`` clears it)."""
        self._prearm_failure = reason

    def offboard_setpoint_age_s(self) -> float:
        return self.t_s - self._sp_t_s

    def truth(self) -> Truth:
        """The truth now (the last ``step``'s time): the last tick's state carried on to it."""
        state = ahead(self.dyn.state, self.t_s - self._tick_t_s)
        return Truth.of(
            self.t_s, self.dyn, self.armed, self.mode, self.landed_state, self.home_ned_m, self.gripper_closed, state
        )

    def estimate(self) -> VehicleState:
        """What the autopilot believes now (what its telemetry reports): the last tick's estimate carried on."""
        return ahead(self.dyn.estimate, self.t_s - self._tick_t_s)

    # -- commands -------------------------------------------------------------------------------

    def arm(self, t_s: float) -> MavResult:
        self.step(t_s)
        if self.armed:
            return MavResult.ACCEPTED
        denial = arming_denial(self.prearm_ok, self._prearm_failure, self.gps_ok, self.landed_state, self.mode)
        if denial is not None:
            return self._deny(denial)
        self.armed = True
        self.land_detector.on_arm(self.t_s)
        self._set_home(self.dyn.estimate.pos_ned_m)
        self.nav.hold_here()
        self._emit(StackEvent(self.t_s, "armed", reason="command", armed=True))
        return MavResult.ACCEPTED

    def disarm(self, t_s: float, force: bool = False) -> MavResult:
        self.step(t_s)
        if not self.armed:
            return MavResult.ACCEPTED
        if self.landed_state is not LandedState.ON_GROUND and not force:
            return self._deny("Disarming denied: not landed")
        self._disarm("force" if force else "command")
        return MavResult.ACCEPTED

    def takeoff(self, t_s: float, altitude_m: float | None = None) -> MavResult:
        """Take off to ``altitude_m`` above home (PX4: NaN/≤0/None → MIS_TAKEOFF_ALT)."""
        self.step(t_s)
        if not self.armed:
            return self._deny("Takeoff denied: disarmed")
        valid = altitude_m is not None and math.isfinite(altitude_m) and altitude_m > 0.0
        p = self.dyn.estimate.pos_ned_m
        home_down_m = self.home_ned_m[2] if self.home_ned_m else 0.0
        if self.profile is Profile.ARDUPILOT:
            if self.mode is not Mode.AP_GUIDED:
                return self._deny("Takeoff denied: not in GUIDED")
            if self.landed_state is not LandedState.ON_GROUND or not valid:
                return self._deny("Takeoff denied: already flying or bad altitude")
            self.nav.takeoff_target_ned_m = (p[0], p[1], home_down_m - float(altitude_m))  # type: ignore[arg-type]
            self._guided_sub = "takeoff"
            return MavResult.ACCEPTED
        alt_m = float(altitude_m) if valid else self.tuning.takeoff_alt_m()  # type: ignore[arg-type]
        self._enter(Mode.AUTO_TAKEOFF, "command")
        self.nav.takeoff_target_ned_m = (p[0], p[1], home_down_m - alt_m)
        return MavResult.ACCEPTED

    def land(self, t_s: float, source: str = "command") -> MavResult:
        return self.set_mode(t_s, Mode.AP_LAND if self.profile is Profile.ARDUPILOT else Mode.AUTO_LAND, source)

    def return_to_launch(self, t_s: float, source: str = "command") -> MavResult:
        return self.set_mode(t_s, Mode.AP_RTL if self.profile is Profile.ARDUPILOT else Mode.AUTO_RTL, source)

    def hold(self, t_s: float, source: str = "command") -> MavResult:
        return self.set_mode(t_s, hold_mode(self.profile), source)

    def set_mode(self, t_s: float, mode: Mode, source: str = "command") -> MavResult:
        """Switch mode on a command (``source`` "command") or a pilot's switch ("pilot")."""
        self.step(t_s)
        if mode.profile is not self.profile:
            return MavResult.UNSUPPORTED
        if mode is self.mode:
            return MavResult.ACCEPTED
        denial = mode_switch_denial(mode, self.gps_ok, self.offboard_setpoint_age_s())
        if denial is not None:
            return self._deny(denial)
        if mode is Mode.AUTO_TAKEOFF:
            return self.takeoff(t_s)
        self._enter(mode, source)
        return MavResult.ACCEPTED

    def reposition(self, t_s: float, pos_ned_m: Vec3) -> MavResult:
        """Fly to ``pos_ned_m`` and hold there (PX4 DO_REPOSITION → HOLD; ArduCopter: in GUIDED)."""
        self.step(t_s)
        if not self.armed or self.landed_state is LandedState.ON_GROUND:
            return self._deny("Reposition denied: not flying")
        if self.profile is Profile.ARDUPILOT:
            if self.mode is not Mode.AP_GUIDED:
                return self._deny("Reposition denied: not in GUIDED")
            self.position_target(t_s, PositionTarget(type_mask=0xDF8, pos_ned_m=pos_ned_m))
            return MavResult.ACCEPTED
        if self.mode is not Mode.AUTO_LOITER:
            self._enter(Mode.AUTO_LOITER, "command")
        self.nav.hold_at(pos_ned_m)
        return MavResult.ACCEPTED

    def set_gripper(self, t_s: float, grab: bool) -> MavResult:
        self.step(t_s)
        self.gripper_closed = grab
        self._emit(StackEvent(self.t_s, "gripper", reason="command", text="grab" if grab else "release"))
        return MavResult.ACCEPTED

    def position_target(self, t_s: float, target: PositionTarget) -> None:
        """A SET_POSITION_TARGET_LOCAL_NED arrived (PX4 tracks them in any mode; ArduCopter only in GUIDED)."""
        self.step(t_s)
        if target.frame not in tuple(Frame):
            return
        if self.profile is Profile.ARDUPILOT and self.mode is not Mode.AP_GUIDED:
            return
        s = self.dyn.estimate
        self._sp = target.resolve(s.pos_ned_m, s.yaw_rad)
        self._sp_t_s = self.t_s
        if self.profile is Profile.ARDUPILOT:
            if self._guided_sub == "takeoff" and self.landed_state is LandedState.ON_GROUND:
                self._statustext("Guided takeoff cancelled by a setpoint", SEVERITY_WARNING)
            self._guided_sub = "setpoint"

    # -- internals ------------------------------------------------------------------------------

    def _emit(self, event: StackEvent) -> None:
        if self._on_event is not None:
            self._on_event(event)

    def _statustext(self, text: str, severity: int = SEVERITY_INFO) -> None:
        self._emit(StackEvent(self.t_s, "statustext", text=text, severity=severity))

    def _deny(self, text: str) -> MavResult:
        self._statustext(text, SEVERITY_WARNING)
        return MavResult.DENIED

    def _set_home(self, pos_ned_m: Vec3) -> None:
        self.home_ned_m = pos_ned_m
        self._emit(StackEvent(self.t_s, "home", reason="set"))

    def _enter(self, mode: Mode, reason: str) -> None:
        self.mode = mode
        self.nav.hold_here()
        if mode.behaviour is Behaviour.LAND:
            self.nav.start_landing()
        elif mode.behaviour is Behaviour.RTL:
            on_ground = self.landed_state is LandedState.ON_GROUND
            self.nav.start_rtl(self.home_ned_m or (0.0, 0.0, 0.0), on_ground)
        elif mode is Mode.AP_GUIDED:
            self._guided_sub = "hold"
        self._emit(StackEvent(self.t_s, "mode", reason=reason, mode=mode))

    def _disarm(self, reason: str) -> None:
        self.armed = False
        self._emit(StackEvent(self.t_s, "armed", reason=reason, armed=False))
        landed = self.landed_state is LandedState.ON_GROUND
        if self.profile is Profile.PX4 and landed and self.mode.behaviour in (Behaviour.LAND, Behaviour.RTL):
            self._enter(Mode.AUTO_LOITER, "landed")

    def _tick(self, t_s: float, dt_s: float) -> None:
        if self.params.version != self._params_version:
            self._apply_params()
        if self.home_ned_m is None and self.gps_ok:
            self._set_home(self.dyn.estimate.pos_ned_m)
        self._failsafes(t_s)
        control = self._control(t_s)
        self.dyn.step(dt_s, control, armed=self.armed)
        self._update_landed_state(t_s)
        self._auto_disarm(t_s)

    def _apply_params(self) -> None:
        """Parameters the physics reads (a PARAM_SET takes effect at the next tick): ArduCopter's shaping limits."""
        self._params_version = self.params.version
        shaping = self.tuning.shaping()
        if shaping is not None:
            self.dyn.set_shaping(*shaping)

    def _failsafes(self, t_s: float) -> None:
        loss = setpoint_loss(self.mode, self._guided_sub, self._sp, t_s - self._sp_t_s, self.tuning.offboard_loss_s())
        if loss is SetpointLoss.OFFBOARD_LOST:
            self._statustext("Failsafe: offboard lost, switching to HOLD", SEVERITY_WARNING)
            self._enter(Mode.AUTO_LOITER, "offboard_loss")
        elif loss is SetpointLoss.GUIDED_STOP:
            self._guided_sub = "hold"
            self.nav.hold_here()

    def _control(self, t_s: float) -> ControlInput:
        pr = self.dyn.params
        yaw_sp: float | None = self.nav.yaw_hold_rad
        yaw_rate_sp: float | None = None
        behaviour = self.mode.behaviour
        takeoff = self._taking_off()
        shaped = False
        if takeoff:
            v, done = self.nav.takeoff_velocity()
            if done:
                self._takeoff_done()
        elif behaviour is Behaviour.OFFBOARD and (self.mode is Mode.OFFBOARD or self._guided_sub == "setpoint"):
            sp = self._sp or ResolvedSetpoint.zero()
            v = sp.velocity(self.dyn.estimate_pos_vel()[0], pr.xy_pos_p, pr.z_pos_p, self.tuning.cruise_mps())
            shaped = sp.is_velocity
            if sp.yaw_rad is not None or sp.yaw_rate_radps is not None:
                yaw_sp, yaw_rate_sp = sp.yaw_rad, sp.yaw_rate_radps
        elif behaviour is Behaviour.LAND:
            v = self.nav.landing_velocity()
        elif behaviour is Behaviour.RTL:
            v = self.nav.rtl_velocity()
        else:
            v = self.nav.hold_velocity()
        return ControlInput(v, yaw_sp, yaw_rate_sp, self._motors_on(t_s, v, takeoff), shaped)

    def _taking_off(self) -> bool:
        """PX4 AUTO.TAKEOFF, or ArduCopter GUIDED in its takeoff sub-mode."""
        in_takeoff = self.mode.behaviour is Behaviour.TAKEOFF or (
            self.mode is Mode.AP_GUIDED and self._guided_sub == "takeoff"
        )
        return in_takeoff and self.nav.takeoff_target_ned_m is not None

    def _motors_on(self, t_s: float, vel_sp_ned_mps: Vec3, takeoff: bool) -> bool:
        """Thrust only when armed; on the ground only after a climb was wanted for SPOOLUP_S."""
        climb = vel_sp_ned_mps[2] <= -CLIMB_INTENT_MPS and (takeoff or self.mode is not Mode.AP_GUIDED)
        return self.spoolup.motors_on(t_s, self.armed, self.landed_state is LandedState.ON_GROUND, climb)

    def _takeoff_done(self) -> None:
        target = self.nav.takeoff_target_ned_m
        assert target is not None
        self.nav.takeoff_target_ned_m = None
        if self.mode is Mode.AP_GUIDED:
            self._guided_sub = "hold"
        else:
            self._statustext("Takeoff complete", SEVERITY_INFO)
            self._enter(Mode.AUTO_LOITER, "takeoff_done")
        self.nav.hold_at(target)

    def _landing_phase(self) -> bool:
        b = self.mode.behaviour
        return b is Behaviour.LAND or (b is Behaviour.RTL and self.nav.rtl_phase == "land")

    def _update_landed_state(self, t_s: float) -> None:
        on_ground = self.dyn.on_ground
        update = self.land_detector.update(t_s, self.landed_state, on_ground, self._taking_off(), self._landing_phase())
        if update.detected == "takeoff":
            self._statustext("Takeoff detected", SEVERITY_INFO)
        self._set_landed_state(update.landed_state)
        if update.detected == "landing":
            self._statustext("Landing detected", SEVERITY_INFO)
            if self.mode.behaviour is Behaviour.OFFBOARD:
                self.nav.hold_here()

    def _set_landed_state(self, state: LandedState) -> None:
        if state is not self.landed_state:
            self.landed_state = state
            self._emit(StackEvent(self.t_s, "landed_state", landed_state=state))

    def _auto_disarm(self, t_s: float) -> None:
        if not self.armed:
            return
        at_touchdown = self.profile is Profile.ARDUPILOT and self._landing_phase()
        disarm = self.land_detector.auto_disarm(t_s, self.landed_state, at_touchdown, self.tuning)
        if disarm is not None:
            self._statustext(disarm.text, SEVERITY_INFO)
            self._disarm(disarm.reason)
