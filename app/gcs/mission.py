"""The mission's end of the ground station: commands into the runner; state, telemetry and events out.

``MissionBridge`` owns a ``GroundLink`` and a running mission's ``MissionRunner``:

- commands (on the event loop, through the link's dedupe and strict parsing): ``start`` → the runner's
  ``request_start`` (only while waiting in WAIT_FOR_START; ``start_ne_m`` / ``search_radius_m`` / ``drift_ne_mps``
  become the mission's ``search_start_ne_m`` / ``search_max_radius_m`` / ``search_drift_ne_mps``,
  validated like the mission file); ``abort``,
  ``hold``, ``resume``, ``rtl`` → ``request``; ``authorize_land`` → ``authorize_land``. Each is accepted or
  rejected with the runner's reason, and a rejected one changes nothing. A pilot who has control rejects
  them all — checked by the runner when the command is handled, on the freshest mode the boundary knows.
- ``state`` (retained): the mission state, the flight mode, armed, the outcome and the last error, whenever
  they change (checked at the telemetry rate, and at once on every state change);
- ``telemetry`` at ``telemetry_rate_hz``: position, height above the sea, the target estimate and covariance;
- ``events``: the event log's ``state``, ``run``, ``gcs`` and ``vehicle`` records (state changes, start,
  landing authorisation, commands, flight mode and link changes, the end), as they are written; and, from the
  estimates at the telemetry rate, ``target_found`` / ``target_lost`` and ``radar_calibration`` (its result).

With a ground station configured the mission waits in its initial state for ``start`` (``runner.start_given``
is cleared when the bridge is made). The link's loss does not stop the mission: it flies on, and the link
reconnects by itself.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from typing import Any

from app.clock import Clock
from app.eventlog import EventLog
from app.gcs.config import GcsSettings
from app.gcs.link import GroundLink
from app.gcs.protocol import Abort, AuthorizeLand, Battery, Command, Event, Hold, Resume, Rtl, Start, State, Telemetry
from app.gcs.protocol import TargetEstimate as TargetPayload
from app.missions.runner import MissionRunner
from app.missions.table import SUCCESS

EVENT_KINDS = ("state", "run", "gcs", "vehicle")
FINAL_FLUSH_S = 2.0  # at the end, wait this long at most for the final state and events to go out


class MissionBridge:
    def __init__(self, settings: GcsSettings, runner: MissionRunner, clock: Clock, events: EventLog) -> None:
        self.runner = runner
        self._clock = clock
        self._events = events
        self.link = GroundLink(settings, self.handle, clock=clock)
        self._period_s = 1.0 / settings.telemetry_rate_hz
        self._loop: asyncio.AbstractEventLoop | None = None
        self._outcome: str | None = None
        self._last_error: str | None = None
        self._target_found = False
        self._calibration: object = None
        runner.start_given = False  # wait for the ground station's start
        events.subscribe(EVENT_KINDS, self._on_record)

    # ---- commands -----------------------------------------------------------------------------------

    def handle(self, command: Command) -> str | None:
        """The runner's answer to one command (None: accepted); logged as a ``gcs`` record either way."""
        r = self.runner
        reason: str | None
        match command:
            case Start():
                updates: dict[str, Any] = {}
                if command.start_ne_m is not None:
                    updates["search_start_ne_m"] = command.start_ne_m
                if command.search_radius_m is not None:
                    updates["search_max_radius_m"] = command.search_radius_m
                if command.drift_ne_mps is not None:
                    updates["search_drift_ne_mps"] = command.drift_ne_mps
                reason = r.request_start(**updates)
            case Abort() | Hold() | Resume() | Rtl():
                reason = r.request(command.cmd)
            case AuthorizeLand():
                reason = r.authorize_land()
        self._events.write(
            self._clock.now_s(), "gcs", cmd=command.cmd, id=command.id, accepted=reason is None, reason=reason
        )
        return reason

    # ---- state, telemetry, events -------------------------------------------------------------------

    def state(self) -> State:
        t = self.runner.boundary.telemetry()
        return State(
            mission_state=self.runner.state or "STARTING",
            flight_mode=t.mode().value,
            armed=t.is_armed(),
            outcome=self._outcome,
            last_error=self._last_error,
        )

    def telemetry(self) -> Telemetry | None:
        t_s = self._clock.now_s()
        tel = self.runner.boundary.telemetry()
        pv = tel.pos_vel
        if pv is None:
            return None
        snap = self.runner.mission.snapshot(t_s)
        target = None
        if snap.target is not None and snap.target_cov_ne_m2 is not None:
            p, v, c = snap.target.pos_ned_m, snap.target.vel_ned_mps, snap.target_cov_ne_m2
            target = TargetPayload(position_ne_m=(p[0], p[1]), velocity_ne_mps=(v[0], v[1]), covariance_ne_m2=c)
        battery = None
        if tel.battery is not None:
            b = tel.battery.value
            battery = Battery(voltage_v=b.voltage_v, remaining_frac=b.remaining_frac)
        return Telemetry(
            t_s=pv.t_s,
            position_ned_m=pv.pos_ned_m,
            height_above_sea_m=snap.height_above_sea_m,
            target=target,
            battery=battery,
        )

    def _on_record(self, record: dict[str, Any]) -> None:
        """From the event log, on whichever thread wrote the record: onto the loop."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed meanwhile
                loop.call_soon_threadsafe(self._publish_record, record)

    def _publish_record(self, record: dict[str, Any]) -> None:
        kind = record["kind"]
        fields = {k: v for k, v in record.items() if k not in ("t_s", "kind")}
        if kind == "state":
            name = "state_changed"
            self.link.publish_state(self.state())
        elif kind == "run":
            name = str(fields.pop("event", "run"))
            if name == "finished":
                self._outcome = str(fields.get("outcome"))
                if self._outcome not in SUCCESS:
                    self._last_error = str(fields.get("reason"))
                self.link.publish_state(self.state())
        elif kind == "vehicle":
            name = str(fields.pop("event", "vehicle"))
            self.link.publish_state(self.state())
        else:
            name = "command"
        self.link.publish_event(Event(t_s=record["t_s"], kind=name, fields=_json_safe(fields)))

    # ---- tasks --------------------------------------------------------------------------------------

    async def run(self) -> None:
        """The link and the publisher, until cancelled."""
        self._loop = asyncio.get_running_loop()
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self.link.run(), name="gcs.link")
            tg.create_task(self._publish(), name="gcs.publish")

    async def _publish(self) -> None:
        while True:
            self.link.publish_state(self.state())
            telemetry = self.telemetry()
            if telemetry is not None:
                self.link.publish_telemetry(telemetry)
            self._notable(telemetry)
            await self._clock.sleep(self._period_s)

    def _notable(self, telemetry: Telemetry | None) -> None:
        """Events the estimates tell, checked at the telemetry rate: the object found or lost, the radar's
        calibration result."""
        t_s = self._clock.now_s()
        found = telemetry is not None and telemetry.target is not None
        if found != self._target_found:
            self._target_found = found
            fields: dict[str, Any] = {"state": self.runner.state}
            if telemetry is not None and telemetry.target is not None:
                fields["position_ne_m"] = list(telemetry.target.position_ne_m)
            self.link.publish_event(Event(t_s=t_s, kind="target_found" if found else "target_lost", fields=fields))
        calibration = self.runner.mission.summary().get("radar_calibration")
        if calibration is not None and calibration != self._calibration:
            self._calibration = calibration
            self.link.publish_event(Event(t_s=t_s, kind="radar_calibration", fields={"result": str(calibration)}))

    async def finish(self) -> None:
        """After the mission: the final state and the last events out (bounded by ``FINAL_FLUSH_S``)."""
        self.link.publish_state(self.state())
        await self.link.flush(FINAL_FLUSH_S)


def _json_safe(fields: dict[str, Any]) -> dict[str, Any]:
    """Event fields as JSON values: non-finite numbers become null, anything else unknown its text."""
    out: dict[str, Any] = {}
    for k, v in fields.items():
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = None
        elif v is None or isinstance(v, str | int | float | bool | list | dict):
            out[k] = v
        else:
            out[k] = str(v)
    return out
