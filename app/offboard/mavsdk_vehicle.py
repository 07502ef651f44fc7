"""The ``Vehicle`` protocol on MAVSDK 4 (``mavsdk.asyncio``), for PX4 and ArduPilot.

Only this module imports mavsdk; its errors become ``VehicleError`` here. What it does differently per
autopilot (reference notes §2 and §5):
- rates are requested explicitly for every stream the app uses (ArduPilot sends almost nothing unasked);
  a refused rate request is logged, not fatal — ``wait_ready`` then says what never arrived;
- readiness means a position stream, home, flight mode and armed state — never MAVSDK's health flags,
  which stay false on ArduPilot;
- home comes from the stream or, when that stays silent (ArduPilot), from the one-shot getter;
- offboard is GUIDED on ArduPilot and HOLD is BRAKE; both read through MAVSDK's own mode mapping;
- the flight mode comes with HEARTBEAT, 1 Hz on both autopilots and not faster on request; on PX4 (≥ 1.15)
  CURRENT_MODE is requested at ``telemetry.mode_rate_hz`` and read through MAVLink-direct, so that a
  pilot's switch is seen within a few tens of milliseconds. ArduPilot has no such message: there a switch is
  seen with the next heartbeat (≤ 1 s);
- position (LOCAL_POSITION_NED, read through MAVLink-direct) and attitude are stamped with the time the
  autopilot took them, not when they arrived (``app.offboard.timesync``): a busy companion computer delays
  them, and the guidance, the tracking figures and the state history want where the vehicle *was* then.
  An autopilot clock that does not run in real time (PX4 SITL in lockstep) is detected; its samples keep
  their arrival time.
"""

from __future__ import annotations

import asyncio
import json
import math
import sys
import threading
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk, MavsdkError
from mavsdk.asyncio.autopilot import Autopilot as MavAutopilot
from mavsdk.asyncio.plugins.action import ActionAsync, ActionError
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync, OffboardError, VelocityNedYaw
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.logging import LogLevel, log_subscribe
from mavsdk.plugins.mavlink_direct.mavlink_direct import MavlinkMessage

from app.clock import Clock
from app.errors import VehicleConnectionError, VehicleError
from app.estimators.geodesy import ned_offset_m
from app.eventlog import EventLog
from app.messages import (
    AttitudeEuler,
    Autopilot,
    FlightMode,
    LandedState,
    PositionVelocityNed,
    Stamped,
    TelemetrySnapshot,
    Vec3,
)
from app.offboard.px4_modes import MAV_CMD_SET_MESSAGE_INTERVAL, MSG_ID_CURRENT_MODE, px4_flight_mode
from app.offboard.timesync import RemoteClock
from app.settings import ConnectionSettings, TelemetrySettings

ARM_RETRY_PERIOD_S = 1.0
# PX4 denies arming while pre-arm checks fail; ArduCopter answers MAV_RESULT_FAILED for the same.
ARM_RETRY_RESULTS = frozenset({"COMMAND_DENIED", "FAILED", "BUSY"})
HOME_CHANGE_M = 0.5  # a home estimate that moves less than this is not re-published
# While CURRENT_MODE (≥ 2 Hz on PX4) is this fresh, heartbeat modes are ignored: a heartbeat built just before
# a switch and handled just after its CURRENT_MODE must not read as the pilot handing back.
CURRENT_MODE_FRESH_S = 1.0
SampleListener = Callable[[PositionVelocityNed | AttitudeEuler, float], None]
AUTOPILOT_COMPONENT_ID = 1  # MAV_COMP_ID_AUTOPILOT1: PX4 and ArduPilot


def route_mavsdk_log(path: Path | None) -> None:
    """Send MAVSDK's own log lines (C library threads) to ``path`` instead of the terminal.

    Only warnings and errors are kept when ``path`` is None, printed to stderr.
    """
    lock = threading.Lock()
    out = path.open("a", buffering=1) if path else None

    def on_log(level: LogLevel, message: str, file: str | None, line: int) -> bool:
        text = f"[{level.name}] {message}\n"
        with lock:
            if out is not None:
                out.write(text)
            elif level >= LogLevel.WARN:
                sys.stderr.write("mavsdk: " + text)
        return True  # suppress MAVSDK's default printing

    log_subscribe(on_log)


