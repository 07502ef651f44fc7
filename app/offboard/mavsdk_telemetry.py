"""MAVSDK 4 telemetry for the ``Vehicle`` adapter: streams in, one snapshot out (PX4 and ArduPilot).

What it does differently per autopilot (reference notes §2 and §5):
- rates are requested explicitly for every stream the app uses (ArduPilot sends almost nothing unasked);
  a refused rate request is logged, not fatal — ``wait_ready`` then says what never arrived;
- readiness means a position stream, home, flight mode and armed state — never MAVSDK's health flags,
  which stay false on ArduPilot;
- home comes from the stream or, when that stays silent (ArduPilot), from the one-shot getter;
- the flight mode comes with HEARTBEAT, 1 Hz on both autopilots and not faster on request; on PX4 (≥ 1.15)
  CURRENT_MODE is requested at ``telemetry.mode_rate_hz`` and read through MAVLink-direct, so that a
  pilot's switch is seen within a few tens of milliseconds. ArduPilot has no such message: there a switch is
  seen with the next heartbeat (≤ 1 s);
- position (LOCAL_POSITION_NED, read through MAVLink-direct) and attitude are stamped with the time the
  autopilot took them, not when they arrived (``app.offboard.timesync``): a busy companion computer delays
  them, and the guidance, the tracking figures and the state history want where the vehicle *was* then.
  An autopilot clock that does not run in real time (PX4 SITL in lockstep) is detected; its samples keep
  their arrival time;
- every sample is stamped when it *arrived*, in MAVSDK's callback thread (``stamped``), not when the event
  loop got round to reading it: a backlog of flight-mode or armed samples does not read as fresh;
- the autopilot's HEARTBEAT is followed on its own (``heartbeat_t_s``), so a lost link shows as an ageing
  heartbeat; a stream whose subscription ends is logged (``stream_ended``) and then ages into the guards.
"""

from __future__ import annotations

import asyncio
import functools
import json
import math
from collections.abc import AsyncIterator, Awaitable, Callable
from dataclasses import replace
from typing import Any

from mavsdk.asyncio import MavsdkError
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.mavlink_direct.mavlink_direct import MavlinkMessage

from app.clock import Clock
from app.errors import VehicleConnectionError
from app.estimators.geodesy import ned_offset_m
from app.eventlog import EventLog
from app.messages import (
    AttitudeEuler,
    Autopilot,
    BatteryLevel,
    FlightMode,
    LandedState,
    PositionVelocityNed,
    Stamped,
    TelemetrySnapshot,
    Vec3,
)
from app.offboard.px4_modes import MAV_CMD_SET_MESSAGE_INTERVAL, MSG_ID_CURRENT_MODE, px4_flight_mode
from app.offboard.timesync import RemoteClock
from app.offboard.vehicle import SampleListener
from app.settings import TelemetrySettings

HOME_CHANGE_M = 0.5  # a home estimate that moves less than this is not re-published
# While CURRENT_MODE (≥ 2 Hz on PX4) is this fresh, heartbeat modes are ignored: a heartbeat built just before
# a switch and handled just after its CURRENT_MODE must not read as the pilot handing back.
CURRENT_MODE_FRESH_S = 1.0
AUTOPILOT_COMPONENT_ID = 1  # MAV_COMP_ID_AUTOPILOT1: PX4 and ArduPilot


def _finite(*xs: float) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)


async def stamped(
    subscribe: Callable[[Callable[[Any, Any], None]], Any], unsubscribe: Callable[[Any], None]
) -> AsyncIterator[tuple[Any, float]]:
    """A MAVSDK subscription (the synchronous plugin's ``subscribe_x``/``unsubscribe_x``) as ``(item, t_s)``.

    ``t_s`` is the loop clock read in MAVSDK's callback thread as the item arrives (``loop.time()`` is the
    monotonic clock and may be read from any thread), so items that wait in the queue keep their arrival
    time. The asyncio wrappers stamp nothing; their queue is unbounded, like this one.
    """
    loop = asyncio.get_running_loop()
    queue: asyncio.Queue[tuple[Any, float]] = asyncio.Queue()

    def callback(data: Any, _user_data: Any) -> None:
        loop.call_soon_threadsafe(queue.put_nowait, (data, loop.time()))

    handle = subscribe(callback)
    try:
        while True:
            yield await queue.get()
    finally:
        unsubscribe(handle)


