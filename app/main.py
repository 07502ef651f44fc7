"""``python -m app.main --mission pickup.yaml [--sim] [--connect URL] [--mqtt URL] [--seed N] [--run-dir DIR]``

Composition root: load settings and the mission table (both validated before anything connects), connect
MAVSDK, build the sensors (the pickup's camera and radar: the simulator's or the real ones) and the ground
station's link, fly the mission (``app.flight.fly_mission``: everything in one TaskGroup), and leave a run
directory with ``summary.json``, ``events.jsonl``, ``run.mcap`` and, for the pickup, ``report.png`` and
``camera/`` (a frame a second for ``run.mcap``). ``--sim`` starts the simulated autopilot (``python -m
sim.autopilot``; for the pickup also the sea, the object, the camera and the radar) as a separate process and
connects MAVSDK to it over real UDP. Exit code 0 when the mission completed; otherwise 1 with a one-line reason
(2 for invalid input).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import ctypes
import ctypes.util
import datetime as dt
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.cli import OneLineParser, number, run_cli
from app.clock import Clock, PreciseClock, realtime_thread
from app.errors import AppError, ConfigError
from app.eventlog import EventLog
from app.flight import Flight, fly_mission
from app.foxglove_log import write_mcap
from app.gcs.config import GcsSettings
from app.missions.pickup_feeds import Producer, camera_producer, radar_producer, radar_task_for
from app.missions.runner import model_name
from app.missions.sensor_log import CameraFrameLog, RadarProfileLog
from app.missions.table import SUCCESS, MissionTable, load_mission
from app.report import render_report
from app.settings import Settings, load_settings

SIM_PILOT_PORT = 14580
PR_SET_PDEATHSIG = 1  # linux/prctl.h
SIM_NICE = 5  # the simulator's niceness above the app's
VEHICLE_ID = "drone1"  # the ground station's topic tree, seapick/<vehicle id>/v1/…, when none is given
SPEED = number(0.0, 30.0, "m/s")
UDP_PORT = number(0, 65535, "(UDP port)", int)
TCP_PORT = number(0, 65535, "(TCP port)", int)


SIM_PROFILES = ("px4", "px4-sih", "ardupilot")  # sim.airframes.SIM_PROFILES (the simulator is another process)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = OneLineParser(prog="python -m app.main", description=__doc__.split("\n\n")[0])
    p.add_argument("--mission", required=True, help="mission name (circle) or path to a mission YAML")
    p.add_argument("--settings", type=Path, default=None, help="settings YAML (default settings/default.yaml)")
    p.add_argument("--sim", action="store_true", help="start the simulated PX4 autopilot and fly it over UDP")
    p.add_argument("--connect", default=None, help="MAVSDK URL, e.g. udpin://0.0.0.0:14540 (PX4 SITL)")
    p.add_argument("--seed", type=int, default=1, help="seed for the simulator (wind gusts)")
    p.add_argument("--run-dir", type=Path, default=None, help="where summary.json and events.jsonl go")
    p.add_argument(
        "--mqtt",
        default=None,
        metavar="URL",
        help="ground station broker, mqtt://host[:port] or mqtts://…: the mission waits for its start command "
        "(default: the settings' gcs section; none: it starts by itself)",
    )
    p.add_argument("--vehicle-id", default=None, help=f"topic tree seapick/<id>/v1/… (default {VEHICLE_ID})")
    p.add_argument(
        "--foxglove",
        action="store_true",
        help="serve the run live to the Foxglove app on ws://127.0.0.1:PORT (the channels of the run's run.mcap)",
    )
    p.add_argument("--foxglove-port", type=TCP_PORT, default=8765, help="port for --foxglove (default 8765; 0: any)")
    sim = p.add_argument_group("simulator (with --sim)")
    sim.add_argument("--wind-mps", type=SPEED, default=None, help="mean wind speed, m/s (sim default 5)")
    sim.add_argument("--gust-mps", type=SPEED, default=None, help="gust standard deviation, m/s (sim default 1)")
    sim.add_argument("--no-wind", action="store_true", help="calm air")
    sim.add_argument(
        "--sim-profile",
        choices=SIM_PROFILES,
        default="px4",
        help="simulated autopilot, calibrated against real firmware: PX4 on a real airframe with a GNSS-grade "
        "estimate, PX4 SIH as recorded (its drag and estimator errors), ArduCopter",
    )
    sim.add_argument(
        "--sea-state", type=number(0, 5, "(WMO code)", int), default=2, help="pickup: the sea state (default 2)"
    )
    sim.add_argument(
        "--object",
        choices=("marker", "buoy"),
        default="marker",
        help="pickup: what floats — the ArUco marker, or a plain buoy (settings' detector.buoy_diameter_m; the app "
        "then uses the buoy detector)",
    )
    sim.add_argument(
        "--pilot-port",
        type=UDP_PORT,
        default=SIM_PILOT_PORT,
        help="UDP port for python -m sim.pilot",
    )
    args = p.parse_args(argv)
    if args.sim and args.connect:
        p.error("--sim and --connect exclude each other")
    return args


def ground_settings(settings: Settings, args: argparse.Namespace) -> GcsSettings | None:
    """The ground station's link: the settings' ``gcs`` section, ``--mqtt`` / ``--vehicle-id`` over it."""
    section = dict(settings.gcs or {})
    if args.mqtt is not None:
        section["broker_url"] = args.mqtt
    if args.vehicle_id is not None:
        section["vehicle_id"] = args.vehicle_id
    if not section.get("broker_url"):
        if args.vehicle_id is not None:
            raise ConfigError("--vehicle-id", "", "needs a broker (--mqtt or the settings' gcs section)")
        return None
    section.setdefault("vehicle_id", VEHICLE_ID)
    return GcsSettings.from_mapping(section, "gcs", "--mqtt" if args.mqtt is not None else "settings")


def _simulator_child_setup() -> Callable[[], None]:
    """What runs in the simulator's process before it starts: a lower priority, and dying with the app — even when
    the app is killed outright (SIGKILL), a simulator left behind would fly on and eat CPU (Linux:
    PR_SET_PDEATHSIG; the simulator also watches its parent, ``--parent-pid``). libc is looked up here, in the app:
    ``find_library`` runs ``ldconfig`` in a subprocess, which has no place between fork and exec."""
    prctl: Callable[..., int] | None = None
    with contextlib.suppress(OSError, AttributeError):
        prctl = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True).prctl
    app_pid = os.getpid()

    def child() -> None:
        os.nice(SIM_NICE)
        if prctl is not None:
            prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != app_pid:  # the app died before the signal was armed
            os.kill(os.getpid(), signal.SIGTERM)

    return child


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass(frozen=True)
class SimSensors:
    """Where the simulator serves the pickup's camera and radar (a short path: Unix sockets allow 107 bytes)."""

    camera: str  # unix:PATH
    radar: str  # the pty's symlink

    @classmethod
    def make(cls) -> SimSensors:
        d = Path(tempfile.mkdtemp(prefix="seapick-"))
        return cls(f"unix:{d / 'camera.sock'}", str(d / "radar"))


