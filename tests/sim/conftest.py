"""Fixtures for the simulator tests: the MAVLink endpoint in a thread and a real MAVSDK 4 client on it."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator, Awaitable, Callable
from contextlib import asynccontextmanager
from dataclasses import dataclass
from typing import Any

from sim.autopilot import SimAutopilot, SimConfig

CONNECT_TIMEOUT_S = 15.0  # generous: the machine may be busy


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Connected:
    sim: SimAutopilot
    system: Any
    telemetry: Any
    action: Any
    offboard: Any
    param: Any


@asynccontextmanager
async def mavsdk_on_sim(**config: Any) -> AsyncIterator[Connected]:
    """Start the endpoint (thread) sending to a free port and connect MAVSDK there as a companion computer."""
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.offboard import OffboardAsync
    from mavsdk.asyncio.plugins.param import ParamAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    port = free_udp_port()
    sim = SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0, **config))
    try:
        async with Mavsdk(Configuration.create_with_component_type(ComponentType.COMPANION_COMPUTER)) as m:
            await m.add_any_connection(f"udpin://0.0.0.0:{port}")
            sim.start()  # after MAVSDK listens, so its first heartbeat is not lost
            system = await m.first_autopilot(timeout_s=CONNECT_TIMEOUT_S)
            assert system is not None, "no autopilot discovered"
            yield Connected(
                sim, system, TelemetryAsync(system), ActionAsync(system), OffboardAsync(system), ParamAsync(system)
            )
    finally:
        sim.stop()


@asynccontextmanager
async def app_vehicle_on_sim(
    settings: Any, clock: Any, events: Any, **config: Any
) -> AsyncIterator[tuple[SimAutopilot, Any]]:
    """The endpoint (thread) on a free port and the app's own ``MavsdkVehicle`` connected to it, its telemetry
    streams running and ready."""
    from app.offboard.mavsdk_vehicle import MavsdkVehicle

    port = free_udp_port()
    sim = SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0, **config))
    asyncio.get_running_loop().call_later(0.5, sim.start)  # after MAVSDK listens
    try:
        url = f"udpin://0.0.0.0:{port}"
        async with MavsdkVehicle.connect(url, clock, events, settings.connection, settings.telemetry) as vehicle:
            streams = asyncio.create_task(vehicle.run())
            try:
                await vehicle.wait_ready(30.0)
                yield sim, vehicle
            finally:
                streams.cancel()
    finally:
        sim.stop()


async def first(stream: AsyncIterator[Any], predicate: Callable[[Any], bool], timeout_s: float) -> Any:
    """The first item of ``stream`` that satisfies ``predicate`` (closing the stream), or TimeoutError."""

    async def scan() -> Any:
        try:
            async for item in stream:
                if predicate(item):
                    return item
        finally:
            await stream.aclose()  # type: ignore[attr-defined]

    return await asyncio.wait_for(scan(), timeout_s)


async def eventually(check: Callable[[], Awaitable[bool]] | Callable[[], bool], timeout_s: float) -> None:
    """Poll ``check`` every 50 ms until it is true, or fail after ``timeout_s``."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while True:
        result = check()
        if asyncio.iscoroutine(result):
            result = await result
        if result:
            return
        assert loop.time() < deadline, "condition not met in time"
        await asyncio.sleep(0.05)
