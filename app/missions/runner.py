"""The mission runner: ticks the table on the loop clock.

Each tick builds one immutable ``GuardContext``, then in order:
1. takeover — in a flying state while armed, a pilot mode (POSCTL, ALTCTL, …), or (in the air) any mode other
   than the ones our last command expects once that command had shown in telemetry, means someone else has
   the vehicle: enter MANUAL, stop guiding at once, command nothing (PX4: standby setpoints only);
2. handback — in MANUAL, OFFBOARD selected by the pilot (ArduPilot: GUIDED) resumes the table's choice;
3. the state's transitions in order, first true guard wins;
4. the state's timeout.
A command the vehicle refuses sends the mission to ABORT. Entry actions that command the vehicle never
run while the pilot has control.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from app.clock import Clock, sleep_until
from app.errors import VehicleError
from app.eventlog import EventLog
from app.messages import PILOT_MODES, Autopilot, FlightMode, LandedState
from app.missions.actions import ACTIONS
from app.missions.circle import TrackingErrors
from app.missions.guards import GUARDS, GuardContext
from app.missions.params import MissionParams
from app.missions.table import MissionTable
from app.offboard.setpoint_loop import SetpointLoop
from app.offboard.vehicle import Vehicle


@dataclass
class ModeWatch:
    """Which flight modes our last command allows, and whether telemetry has shown one of them yet."""

    expected: frozenset[FlightMode] | None = None
    since_s: float = 0.0
    confirmed: bool = False

    def expect(self, modes: frozenset[FlightMode], t_s: float) -> None:
        self.expected, self.since_s, self.confirmed = modes, t_s, False

    def clear(self, t_s: float) -> None:
        self.expected, self.since_s, self.confirmed = None, t_s, False


@dataclass
class RunResult:
    outcome: str
    reason: str
    states_visited: list[str] = field(default_factory=list)
    final_state: str = ""


class MissionRunner:
    def __init__(
        self,
        table: MissionTable,
        vehicle: Vehicle,
        setpoints: SetpointLoop,
        clock: Clock,
        events: EventLog,
        tick_rate_hz: float,
        mode_confirm_timeout_s: float,
    ) -> None:
        self.table = table
        self.vehicle = vehicle
        self.setpoints = setpoints
        self.params: MissionParams = table.params
        self.tracking = TrackingErrors()
        self._clock = clock
        self._events = events
        self._period_s = 1.0 / tick_rate_hz
        self._confirm_timeout_s = mode_confirm_timeout_s
        self._watch = ModeWatch()
        self.state = ""
        self._entry_t_s = 0.0
        self._taken_over_from: str | None = None
        self._abort_requested = False
        self._abort_reason = ""
        self._result: RunResult | None = None
        self.states_visited: list[str] = []

    # ---- MissionIO (what actions see) ---------------------------------------------------------

    def now_s(self) -> float:
        return self._clock.now_s()

    def expect_modes(self, modes: frozenset[FlightMode]) -> None:
        self._watch.expect(modes, self._clock.now_s())

    # ---- control --------------------------------------------------------------------------------

    def request_abort(self, reason: str) -> None:
        if not self._abort_requested:
            self._events.write(self._clock.now_s(), "run", event="abort_requested", reason=reason)
            self._abort_reason = reason
        self._abort_requested = True

    @property
    def pilot_has_control(self) -> bool:
        return self._taken_over_from is not None

    async def run(self) -> RunResult:
        await self._enter(self.table.initial, "start")
        next_s = self._clock.now_s()
        while self._result is None:
            next_s = max(next_s + self._period_s, self._clock.now_s())
            await sleep_until(self._clock, next_s)
            await self.tick()
        return self._result

    async def tick(self) -> None:
        now_s = self._clock.now_s()
        spec = self.table.states[self.state]
        tel = self.vehicle.telemetry()
        ctx = GuardContext(
            t_s=now_s,
            state=self.state,
            time_in_state_s=now_s - self._entry_t_s,
            telemetry=tel,
            params=self.params,
            target=self.setpoints.source,
            abort_requested=self._abort_requested,
        )
        mode = tel.mode()
        if spec.flying and tel.is_armed():
            w = self._watch
            # Only a mode sample received after our last mode command can confirm or contradict it
            # (ArduPilot heartbeats come at 1 Hz: the snapshot may still show the mode before it).
            fresh = tel.flight_mode is not None and tel.flight_mode.t_s >= w.since_s
            if fresh and w.expected is not None and not w.confirmed and mode in w.expected:
                w.confirmed = True
            # On the ground the autopilot ends a landing itself (PX4: HOLD as it disarms, the mode seen through
            # CURRENT_MODE before the 1 Hz heartbeat says disarmed): only a pilot mode is a takeover there.
            on_ground = tel.landed_state is not None and tel.landed_state.value == LandedState.ON_GROUND
            unexpected = w.confirmed and w.expected is not None and mode not in w.expected and not on_ground
            if fresh and (mode in PILOT_MODES or unexpected):
                await self._take_over(mode)
                return
            if w.expected is not None and not w.confirmed and now_s - w.since_s > self._confirm_timeout_s:
                await self._enter(
                    self.table.abort_state,
                    f"flight mode {mode.value} never became {'/'.join(sorted(m.value for m in w.expected))}",
                )
                return
        if self._abort_requested and not any(t.when == "abort_requested" for t in spec.transitions):
            # A state that does not handle the request itself goes to ABORT (commands are skipped there
            # while the pilot has control).
            await self._enter(self.table.abort_state, f"abort requested ({self._abort_reason})")
            return
        if spec.manual and mode == FlightMode.OFFBOARD and tel.is_armed():
            await self._hand_back()
            return
        for t in spec.transitions:
            if GUARDS[t.when](ctx):
                why = f"abort requested ({self._abort_reason})" if t.when == "abort_requested" else t.when
                await self._enter(t.to, why)
                return
        if spec.timeout_s is not None and spec.on_timeout and now_s - self._entry_t_s >= spec.timeout_s:
            await self._enter(spec.on_timeout, f"timeout {spec.timeout_s:g} s in {self.state}")

    async def _take_over(self, mode: FlightMode) -> None:
        self._taken_over_from = self.state
        self._watch.clear(self._clock.now_s())
        if self.vehicle.autopilot == Autopilot.PX4:
            self.setpoints.standby()
        else:
            self.setpoints.disengage()
        who = "pilot" if mode in PILOT_MODES else "autopilot"
        await self._enter(self.table.manual_state, f"{who} switched to {mode.value}")

    async def _hand_back(self) -> None:
        manual = self.table.states[self.state]
        src = self._taken_over_from or ""
        dst = manual.resume.get(src) or manual.resume_default or self.table.abort_state
        self._taken_over_from = None
        self.setpoints.disengage()
        await self._enter(dst, f"handed back (OFFBOARD) after takeover in {src}")

    async def _enter(self, name: str, reason: str) -> None:
        now_s = self._clock.now_s()
        self._events.write(now_s, "state", **{"from": self.state or None, "to": name, "reason": reason})
        previous = self.state
        self.state = name
        self._entry_t_s = now_s
        self.states_visited.append(name)
        spec = self.table.states[name]
        if spec.control != "offboard" and not spec.manual:
            self.setpoints.disengage()
        for action in spec.entry:
            a = ACTIONS[action]
            if a.commands_vehicle and self.pilot_has_control:
                self._events.write(self._clock.now_s(), "command", name=action, result="skipped_pilot_control")
                continue
            try:
                await a.fn(self)
                self._events.write(self._clock.now_s(), "command", name=action, result="ok")
            except VehicleError as e:
                self._events.write(self._clock.now_s(), "command", name=action, result=e.result, error=str(e))
                if not spec.abort:
                    await self._enter(self.table.abort_state, f"{action} failed in {name}: {e}")
                    return
        if spec.terminal is not None:
            self._result = RunResult(
                spec.terminal, reason if spec.terminal != "completed" else "completed", self.states_visited, name
            )
            self._events.write(
                self._clock.now_s(), "run", event="finished", outcome=spec.terminal, reason=reason, previous=previous
            )