def start_simulator(
    args: argparse.Namespace, run_dir: Path, sensors: SimSensors | None = None
) -> tuple[subprocess.Popen[bytes], str]:
    port = free_udp_port()
    cmd = [
        sys.executable, "-m", "sim.autopilot",
        "--udp", f"127.0.0.1:{port}",
        "--pilot-port", str(args.pilot_port),
        "--seed", str(args.seed),
        "--profile", args.sim_profile,
        "--state-log", str(run_dir / "sim_state.jsonl"),
        "--parent-pid", str(os.getpid()),
    ]  # fmt: skip
    if args.no_wind:
        cmd.append("--no-wind")
    if args.wind_mps is not None:
        cmd += ["--wind-mps", str(args.wind_mps)]
    if args.gust_mps is not None:
        cmd += ["--gust-mps", str(args.gust_mps)]
    if sensors is not None:
        cmd += ["--camera-socket", sensors.camera, "--radar-link", sensors.radar, "--sea-state", str(args.sea_state)]
        cmd += ["--object", args.object]
        if args.settings is not None:
            cmd += ["--settings", str(args.settings)]
    log = (run_dir / "sim.log").open("wb")
    # The simulator stands in for other hardware (the autopilot, the camera, the radar) that does not share the
    # companion computer's CPU: it runs at a lower priority, so the app's setpoint loop is not queued behind it.
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, preexec_fn=_simulator_child_setup())
    return proc, f"udpin://0.0.0.0:{port}"


