"""The one interface the flight code has to a vehicle.

Only ``app.offboard.boundary.VehicleBoundary`` calls the commands and setpoints; it applies authority,
the envelope and offboard ownership first. Implemented by the MAVSDK adapter
(``app.offboard.mavsdk_vehicle``) for PX4 and ArduPilot, and by the in-process simulator (``sim.inproc``)
for virtual-time tests. Commands raise ``VehicleError`` when the autopilot refuses them. Telemetry is a
snapshot of the latest sample of every stream, each stamped on the loop clock: position and attitude with
the time the autopilot took them (its ``time_boot_ms`` mapped onto the loop clock,
``app.offboard.timesync``) once that clock is seen to run in real time, the rest with the time they were
received (in MAVSDK's callback thread, not when the app read them).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from app.messages import AttitudeEuler, Autopilot, PositionVelocityNed, TelemetrySnapshot, Vec3
from app.offboard.watchdog import SetpointWatchdog

# Called with every position and attitude sample (stamped on the loop clock) and the loop time it arrived.
SampleListener = Callable[[PositionVelocityNed | AttitudeEuler, float], None]


class Vehicle(Protocol):
    @property
    def autopilot(self) -> Autopilot:
        """Which autopilot answered (known after ``wait_ready``)."""
        ...

    async def run(self) -> None:
        """Consume the telemetry streams until cancelled (started in the root TaskGroup)."""
        ...

    async def wait_ready(self, timeout_s: float) -> None:
        """Wait for what a mission needs: a position stream, home, flight mode and armed state.

        Raises ``VehicleConnectionError`` naming what is missing after ``timeout_s``.
        """
        ...

    def telemetry(self) -> TelemetrySnapshot:
        """The latest sample of every stream (never blocks)."""
        ...

    def add_sample_listener(self, listener: SampleListener) -> None:
        """Call ``listener(sample, received_s)`` for every position and attitude sample, in arrival order
        (the snapshot keeps only the latest; a vehicle-state history wants them all)."""
        ...

    def link_stats(self) -> dict[str, float | str | None]:
        """Figures about the telemetry link for the run summary (e.g. sample latency); may be empty."""
        ...

    async def set_param(self, name: str, value: float) -> None:
        """Set a float parameter on the autopilot (PARAM_SET); raises ``VehicleError`` if it is not taken."""
        ...

    async def arm(self) -> None: ...

    async def takeoff(self, altitude_m: float) -> None:
        """Autopilot takeoff to ``altitude_m`` above home (PX4: MIS_TAKEOFF_ALT; ArduPilot: GUIDED)."""
        ...

    async def start_offboard(self, yaw_rad: float) -> None:
        """Send a zero-velocity setpoint, then switch to OFFBOARD (ArduPilot: GUIDED)."""
        ...

    async def set_velocity_ned(self, vel_ned_mps: Vec3, yaw_rad: float) -> None:
        """One velocity setpoint in the local NED frame, yaw absolute."""
        ...

    def zero_velocity_now(self, yaw_rad: float) -> None:
        """From any thread, without the event loop: make the setpoint being re-sent zero velocity."""
        ...

    def attach_watchdog(self, watchdog: SetpointWatchdog) -> None:
        """Poll ``watchdog`` off the event loop (MAVSDK: a thread on the monotonic clock; the in-process
        simulator: its physics steps), until the vehicle is closed."""
        ...

    async def hold(self) -> None:
        """Switch to HOLD (PX4 AUTO.LOITER; ArduPilot BRAKE)."""
        ...

    async def stop_offboard(self) -> None:
        """Leave offboard on our own account: zero velocity, then HOLD."""
        ...

    async def land(self) -> None: ...

    async def grip(self, closed: bool) -> None:
        """Close (grab) or open (release) the gripper: MAV_CMD_DO_GRIPPER, instance 1."""
        ...
