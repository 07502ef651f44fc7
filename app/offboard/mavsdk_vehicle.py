"""The ``Vehicle`` protocol on MAVSDK 4 (``mavsdk.asyncio``), for PX4 and ArduPilot.

Only this module and ``app.offboard.mavsdk_telemetry`` (the streams) import mavsdk; its errors become
``VehicleError`` here. Commands differ per autopilot only through MAVSDK's own mapping (reference notes
§2 and §5): offboard is GUIDED on ArduPilot and HOLD is BRAKE. Arming is retried while pre-arm checks run.

Setpoints go out on a dedicated one-thread executor with a timeout (``connection.setpoint_timeout_s``), never
queued behind a slow command in the default executor. The setpoint watchdog runs in a thread of its own
(``WatchdogThread``) and, when it fires, calls MAVSDK's synchronous offboard plugin from that thread: the
event loop is not needed to stop the vehicle.
"""

from __future__ import annotations

import asyncio
import math
import sys
import threading
from collections.abc import AsyncIterator, Awaitable
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk, MavsdkError
from mavsdk.asyncio.autopilot import Autopilot as MavAutopilot
from mavsdk.asyncio.plugins.action import ActionAsync, ActionError
from mavsdk.asyncio.plugins.gripper import GripperAsync, GripperError
from mavsdk.asyncio.plugins.offboard import OffboardAsync, OffboardError, VelocityNedYaw
from mavsdk.asyncio.plugins.param import ParamAsync, ParamError
from mavsdk.logging import LogLevel, log_subscribe

from app.clock import Clock
from app.errors import VehicleConnectionError, VehicleError
from app.eventlog import EventLog
from app.messages import Autopilot, TelemetrySnapshot, Vec3
from app.offboard.mavsdk_telemetry import MavsdkTelemetry
from app.offboard.vehicle import SampleListener
from app.offboard.watchdog import SetpointWatchdog, WatchdogThread
from app.settings import ConnectionSettings, TelemetrySettings

GRIPPER_INSTANCE = 1  # MAV_CMD_DO_GRIPPER param 1
ARM_RETRY_PERIOD_S = 1.0
# PX4 denies arming while pre-arm checks fail; ArduCopter answers MAV_RESULT_FAILED for the same.
ARM_RETRY_RESULTS = frozenset({"COMMAND_DENIED", "FAILED", "BUSY"})


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


class MavsdkVehicle:
    """A PX4 or ArduPilot vehicle reached through MAVSDK. Build it with ``MavsdkVehicle.connect``."""

    def __init__(
        self,
        mavsdk: Mavsdk,
        system: Any,
        autopilot: Autopilot,
        clock: Clock,
        events: EventLog,
        conn: ConnectionSettings,
        tel: TelemetrySettings,
    ) -> None:
        self._mavsdk = mavsdk
        self._system = system
        self._autopilot = autopilot
        self._clock = clock
        self._conn = conn
        self._action = ActionAsync(system)
        self._offboard = OffboardAsync(system)
        self._gripper = GripperAsync(system)
        self._param = ParamAsync(system)
        # The same plugin instance, called synchronously (a second Offboard plugin would re-send on its own).
        self._offboard_sync = self._offboard._plugin
        self._streams = MavsdkTelemetry(system, autopilot, clock, events, tel)
        self._setpoint_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mavsdk.setpoints")
        self._watchdog_threads: list[WatchdogThread] = []

    def close(self) -> None:
        """Stop the watchdog threads and the setpoint executor (before MAVSDK is destroyed)."""
        for w in self._watchdog_threads:
            w.stop()
        self._watchdog_threads.clear()
        self._setpoint_executor.shutdown(wait=False, cancel_futures=True)

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
            kind = await system.autopilot_type()
            autopilot = {MavAutopilot.PX4: Autopilot.PX4, MavAutopilot.ARDUPILOT: Autopilot.ARDUPILOT}.get(
                kind, Autopilot.UNKNOWN
            )
            events.write(clock.now_s(), "vehicle", event="connected", url=url, autopilot=autopilot.value)
            vehicle = cls(mavsdk, system, autopilot, clock, events, conn, tel)
            try:
                yield vehicle
            finally:
                vehicle.close()

    @property
    def autopilot(self) -> Autopilot:
        return self._autopilot

    # ---- telemetry (app.offboard.mavsdk_telemetry) ------------------------------------------

    def telemetry(self) -> TelemetrySnapshot:
        return self._streams.snapshot()

    async def run(self) -> None:
        await self._streams.run()

    async def wait_ready(self, timeout_s: float) -> None:
        await self._streams.wait_ready(timeout_s)

    def add_sample_listener(self, listener: SampleListener) -> None:
        self._streams.add_sample_listener(listener)

    def link_stats(self) -> dict[str, float | str | None]:
        return self._streams.link_stats()

    # ---- commands -----------------------------------------------------------------------------

    async def _call(self, name: str, coro: Awaitable[Any]) -> None:
        try:
            await coro
        except (ActionError, OffboardError, GripperError, ParamError) as e:
            raise VehicleError(name, e.result.name, str(e)) from e
        except MavsdkError as e:
            raise VehicleError(name, "ERROR", str(e)) from e

    async def set_param(self, name: str, value: float) -> None:
        await self._call("set_param", self._param.set_param_float(name, value))

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
        """On the setpoint executor, within ``setpoint_timeout_s`` (else ``VehicleError`` TIMEOUT)."""
        sp = VelocityNedYaw(vel_ned_mps[0], vel_ned_mps[1], vel_ned_mps[2], math.degrees(yaw_rad))
        loop = asyncio.get_running_loop()
        try:
            async with asyncio.timeout(self._conn.setpoint_timeout_s):
                await self._call(
                    "set_velocity_ned",
                    loop.run_in_executor(self._setpoint_executor, self._offboard_sync.set_velocity_ned, sp),
                )
        except TimeoutError as e:
            raise VehicleError(
                "set_velocity_ned", "TIMEOUT", f"not sent within {self._conn.setpoint_timeout_s} s"
            ) from e

    def zero_velocity_now(self, yaw_rad: float) -> None:
        """From the watchdog's thread: MAVSDK re-sends zero velocity from now on (no event loop involved)."""
        try:
            self._offboard_sync.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, math.degrees(yaw_rad)))
        except (OffboardError, MavsdkError, RuntimeError) as e:
            sys.stderr.write(f"seapick: watchdog could not zero the setpoint: {e}\n")

    def attach_watchdog(self, watchdog: SetpointWatchdog) -> None:
        """Poll ``watchdog`` in a daemon thread on the loop's clock (monotonic), read without the loop."""
        thread = WatchdogThread(watchdog, asyncio.get_running_loop().time)
        self._watchdog_threads.append(thread)
        thread.start()

    async def hold(self) -> None:
        await self._call("hold", self._action.hold())

    async def stop_offboard(self) -> None:
        """Zero velocity, then HOLD (ArduPilot: BRAKE). Falls back to ``hold`` if offboard.stop fails."""
        attitude = self._streams.snapshot().attitude
        yaw_rad = attitude.yaw_rad if attitude else 0.0
        try:
            await self.set_velocity_ned((0.0, 0.0, 0.0), yaw_rad)
            await self._call("offboard_stop", self._offboard.stop())
        except VehicleError:
            await self.hold()

    async def grip(self, closed: bool) -> None:
        if closed:
            await self._call("gripper_grab", self._gripper.grab(GRIPPER_INSTANCE))
        else:
            await self._call("gripper_release", self._gripper.release(GRIPPER_INSTANCE))

    async def land(self) -> None:
        await self._call("land", self._action.land())