class MavsdkTelemetry:
    """Every stream the app uses, consumed into a ``TelemetrySnapshot`` (``run`` until cancelled)."""

    def __init__(
        self, system: Any, autopilot: Autopilot, clock: Clock, events: EventLog, settings: TelemetrySettings
    ) -> None:
        self._system = system
        self._autopilot = autopilot
        self._clock = clock
        self._events = events
        self._tel_settings = settings
        self._telemetry = TelemetryAsync(system)
        self._direct = MavlinkDirectAsync(system)
        self._tel_sync = self._telemetry._plugin  # the same plugins, subscribed with our own stamping callback
        self._direct_sync = self._direct._plugin
        self._snapshot = TelemetrySnapshot()
        self._global_pair: tuple[Any, Vec3] | None = None
        self._home_global: Any = None
        self._current_mode_t: float | None = None  # when the last CURRENT_MODE arrived
        # Samples are stamped with the autopilot's own time_boot_ms, mapped onto the loop clock.
        self._position_clock = RemoteClock()
        self._attitude_clock = RemoteClock()
        self._sample_listeners: list[SampleListener] = []
        self._sysid: int | None = None

    def snapshot(self) -> TelemetrySnapshot:
        return self._snapshot

    def _update(self, **fields: Any) -> None:
        self._snapshot = replace(self._snapshot, **fields)

    async def run(self) -> None:
        """Request rates, then consume every stream until cancelled."""
        streams: list[tuple[str, Callable[[], Awaitable[None]]]] = [
            ("position", self._consume_position),
            ("attitude", self._consume_attitude),
            ("flight_mode", self._consume_flight_mode),
            ("armed", self._consume_armed),
            ("landed_state", self._consume_landed),
            ("home", self._consume_home),
            ("global_position", self._consume_global),
            ("heartbeat", self._consume_heartbeat),
            ("battery", self._consume_battery),
        ]
        if self._autopilot is Autopilot.PX4 and self._tel_settings.mode_rate_hz > 0.0:
            streams.append(("current_mode", self._consume_current_mode))
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self._request_rates(), name="vehicle.rates")
            for name, consume in streams:
                tg.create_task(self._watch_stream(name, consume), name=f"vehicle.{name}")

    async def _watch_stream(self, name: str, consume: Callable[[], Awaitable[None]]) -> None:
        """Run one consumer; if its subscription ever ends, say so (its samples then age into the guards)."""
        await consume()
        self._events.write(self._clock.now_s(), "vehicle", event="stream_ended", stream=name)

    def _direct_messages(self, name: str) -> AsyncIterator[tuple[MavlinkMessage, float]]:
        d = self._direct_sync
        return stamped(functools.partial(d.subscribe_message, name), d.unsubscribe_message)

    async def _consume_heartbeat(self) -> None:
        async for msg, received_s in self._direct_messages("HEARTBEAT"):
            if msg.component_id == AUTOPILOT_COMPONENT_ID and msg.system_id == await self._system_id():
                self._update(heartbeat_t_s=received_s)

    async def _system_id(self) -> int:
        if self._sysid is None:
            self._sysid = int(await self._system.get_system_id())
        return self._sysid

    async def _request_rates(self) -> None:
        t = self._tel_settings
        requests: list[tuple[str, Callable[[float], Awaitable[Any]], float]] = [
            ("position_velocity_ned", self._telemetry.set_rate_position_velocity_ned, t.position_rate_hz),
            ("attitude_euler", self._telemetry.set_rate_attitude_euler, t.attitude_rate_hz),
            ("position", self._telemetry.set_rate_position, t.global_position_rate_hz),
            ("landed_state", self._telemetry.set_rate_landed_state, t.status_rate_hz),
            ("home", self._telemetry.set_rate_home, t.status_rate_hz),
        ]

        async def one(name: str, setter: Callable[[float], Awaitable[Any]], rate_hz: float) -> None:
            try:
                await setter(rate_hz)
                self._events.write(self._clock.now_s(), "vehicle", event="rate", stream=name, rate_hz=rate_hz)
            except MavsdkError as e:
                self._events.write(
                    self._clock.now_s(), "vehicle", event="rate_refused", stream=name, rate_hz=rate_hz, error=str(e)
                )

        await asyncio.gather(*(one(*r) for r in requests))

    async def _consume_position(self) -> None:
        """LOCAL_POSITION_NED through MAVLink-direct: MAVSDK's PositionVelocityNed drops ``time_boot_ms``."""
        async for msg, received_s in self._direct_messages("LOCAL_POSITION_NED"):
            if msg.component_id != AUTOPILOT_COMPONENT_ID:
                continue
            try:
                f = json.loads(msg.fields_json)
                p = (float(f["x"]), float(f["y"]), float(f["z"]))
                v = (float(f["vx"]), float(f["vy"]), float(f["vz"]))
                boot_ms = int(f["time_boot_ms"])
            except (KeyError, TypeError, ValueError):
                continue
            if not _finite(*p, *v):
                continue
            t_s = self._position_clock.stamp(boot_ms / 1e3, received_s) if boot_ms > 0 else received_s
            self._publish(PositionVelocityNed(t_s, p, v), received_s)

    async def _consume_attitude(self) -> None:
        t = self._tel_sync
        async for a, received_s in stamped(t.subscribe_attitude_euler, t.unsubscribe_attitude_euler):
            t_s = self._attitude_clock.stamp(a.timestamp_us / 1e6, received_s) if a.timestamp_us > 0 else received_s
            rpy = (math.radians(a.roll_deg), math.radians(a.pitch_deg), math.radians(a.yaw_deg))
            self._publish(AttitudeEuler(t_s, *rpy), received_s)

    def add_sample_listener(self, listener: SampleListener) -> None:
        """Call ``listener(sample, received_s)`` for every position and attitude sample, in arrival order.

        The snapshot keeps only the latest; a state history wants them all (several can arrive at once).
        """
        self._sample_listeners.append(listener)

    def _publish(self, sample: PositionVelocityNed | AttitudeEuler, received_s: float) -> None:
        if isinstance(sample, PositionVelocityNed):
            self._update(pos_vel=sample)
        else:
            self._update(attitude=sample)
        for listener in self._sample_listeners:
            listener(sample, received_s)

    def link_stats(self) -> dict[str, float | str | None]:
        """Which time position and attitude samples carry, and how late they reached the app."""
        return self._position_clock.summary("position") | self._attitude_clock.summary("attitude")

    async def _consume_flight_mode(self) -> None:
        t = self._tel_sync
        async for m, received_s in stamped(t.subscribe_flight_mode, t.unsubscribe_flight_mode):
            last = self._current_mode_t
            if last is not None and received_s - last < CURRENT_MODE_FRESH_S:
                continue
            mode = FlightMode[m.name] if m.name in FlightMode.__members__ else FlightMode.UNKNOWN
            self._set_flight_mode(mode, received_s)

    async def _consume_current_mode(self) -> None:
        """PX4's CURRENT_MODE: asked for at ``mode_rate_hz``; refused (PX4 < 1.15) → the heartbeat alone."""
        direct = self._direct
        rate_hz = self._tel_settings.mode_rate_hz
        try:
            sysid = await self._system.get_system_id()
            fields: dict[str, float] = {"target_system": sysid, "target_component": 1, "confirmation": 0}
            fields |= {"command": MAV_CMD_SET_MESSAGE_INTERVAL, "param1": MSG_ID_CURRENT_MODE, "param2": 1e6 / rate_hz}
            fields |= dict.fromkeys(("param3", "param4", "param5", "param6", "param7"), 0)
            command = MavlinkMessage("COMMAND_LONG", 0, 0, sysid, 1, json.dumps(fields))
            ack = json.loads((await direct.send_command(command)).fields_json)
            if ack.get("result") != 0:
                raise MavsdkError(f"SET_MESSAGE_INTERVAL answered MAV_RESULT {ack.get('result')}")
        except (MavsdkError, ValueError) as e:
            self._events.write(
                self._clock.now_s(),
                "vehicle",
                event="rate_refused",
                stream="current_mode",
                rate_hz=rate_hz,
                error=str(e),
            )
            return
        self._events.write(self._clock.now_s(), "vehicle", event="rate", stream="current_mode", rate_hz=rate_hz)
        async for msg, received_s in self._direct_messages("CURRENT_MODE"):
            try:
                custom_mode = int(json.loads(msg.fields_json)["custom_mode"])
            except (KeyError, TypeError, ValueError):
                continue
            self._current_mode_t = received_s
            self._set_flight_mode(px4_flight_mode(custom_mode), received_s)

    def _set_flight_mode(self, mode: FlightMode, received_s: float) -> None:
        """A flight-mode sample, from HEARTBEAT or CURRENT_MODE (whichever comes first), as it arrived."""
        previous = self._snapshot.mode()
        self._update(flight_mode=Stamped(received_s, mode))
        if mode != previous:
            self._events.write(received_s, "vehicle", event="flight_mode", mode=mode.value)

    async def _consume_armed(self) -> None:
        t = self._tel_sync
        async for armed, received_s in stamped(t.subscribe_armed, t.unsubscribe_armed):
            previous = self._snapshot.armed
            self._update(armed=Stamped(received_s, bool(armed)))
            if previous is None or previous.value != bool(armed):
                self._events.write(received_s, "vehicle", event="armed", armed=bool(armed))

    async def _consume_landed(self) -> None:
        t = self._tel_sync
        async for s, received_s in stamped(t.subscribe_landed_state, t.unsubscribe_landed_state):
            state = LandedState[s.name] if s.name in LandedState.__members__ else LandedState.UNKNOWN
            self._update(landed_state=Stamped(received_s, state))

    async def _consume_battery(self) -> None:
        """BATTERY_STATUS (~1 Hz): for the operator, not for any guard."""
        async for b in self._telemetry.subscribe_battery():
            volts = b.voltage_v if _finite(b.voltage_v) and b.voltage_v > 0.0 else None
            pct = b.remaining_percent
            frac = min(max(pct / 100.0, 0.0), 1.0) if _finite(pct) and pct >= 0.0 else None
            self._update(battery=Stamped(self._clock.now_s(), BatteryLevel(volts, frac)))

    async def _consume_home(self) -> None:
        async for h in self._telemetry.subscribe_home():
            self._set_home(h)

    async def _consume_global(self) -> None:
        async for p in self._telemetry.subscribe_position():
            if _finite(p.latitude_deg, p.longitude_deg, p.absolute_altitude_m) and self._snapshot.pos_vel:
                # A global fix paired with the local position received just before it.
                self._global_pair = (p, self._snapshot.pos_vel.pos_ned_m)
                if self._home_global is not None:
                    self._set_home(self._home_global)

    def _set_home(self, h: Any) -> bool:
        """Home in the local NED frame.

        From the global home and a (global, local) position pair when there is one: ArduCopter's
        HOME_POSITION carries x = y = z = 0 because its local origin is the EKF origin, not home. Else
        from HOME_POSITION's local fields (PX4 fills them).
        """
        home: Vec3 | None = None
        if _finite(h.latitude_deg, h.longitude_deg, h.absolute_altitude_m):
            self._home_global = h
            if self._global_pair is not None:
                g, local = self._global_pair
                d = ned_offset_m(
                    g.latitude_deg, g.longitude_deg, g.absolute_altitude_m,
                    h.latitude_deg, h.longitude_deg, h.absolute_altitude_m,
                )  # fmt: skip
                home = (local[0] + d[0], local[1] + d[1], local[2] + d[2])
        if home is None and self._autopilot != Autopilot.ARDUPILOT:
            if _finite(h.local_north_m, h.local_east_m, h.local_down_m):
                home = (h.local_north_m, h.local_east_m, h.local_down_m)
        if home is None:
            return False
        old = self._snapshot.home_ned_m
        if old is None or max(abs(a - b) for a, b in zip(old, home, strict=True)) > HOME_CHANGE_M:
            self._update(home_ned_m=home)
            self._events.write(self._clock.now_s(), "vehicle", event="home", home_ned_m=list(home))
        return True

    async def wait_ready(self, timeout_s: float) -> None:
        deadline_s = self._clock.now_s() + timeout_s
        next_home_poll_s = self._clock.now_s() + 2.0
        while True:
            s = self._snapshot
            missing = [
                name
                for name, value in (
                    ("position stream", s.pos_vel),
                    ("home position", s.home_ned_m),
                    ("flight mode", s.flight_mode),
                    ("armed state", s.armed),
                )
                if value is None
            ]
            if not missing:
                return
            now_s = self._clock.now_s()
            if now_s >= deadline_s:
                raise VehicleConnectionError(
                    "wait_ready", "timeout", f"no {', '.join(missing)} within {timeout_s:.0f} s"
                )
            if s.home_ned_m is None and now_s >= next_home_poll_s:
                # ArduPilot: the home stream can stay silent while the one-shot getter works.
                next_home_poll_s = now_s + 2.0
                try:
                    self._set_home(await self._telemetry.home())
                except MavsdkError:
                    pass
            await self._clock.sleep(0.05)
