"""The mission runner: ticks the table on the loop clock; a state's entry runs as a cancellable task.

Entering a state starts one task (in the runner's TaskGroup) that first leaves offboard if the new state
does not fly offboard and we own it (zero velocity, then HOLD: ``VehicleBoundary.leave_offboard``,
shielded), then runs the state's entry actions in order. The runner keeps ticking meanwhile, so nothing
an action does — an arm retried for seconds, a command waiting for its ACK — can delay a takeover or an
abort. Each tick, in order:

1. takeover — the boundary judges the freshest flight mode (``app.offboard.mode_watch``). A pilot's switch,
   or an autopilot failsafe mode, while the mission flies enters MANUAL at once: the entry task is
   cancelled, guidance stops and nothing is commanded any more (PX4: zero standby setpoints only). The
   boundary makes the same check right before every command and setpoint, so a command an action was
   about to send after the switch is refused rather than sent;
2. a commanded flight mode that never showed in telemetry within ``mode_confirm_timeout_s`` → ABORT;
3. handback — in MANUAL, the pilot selecting OFFBOARD (ArduPilot: GUIDED) resumes the table's choice;
4. the state's transitions in order, first true guard wins (taking one cancels the entry in progress);
5. the state's timeout.

A command the vehicle refuses sends the mission to ABORT. An abort request (signal, ground station) enters
ABORT at once from any state, preempting whatever runs; from then on only ABORT's own stop goes out.

A ground station (``app.gcs.mission``) starts the mission (``request_start``: the initial state waits for
it when one is configured), asks for ``abort``/``hold``/``resume``/``rtl`` (``request``) and authorises the
landing (``authorize_land``, when ``params.land_authorization``). Each answers None or why not, and a
refused request changes nothing; a pilot who has control refuses them all.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field, replace

from pydantic import ValidationError

from app.clock import Clock, sleep_until
from app.errors import CommandRefused, VehicleError
from app.eventlog import EventLog
from app.messages import Autopilot
from app.missions.actions import ACTIONS
from app.missions.circle import CircleMission
from app.missions.estimates import MissionModel, NoEstimates
from app.missions.guards import GUARDS, GuardContext, ready_to_descend
from app.missions.params import MissionParams
from app.missions.table import SUCCESS, MissionTable, StateSpec
from app.offboard.boundary import VehicleBoundary
from app.offboard.mode_watch import Takeover
from app.offboard.setpoint_loop import SetpointLoop

MISSION_MODELS: dict[str, type[MissionModel]] = {"circle": CircleMission}  # pickup: built with settings (main)


def model_name(table: MissionTable) -> str | None:
    """The mission model the table's entry actions work on (``None``: they need none)."""
    models = sorted({m for s in table.states.values() for a in s.entry if (m := ACTIONS[a].model) is not None})
    if len(models) > 1:
        raise ValueError(f"mission {table.mission!r} mixes the actions of the {' and '.join(models)} missions")
    return models[0] if models else None


def mission_model_for(table: MissionTable) -> MissionModel:
    """A fresh model for the table: the one its entry actions work on (a table without one estimates nothing)."""
    name = model_name(table)
    models = [name] if name is not None else []
    if models and models[0] not in MISSION_MODELS:
        raise ValueError(f"mission {table.mission!r} needs its {models[0]} model built by the caller")
    return MISSION_MODELS[models[0]]() if models else NoEstimates()