def _finite(*xs: float) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)


class MavsdkVehicle:
    """A PX4 or ArduPilot vehicle reached through MAVSDK. Build it with ``MavsdkVehicle.connect``."""

    def __init__(
        self,
        mavsdk: Mavsdk,
        system: Any,
        clock: Clock,
        events: EventLog,
        conn: ConnectionSettings,
        tel: TelemetrySettings,
    ) -> None:
        self._mavsdk = mavsdk
        self._system = system
        self._clock = clock
        self._events = events
        self._conn = conn
        self._tel_settings = tel
        self._telemetry = TelemetryAsync(system)
        self._action = ActionAsync(system)
        self._offboard = OffboardAsync(system)
        self._snapshot = TelemetrySnapshot()
        self._autopilot = Autopilot.UNKNOWN
        self._global_pair: tuple[Any, Vec3] | None = None
        self._home_global: Any = None
        self._current_mode_t: float | None = None  # when the last CURRENT_MODE arrived
        self._direct = MavlinkDirectAsync(system)
        # Samples are stamped with the autopilot's own time_boot_ms, mapped onto the loop clock.
        self._position_clock = RemoteClock()
        self._attitude_clock = RemoteClock()
        self._sample_listeners: list[SampleListener] = []

    # ---- construction -------------------------------------------------------------------------

    @classmethod
    @asynccontextmanager
    async def connect(
        cls, url: str, clock: Clock, events: EventLog, conn: ConnectionSettings, tel: TelemetrySettings
    ) -> AsyncIterator[MavsdkVehicle]:
        """Connect to ``url`` and wait for an autopilot heartbeat; destroys MAVSDK on exit."""
        config = Configuration.create_with_component_type(ComponentType.COMPANION_COMPUTER)
        async with Mavsdk(config) as mavsdk:
            try:
                await mavsdk.add_any_connection(url)
            except MavsdkError as e:
                raise VehicleConnectionError("connect", "invalid connection", f"{url}: {e}") from e
            system = await mavsdk.first_autopilot(timeout_s=conn.discover_timeout_s)
            if system is None:
                raise VehicleConnectionError(
                    "connect", "no autopilot", f"no heartbeat on {url} within {conn.discover_timeout_s:.0f} s"
                )
            vehicle = cls(mavsdk, system, clock, events, conn, tel)
            kind = await system.autopilot_type()
            vehicle._autopilot = {MavAutopilot.PX4: Autopilot.PX4, MavAutopilot.ARDUPILOT: Autopilot.ARDUPILOT}.get(
                kind, Autopilot.UNKNOWN
            )
            events.write(clock.now_s(), "vehicle", event="connected", url=url, autopilot=vehicle._autopilot.value)
            yield vehicle

    @property
    def autopilot(self) -> Autopilot:
        return self._autopilot

    # ---- telemetry ----------------------------------------------------------------------------

    def telemetry(self) -> TelemetrySnapshot:
        return self._snapshot

    def _update(self, **fields: Any) -> None:
        self._snapshot = replace(self._snapshot, **fields)

    async def run(self) -> None:
        """Request rates, then consume every stream until cancelled."""
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self._request_rates(), name="vehicle.rates")
            tg.create_task(self._consume_position(), name="vehicle.position")
            tg.create_task(self._consume_attitude(), name="vehicle.attitude")
            tg.create_task(self._consume_flight_mode(), name="vehicle.flight_mode")
            tg.create_task(self._consume_armed(), name="vehicle.armed")
            tg.create_task(self._consume_landed(), name="vehicle.landed_state")
            tg.create_task(self._consume_home(), name="vehicle.home")
            tg.create_task(self._consume_global(), name="vehicle.global_position")
            if self._autopilot is Autopilot.PX4 and self._tel_settings.mode_rate_hz > 0.0:
                tg.create_task(self._consume_current_mode(), name="vehicle.current_mode")

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
        async for msg in self._direct.subscribe_message("LOCAL_POSITION_NED"):
            received_s = self._clock.now_s()
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
        async for a in self._telemetry.subscribe_attitude_euler():
            received_s = self._clock.now_s()
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
        async for m in self._telemetry.subscribe_flight_mode():
            t = self._current_mode_t
            if t is not None and self._clock.now_s() - t < CURRENT_MODE_FRESH_S:
                continue
            self._set_flight_mode(FlightMode[m.name] if m.name in FlightMode.__members__ else FlightMode.UNKNOWN)

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
        async for msg in direct.subscribe_message("CURRENT_MODE"):
            try:
                custom_mode = int(json.loads(msg.fields_json)["custom_mode"])
            except (KeyError, TypeError, ValueError):
                continue
            self._current_mode_t = self._clock.now_s()
            self._set_flight_mode(px4_flight_mode(custom_mode))

    def _set_flight_mode(self, mode: FlightMode) -> None:
        """A fresh flight-mode sample, from HEARTBEAT or CURRENT_MODE (whichever comes first)."""
        previous = self._snapshot.mode()
        self._update(flight_mode=Stamped(self._clock.now_s(), mode))
        if mode != previous:
            self._events.write(self._clock.now_s(), "vehicle", event="flight_mode", mode=mode.value)

    async def _consume_armed(self) -> None:
        async for armed in self._telemetry.subscribe_armed():
            previous = self._snapshot.armed
            self._update(armed=Stamped(self._clock.now_s(), bool(armed)))
            if previous is None or previous.value != bool(armed):
                self._events.write(self._clock.now_s(), "vehicle", event="armed", armed=bool(armed))

    async def _consume_landed(self) -> None:
        async for s in self._telemetry.subscribe_landed_state():
            state = LandedState[s.name] if s.name in LandedState.__members__ else LandedState.UNKNOWN
            self._update(landed_state=Stamped(self._clock.now_s(), state))

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

    # ---- commands -----------------------------------------------------------------------------

    async def _call(self, name: str, coro: Awaitable[Any]) -> None:
        try:
            await coro
        except (ActionError, OffboardError) as e:
            raise VehicleError(name, e.result.name, str(e)) from e
        except MavsdkError as e:
            raise VehicleError(name, "ERROR", str(e)) from e

    async def arm(self) -> None:
        """Arm; a refusal is retried (pre-arm checks may still be running) until the retry timeout."""
        deadline_s = self._clock.now_s() + self._conn.command_retry_timeout_s
        while True:
            try:
                await self._call("arm", self._action.arm())
                return
            except VehicleError as e:
                if e.result not in ARM_RETRY_RESULTS or self._clock.now_s() + ARM_RETRY_PERIOD_S > deadline_s:
                    raise
            await self._clock.sleep(ARM_RETRY_PERIOD_S)

    async def takeoff(self, altitude_m: float) -> None:
        # PX4: writes MIS_TAKEOFF_ALT; ArduPilot: MAVSDK keeps it and sends it as NAV_TAKEOFF param 7.
        await self._call("set_takeoff_altitude", self._action.set_takeoff_altitude(altitude_m))
        await self._call("takeoff", self._action.takeoff())

    async def start_offboard(self, yaw_rad: float) -> None:
        await self.set_velocity_ned((0.0, 0.0, 0.0), yaw_rad)
        await self._call("offboard_start", self._offboard.start())

    async def set_velocity_ned(self, vel_ned_mps: Vec3, yaw_rad: float) -> None:
        sp = VelocityNedYaw(vel_ned_mps[0], vel_ned_mps[1], vel_ned_mps[2], math.degrees(yaw_rad))
        await self._call("set_velocity_ned", self._offboard.set_velocity_ned(sp))

    async def hold(self) -> None:
        await self._call("hold", self._action.hold())

    async def stop_offboard(self) -> None:
        """Zero velocity, then HOLD (ArduPilot: BRAKE). Falls back to ``hold`` if offboard.stop fails."""
        yaw_rad = self._snapshot.attitude.yaw_rad if self._snapshot.attitude else 0.0
        try:
            await self.set_velocity_ned((0.0, 0.0, 0.0), yaw_rad)
            await self._call("offboard_stop", self._offboard.stop())
        except VehicleError:
            await self.hold()

    async def land(self) -> None:
        await self._call("land", self._action.land())
