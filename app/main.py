"""``python -m app.main --mission circle.yaml [--sim] [--connect URL] [--seed N] [--run-dir DIR]``

Composition root: load settings and the mission table (both validated before anything connects), build
the adapters, run everything in one TaskGroup, and leave a run directory with ``summary.json`` and
``events.jsonl``. ``--sim`` starts the simulated PX4 autopilot (``python -m sim.autopilot``) as a separate
process and connects MAVSDK to it over real UDP. Exit code 0 when the mission completed; otherwise 1 with
a one-line reason (2 for invalid input).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import datetime as dt
import json
import signal
import socket
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.clock import Clock, LoopClock
from app.errors import AppError, ConfigError
from app.eventlog import EventLog
from app.missions.runner import MissionRunner, RunResult
from app.missions.table import MissionTable, load_mission
from app.offboard.envelope import EnvelopeLimits
from app.offboard.guidance import ConstantBearingParams
from app.offboard.setpoint_loop import LoopMode, SetpointLoop
from app.offboard.vehicle import Vehicle
from app.settings import Settings, load_settings

SAFE_EXIT_TIMEOUT_S = 5.0
SIM_PILOT_PORT = 14580


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m app.main", description=__doc__.split("\n\n")[0])
    p.add_argument("--mission", required=True, help="mission name (circle) or path to a mission YAML")
    p.add_argument("--settings", type=Path, default=None, help="settings YAML (default settings/default.yaml)")
    p.add_argument("--sim", action="store_true", help="start the simulated PX4 autopilot and fly it over UDP")
    p.add_argument("--connect", default=None, help="MAVSDK URL, e.g. udpin://0.0.0.0:14540 (PX4 SITL)")
    p.add_argument("--seed", type=int, default=1, help="seed for the simulator (wind gusts)")
    p.add_argument("--run-dir", type=Path, default=None, help="where summary.json and events.jsonl go")
    sim = p.add_argument_group("simulator (with --sim)")
    sim.add_argument("--wind-mps", type=float, default=None, help="mean wind speed, m/s (sim default 5)")
    sim.add_argument("--gust-mps", type=float, default=None, help="gust standard deviation, m/s (sim default 1)")
    sim.add_argument("--no-wind", action="store_true", help="calm air")
    sim.add_argument("--sim-profile", choices=("px4", "ardupilot"), default="px4", help="simulated autopilot")
    sim.add_argument("--pilot-port", type=int, default=SIM_PILOT_PORT, help="UDP port for python -m sim.pilot")
    args = p.parse_args(argv)
    if args.sim and args.connect:
        p.error("--sim and --connect exclude each other")
    return args


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_simulator(args: argparse.Namespace, run_dir: Path) -> tuple[subprocess.Popen[bytes], str]:
    port = free_udp_port()
    cmd = [
        sys.executable, "-m", "sim.autopilot",
        "--udp", f"127.0.0.1:{port}",
        "--pilot-port", str(args.pilot_port),
        "--seed", str(args.seed),
        "--profile", args.sim_profile,
        "--state-log", str(run_dir / "sim_state.jsonl"),
    ]  # fmt: skip
    if args.no_wind:
        cmd.append("--no-wind")
    if args.wind_mps is not None:
        cmd += ["--wind-mps", str(args.wind_mps)]
    if args.gust_mps is not None:
        cmd += ["--gust-mps", str(args.gust_mps)]
    log = (run_dir / "sim.log").open("wb")
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    return proc, f"udpin://0.0.0.0:{port}"


@dataclass
class Flight:
    result: RunResult
    duration_s: float
    autopilot: str
    setpoints_sent: int
    tracking: dict[str, Any]
    timing: dict[str, Any]  # telemetry latency and setpoint spacing: what a busy computer did to the run


async def safe_exit(vehicle: Vehicle, setpoints: SetpointLoop, clock: Clock, events: EventLog) -> None:
    """Leaving offboard on our own account: zero velocity, then HOLD. Nothing if we were not guiding."""
    if setpoints.mode != LoopMode.GUIDE:
        setpoints.disengage()
        return
    setpoints.disengage()
    events.write(clock.now_s(), "run", event="safe_exit", action="zero_velocity_then_hold")
    try:
        async with asyncio.timeout(SAFE_EXIT_TIMEOUT_S):
            await vehicle.stop_offboard()
        events.write(clock.now_s(), "command", name="stop_offboard", result="ok")
    except (AppError, TimeoutError) as e:
        events.write(clock.now_s(), "command", name="stop_offboard", result="failed", error=str(e))


async def fly_mission(
    vehicle: Vehicle, table: MissionTable, settings: Settings, clock: Clock, events: EventLog
) -> Flight:
    """Run one mission on a connected vehicle; always ends with a safe exit."""
    g, e = settings.guidance, settings.envelope
    setpoints = SetpointLoop(
        vehicle,
        clock,
        events,
        ConstantBearingParams(g.approach_speed_max_mps, g.transient_distance_m, g.velocity_lead_s),
        EnvelopeLimits(**e.model_dump()),
        g.setpoint_rate_hz,
        g.standby_rate_hz,
        settings.telemetry.position_stale_s,
    )
    runner = MissionRunner(
        table, vehicle, setpoints, clock, events, settings.runner.tick_rate_hz, settings.runner.mode_confirm_timeout_s
    )
    loop = asyncio.get_running_loop()
    main_task = asyncio.current_task()
    signals_seen = 0

    def on_signal(signame: str) -> None:
        nonlocal signals_seen
        signals_seen += 1
        if signals_seen == 1:
            runner.request_abort(signame)
        elif main_task is not None:
            main_task.cancel()

    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, on_signal, sig.name)
    t_start_s = clock.now_s()
    try:
        async with asyncio.TaskGroup() as tg:
            streams = tg.create_task(vehicle.run(), name="vehicle.telemetry")
            loop_task = tg.create_task(setpoints.run(), name="offboard.setpoints")
            try:
                await vehicle.wait_ready(settings.connection.ready_timeout_s)
                events.write(clock.now_s(), "run", event="vehicle_ready", autopilot=vehicle.autopilot.value)
                result = await runner.run()
            finally:
                await safe_exit(vehicle, setpoints, clock, events)
                streams.cancel()
                loop_task.cancel()
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.remove_signal_handler(sig)
    timing = vehicle.link_stats() | setpoints.interval_summary()
    return Flight(
        result, clock.now_s() - t_start_s, vehicle.autopilot.value, setpoints.sent, runner.tracking.summary(), timing
    )


async def connect_and_fly(url: str, table: MissionTable, settings: Settings, events: EventLog, run_dir: Path) -> Flight:
    from app.offboard.mavsdk_vehicle import MavsdkVehicle, route_mavsdk_log  # loads the native library

    route_mavsdk_log(run_dir / "mavsdk.log")
    clock = LoopClock()
    async with MavsdkVehicle.connect(url, clock, events, settings.connection, settings.telemetry) as vehicle:
        return await fly_mission(vehicle, table, settings, clock, events)


def first_leaf(exc: BaseException) -> BaseException:
    while isinstance(exc, BaseExceptionGroup):
        exc = exc.exceptions[0]
    return exc


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        settings = load_settings(args.settings)
        table = load_mission(args.mission)
    except ConfigError as e:
        print(f"seapick: invalid input: {e}", file=sys.stderr)
        return 2
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")  # wall clock only for the folder name
    run_dir: Path = args.run_dir or Path("runs") / f"{table.mission}-{stamp}"
    run_dir.mkdir(parents=True, exist_ok=True)
    events = EventLog(run_dir / "events.jsonl")
    sim_proc = None
    url = args.connect or settings.connection.url
    if args.sim:
        sim_proc, url = start_simulator(args, run_dir)
        print(f"seapick: simulator started (pilot: python -m sim.pilot --port {args.pilot_port} --mode POSCTL)")
    summary: dict[str, Any] = {
        "mission": table.mission,
        "outcome": "failed",
        "reason": "",
        "duration_s": 0.0,
        "states_visited": [],
        "connection": url,
        "sim": bool(args.sim),
        "seed": args.seed,
        "started_utc": stamp,
    }
    try:
        flight = asyncio.run(connect_and_fly(url, table, settings, events, run_dir))
        summary.update(
            outcome=flight.result.outcome,
            reason=flight.result.reason,
            duration_s=round(flight.duration_s, 3),
            states_visited=flight.result.states_visited,
            final_state=flight.result.final_state,
            autopilot=flight.autopilot,
            setpoints_sent=flight.setpoints_sent,
            **flight.tracking,
            timing={k: round(v, 6) if isinstance(v, float) else v for k, v in flight.timing.items()},
        )
    except BaseException as exc:
        leaf = first_leaf(exc)
        if isinstance(leaf, KeyboardInterrupt | asyncio.CancelledError):
            summary["reason"] = "interrupted"
        else:
            summary["reason"] = str(leaf) or type(leaf).__name__
        if not isinstance(leaf, AppError | KeyboardInterrupt | asyncio.CancelledError):
            summary["error_type"] = type(leaf).__name__
    finally:
        events.close()
        if sim_proc is not None:
            sim_proc.terminate()
            try:
                sim_proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                sim_proc.kill()
    summary["event_counts"] = events.counts
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if summary["outcome"] == "completed":
        print(f"seapick: mission {table.mission} completed in {summary['duration_s']:.1f} s ({run_dir})")
        return 0
    print(f"seapick: mission {table.mission} {summary['outcome']}: {summary['reason']}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