# After a takeover, OFFBOARD showing up this soon after our own OFFBOARD command is that command landing
# late (MAVSDK retries a command for ~2 s), not the pilot handing back.
LATE_COMMAND_S = 3.0


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
        boundary: VehicleBoundary,
        setpoints: SetpointLoop,
        clock: Clock,
        events: EventLog,
        tick_rate_hz: float,
        mode_confirm_timeout_s: float,
        mission: MissionModel | None = None,
    ) -> None:
        """``mission`` None: the model the table's actions work on (``mission_model_for``)."""
        self.table = table
        self.boundary = boundary
        self.setpoints = setpoints
        self.params: MissionParams = table.params
        self.mission: MissionModel = mission if mission is not None else mission_model_for(table)
        self._clock = clock
        self._events = events
        self._period_s = 1.0 / tick_rate_hz
        self._confirm_timeout_s = mode_confirm_timeout_s
        self.state = ""
        self._entry_t_s = 0.0
        self._flying_since_s: float | None = None  # the first flying state's entry
        self._taken_over_from: str | None = None
        self._held_from: str | None = None  # the state a hold request left
        self._abort_requested = False
        self._abort_reason = ""
        self.start_given = True  # a ground station clears this and sets it on its start command
        self.land_authorized = False  # an operator's authorize_land (needed when params.land_authorization)
        self._awaiting_authorization_noted = False
        self._result: RunResult | None = None
        self._tg: asyncio.TaskGroup | None = None
        self._entry: asyncio.Task[None] | None = None
        self.states_visited: list[str] = []
        boundary.on_takeover = self._take_over

    # ---- MissionIO (what actions see) ---------------------------------------------------------

    def now_s(self) -> float:
        return self._clock.now_s()

    # ---- control --------------------------------------------------------------------------------

    def request_abort(self, reason: str) -> None:
        """Enter ABORT now (from a signal handler or the ground station; runs on the loop's thread)."""
        if self._abort_requested:
            return
        self._events.write(self._clock.now_s(), "run", event="abort_requested", reason=reason)
        self._abort_requested, self._abort_reason = True, reason
        self.boundary.request_abort()
        if self._tg is not None and self._result is None and not self.table.states[self.state].abort:
            self._enter(self.table.abort_state, f"abort requested ({reason})")

    def request_start(self, **param_updates: object) -> str | None:
        """A ground station's start, with optional parameter changes (e.g. ``search_start_ne_m``); None when
        taken, else why not (nothing changes then). Only while waiting in the initial state."""
        if (refusal := self._refusal()) is not None:
            return refusal
        if self.start_given or self.state != self.table.initial:
            return f"already started ({self.state})"
        if param_updates:
            try:
                params = type(self.params).model_validate(self.params.model_dump() | param_updates)
            except ValidationError as e:
                err = e.errors()[0]
                return f"{'.'.join(str(x) for x in err['loc'])}: {err['msg']}"
            self.params = params
        self.start_given = True
        self._events.write(self._clock.now_s(), "run", event="start_given", **param_updates)
        return None

    def authorize_land(self) -> str | None:
        """An operator's landing authorisation: from now on DESCEND may follow TRACK. None when taken."""
        if (refusal := self._refusal()) is not None:
            return refusal
        if not self.params.land_authorization:
            return f"the mission {self.table.mission} lands without authorisation"
        if self.land_authorized:
            return "landing is already authorised"
        self.land_authorized = True
        self._events.write(self._clock.now_s(), "run", event="land_authorized", state=self.state)
        return None

    def _refusal(self) -> str | None:
        """Why no ground-station request can be taken now, or None. The freshest flight mode is judged first: a
        pilot's switch that arrived with the request wins over it."""
        if self._result is not None:
            ended = self.table.states[self.state]
            return "the mission is aborting" if ended.abort else f"the mission has ended ({self._result.outcome})"
        if self._tg is None:
            return "the mission is not running yet"
        self.boundary.check_takeover()
        spec = self.table.states[self.state]
        if self.pilot_has_control or spec.manual:
            return "the pilot has control"
        if spec.abort or self._abort_requested:
            return "the mission is aborting"
        return None

    def request(self, command: str) -> str | None:
        """A ground station's request — ``abort``, ``hold``, ``resume`` or ``rtl`` — on the loop's thread; None
        when it is carried out, else why not (nothing changes then). A pilot who has control, or an ABORT, wins."""
        if (refusal := self._refusal()) is not None:
            return refusal
        spec = self.table.states[self.state]
        if command == "abort":
            self.request_abort("ground station")
            return None
        if command == "resume":
            if self.state != self.table.requests.get("hold"):
                return f"nothing to resume in {self.state}"
            dst = spec.resume.get(self._held_from or "") or spec.resume_default or self.table.abort_state
            self._enter(dst, f"resume requested (held in {self._held_from})")
            return None
        target = self.table.requests.get(command)  # type: ignore[call-overload]
        if target is None:
            return f"the mission {self.table.mission} has no {command!r} request"
        if not spec.flying:
            return f"not flying ({self.state})"
        if self.state == target:
            return f"already in {target}"
        self._held_from = self.state
        self._enter(target, f"{command} requested")
        return None

    @property
    def pilot_has_control(self) -> bool:
        return self._taken_over_from is not None

    async def run(self) -> RunResult:
        async with asyncio.TaskGroup() as tg:
            self._tg = tg
            self._enter(self.table.initial, "start")
            if self._abort_requested:
                self._enter(self.table.abort_state, f"abort requested ({self._abort_reason})")
            next_s = self._clock.now_s()
            while self._result is None:
                next_s = max(next_s + self._period_s, self._clock.now_s())
                await sleep_until(self._clock, next_s)
                self.tick()
            # Leaving the group waits for the final state's entry (ABORT's stop), which is bounded.
        self._tg = None
        return self._result

    def tick(self) -> None:
        if self._result is not None:
            return
        b = self.boundary
        if b.check_takeover() is not None:
            return  # _take_over entered MANUAL
        now_s = self._clock.now_s()
        spec = self.table.states[self.state]
        if b.commanding and not spec.abort and b.watch.overdue(now_s, self._confirm_timeout_s):
            mode = b.telemetry().mode().value
            self._enter(self.table.abort_state, f"flight mode {mode} never became {b.watch.describe_expected()}")
            return
        if spec.manual and b.may_hand_back(LATE_COMMAND_S):
            self._hand_back()
            return
        ctx = GuardContext(
            t_s=now_s,
            state=self.state,
            time_in_state_s=now_s - self._entry_t_s,
            telemetry=b.telemetry(),
            health=b.health(now_s),
            params=self.params,
            estimates=self.mission.snapshot(now_s),
            abort_requested=self._abort_requested,
            start_given=self.start_given,
            land_authorized=self.land_authorized or not self.params.land_authorization,
            geofence_radius_m=b.params.limits.geofence_radius_m,
            airborne_for_s=None if self._flying_since_s is None else now_s - self._flying_since_s,
        )
        if not ctx.land_authorized:
            self._note_awaiting_authorization(ctx, spec)
        for t in spec.transitions:
            if GUARDS[t.when](ctx):
                why = f"abort requested ({self._abort_reason})" if t.when == "abort_requested" else t.when
                self._enter(t.to, why)
                return
        if spec.timeout_s is not None and spec.on_timeout and now_s - self._entry_t_s >= spec.timeout_s:
            self._enter(spec.on_timeout, f"timeout {spec.timeout_s:g} s in {self.state}")

    def _note_awaiting_authorization(self, ctx: GuardContext, spec: StateSpec) -> None:
        """Say once per state when only the operator's authorisation holds the descent back."""
        if self._awaiting_authorization_noted:
            return
        authorized = replace(ctx, land_authorized=True)
        if any(GUARDS[t.when] is ready_to_descend and ready_to_descend(authorized) for t in spec.transitions):
            self._awaiting_authorization_noted = True
            self._events.write(ctx.t_s, "run", event="awaiting_land_authorization", state=self.state)

    def _take_over(self, takeover: Takeover) -> None:
        """The boundary saw someone else switch the mode (from any task): MANUAL now."""
        if self._result is not None or self.table.states[self.state].manual:
            return
        self._taken_over_from = self.state
        if self.boundary.vehicle.autopilot is Autopilot.PX4:
            self.setpoints.standby()
        else:
            self.setpoints.disengage()
        self._enter(self.table.manual_state, takeover.reason)

    def _hand_back(self) -> None:
        manual = self.table.states[self.state]
        src = self._taken_over_from or ""
        dst = manual.resume.get(src) or manual.resume_default or self.table.abort_state
        self._taken_over_from = None
        self.boundary.hand_back()
        self.setpoints.disengage()
        self._enter(dst, f"handed back (OFFBOARD) after takeover in {src}")

    # ---- entering a state -------------------------------------------------------------------------

    def _enter(self, name: str, reason: str) -> None:
        now_s = self._clock.now_s()
        self._events.write(now_s, "state", **{"from": self.state or None, "to": name, "reason": reason})
        previous = self.state
        entry, unfinished = self._entry, None
        if entry is not None and not entry.done() and entry is not asyncio.current_task():
            entry.cancel()
            unfinished = entry
        self.state = name
        self._entry_t_s = now_s
        self._awaiting_authorization_noted = False
        self.states_visited.append(name)
        spec = self.table.states[name]
        self.boundary.flying = spec.flying
        if spec.flying and self._flying_since_s is None:
            self._flying_since_s = now_s
        if spec.control != "offboard" and not spec.manual:
            self.setpoints.disengage()
        if spec.terminal is not None:
            outcome_reason = reason if spec.terminal not in SUCCESS else spec.terminal
            self._result = RunResult(spec.terminal, outcome_reason, self.states_visited, name)
            self._events.write(now_s, "run", event="finished", outcome=spec.terminal, reason=reason, previous=previous)
        assert self._tg is not None
        self._entry = self._tg.create_task(
            self._run_entry(name, spec, previous, unfinished), name=f"mission.entry.{name}"
        )

    async def _run_entry(
        self, name: str, spec: StateSpec, previous: str, unfinished: asyncio.Task[None] | None = None
    ) -> None:
        try:
            if unfinished is not None:
                # the cancelled entry of the state before finishes first: a leave_offboard it began runs to its
                # HOLD (shielded), and only then can this entry tell whether it must take offboard again (eval
                # run 51: SEARCH entered mid-way through TRACK's leave for a takeoff from the water found offboard
                # still ours, the HOLD came after, and the vehicle sat on the water for 235 s)
                await asyncio.wait([unfinished])
            # … and so does a leave begun by an entry further back: that entry's successor, cancelled in turn while
            # it waited, no longer holds this one up (HOLD in DESCEND, resume → TRACK, at once TRACK → DESCEND:
            # DESCEND found offboard still ours and the HOLD went out after it)
            await self.boundary.leave_settled()
            if spec.control != "offboard" and not spec.manual and not spec.abort:
                await self.boundary.leave_offboard(f"{previous} → {name}")
            entry = spec.entry
            if spec.control == "offboard" and not self.boundary.owns_offboard and "start_offboard" not in entry:
                entry = ("start_offboard", *entry)  # e.g. resumed after a handback: take offboard first
            for action in entry:
                try:
                    await ACTIONS[action].fn(self)
                except CommandRefused as e:
                    self._events.write(self._clock.now_s(), "command", name=action, result="refused", error=str(e))
                    return
                except VehicleError as e:
                    self._events.write(self._clock.now_s(), "command", name=action, result=e.result, error=str(e))
                    if not spec.abort and self.state == name:
                        self._enter(self.table.abort_state, f"{action} failed in {name}: {e}")
                    return
                self._events.write(self._clock.now_s(), "command", name=action, result="ok")
        except asyncio.CancelledError:
            self._events.write(self._clock.now_s(), "run", event="entry_cancelled", state=name)
            raise