async def connect_and_fly(
    url: str,
    table: MissionTable,
    settings: Settings,
    events: EventLog,
    run_dir: Path,
    sim_sensors: SimSensors | None = None,
    ground: GcsSettings | None = None,
) -> Flight:
    from app.offboard.mavsdk_vehicle import MavsdkVehicle, route_mavsdk_log  # loads the native library

    route_mavsdk_log(run_dir / "mavsdk.log")
    clock = PreciseClock()  # real time: wakes on time (the 50 Hz setpoints), not up to 1 ms late
    with realtime_thread(settings.guidance.realtime_priority) as scheduling:  # before the threads start here
        events.write(clock.now_s(), "loop_scheduling", policy=scheduling)
        pickup = model_name(table) == "pickup"
        sensors = pickup_sensors(settings, clock, sim_sensors, SensorLogs.into(run_dir, events)) if pickup else []
        async with MavsdkVehicle.connect(url, clock, events, settings.connection, settings.telemetry) as vehicle:
            flight = await fly_mission(vehicle, table, settings, clock, events, sensors=sensors, ground=ground)
    clock.close()
    flight.timing["loop_scheduling"] = scheduling
    return flight


@dataclass(frozen=True)
class SensorLogs:
    """What the pickup's sensors leave in the run directory for ``run.mcap``: decimated camera frames (JPEG files
    and ``camera`` records) and radar profiles (``radar_profile`` records)."""

    camera: CameraFrameLog | None = None
    radar: RadarProfileLog | None = None

    @classmethod
    def into(cls, run_dir: Path, events: EventLog) -> SensorLogs:
        return cls(CameraFrameLog(run_dir, events), RadarProfileLog(events))


def pickup_sensors(
    settings: Settings, clock: Clock, sim: SimSensors | None, logs: SensorLogs | None = None
) -> list[Producer]:
    """The pickup's camera and radar tasks: the simulator's (a socket, a pty) or the real ones from settings; with
    ``logs``, each keeps some of what it measured in the run directory."""
    from app.sensors.camera_socket import open_socket_camera
    from app.sensors.camera_v4l2 import open_v4l2_camera
    from app.sensors.detect import make_detector

    logs = logs or SensorLogs()
    detector = make_detector(settings.detector, settings.camera)
    if sim is not None:
        size = (settings.camera.width_px, settings.camera.height_px)
        camera = camera_producer(
            lambda: open_socket_camera(sim.camera, expected_size=size), detector, clock, frame_log=logs.camera
        )
        return [camera, radar_producer(radar_task_for(settings, sim.radar, on_frame=logs.radar))]
    camera = camera_producer(  # opened on the loop; its capture thread may call loop.time()
        lambda: open_v4l2_camera(settings.camera, asyncio.get_running_loop().time),
        detector,
        clock,
        frame_log=logs.camera,
    )
    return [camera, radar_producer(radar_task_for(settings, settings.radar.port, on_frame=logs.radar))]


def tracking_report(summary: dict[str, Any]) -> str:
    """The tracking error after convergence, 3-D / horizontal / vertical, as one table."""
    rows = [("3-D", ""), ("horizontal", "horizontal_"), ("vertical", "vertical_")]
    head = f"tracking error after convergence ({summary['tracking_samples']} samples):"
    lines = [head, "             p50 m    p95 m"]
    for label, key in rows:
        p50, p95 = summary.get(f"tracking_error_{key}p50_m"), summary.get(f"tracking_error_{key}p95_m")
        if p50 is not None and p95 is not None:
            lines.append(f"  {label:<10} {p50:7.4f}  {p95:7.4f}")
    return "\n".join(lines)


def pickup_truth(state_log: Path, summary: dict[str, Any]) -> dict[str, Any]:
    """The simulator's verdict on the pickup (its state log): the grabs, the touchdown error, time to pickup."""
    from sim.state_log import read_state_log  # only with --sim: the simulator's own log

    grabs = [r for r in read_state_log(state_log) if r.get("event") == "grab"] if state_log.exists() else []
    caught = [g for g in grabs if g.get("caught")]
    last = caught[-1] if caught else (grabs[-1] if grabs else None)
    armed = [r["t_s"] for r in read_state_log(state_log) if r.get("event") == "armed" and r.get("armed")]
    return {
        "touchdown_error_m": None if last is None else round(last["error_m"], 4),
        "time_to_pickup_s": round(caught[0]["t_s"] - armed[0], 2) if caught and armed else None,
        "grabs": [{k: round(v, 4) if isinstance(v, float) else v for k, v in g.items() if k != "event"} for g in grabs],
        "off_target_touchdowns": sum(1 for g in grabs if not g.get("caught") and not g.get("slipped")),
    }


def first_leaf(exc: BaseException) -> BaseException:
    while isinstance(exc, BaseExceptionGroup):
        exc = exc.exceptions[0]
    return exc


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        settings = load_settings(args.settings)
        table = load_mission(args.mission)
        ground = ground_settings(settings, args)
        if args.sim and args.object == "buoy":  # the simulated object is a buoy: look for one
            settings = settings.model_copy(update={"detector": settings.detector.model_copy(update={"kind": "buoy"})})
    except ConfigError as e:
        print(f"seapick: invalid input: {e}", file=sys.stderr)
        return 2
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")  # wall clock only for the folder name
    run_dir: Path = args.run_dir or Path("runs") / f"{table.mission}-{stamp}"
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        events = EventLog(run_dir / "events.jsonl")
    except OSError as e:
        print(f"seapick: invalid input: --run-dir {run_dir}: {e.strerror or e}", file=sys.stderr)
        return 2
    live = None
    if args.foxglove:
        from app.foxglove_live import LiveServer

        try:
            live = LiveServer.start(events, args.foxglove_port, run_dir)
        except ConfigError as e:
            events.close()
            print(f"seapick: invalid input: {e}", file=sys.stderr)
            return 2
        print(f"seapick: Foxglove live on {live.url} (Foxglove: Open connection, Foxglove WebSocket)")
    sim_proc = None
    url = args.connect or settings.connection.url
    pickup = model_name(table) == "pickup"
    sim_sensors = SimSensors.make() if args.sim and pickup else None
    if args.sim:
        sim_proc, url = start_simulator(args, run_dir, sim_sensors)
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
        flight = asyncio.run(connect_and_fly(url, table, settings, events, run_dir, sim_sensors, ground))
        summary.update(
            outcome=flight.result.outcome,
            reason=flight.result.reason,
            duration_s=round(flight.duration_s, 3),
            states_visited=flight.result.states_visited,
            final_state=flight.result.final_state,
            autopilot=flight.autopilot,
            setpoints_sent=flight.setpoints_sent,
            **flight.figures,
            timing={k: round(v, 6) if isinstance(v, float) else v for k, v in flight.timing.items()},
            safety=flight.safety,
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
        if live is not None:
            live.stop()
        if sim_proc is not None:
            sim_proc.terminate()
            try:
                sim_proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                sim_proc.kill()
    summary["event_counts"] = events.counts
    if live is not None:
        summary["foxglove_live"] = {"url": live.url, "dropped": live.dropped, "skipped": live.skipped}
    if sim_proc is not None and pickup:
        summary.update(pickup_truth(run_dir / "sim_state.jsonl", summary))
    if pickup:
        try:
            summary["report"] = str(render_report(run_dir, title=f"{table.mission} seed {args.seed}"))
        except Exception as e:  # a figure that failed must not cost the summary
            summary["report_error"] = f"{type(e).__name__}: {e}"
    try:
        summary["mcap"] = str(write_mcap(run_dir))
    except Exception as e:  # nor a recording that failed
        summary["mcap_error"] = f"{type(e).__name__}: {e}"
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if summary.get("tracking_samples"):
        print(tracking_report(summary))
    if summary["outcome"] in SUCCESS:
        print(f"seapick: mission {table.mission} {summary['outcome']} in {summary['duration_s']:.1f} s ({run_dir})")
        return 0
    print(f"seapick: mission {table.mission} {summary['outcome']}: {summary['reason']}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m app.main"))
