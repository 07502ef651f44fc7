"""The simulated autopilot as a MAVLink endpoint (PX4 or ArduCopter dialect), in real time.

The command line: it runs the endpoint (``SimAutopilot`` in ``sim.autopilot_endpoint``; its UDP links
are ``sim.autopilot_link``) in the main thread until SIGINT or SIGTERM, sending to ``--udp`` where
MAVSDK listens and taking mode switches from a pilot tool (``sim.pilot``) on ``--pilot-port``. See
``sim.state_log`` for the JSON-lines log. ``SimAutopilot`` and ``SimConfig`` are importable from here.

CLI::

    python -m sim.autopilot --udp 127.0.0.1:14540 [--pilot-port 14580] [--profile px4|px4-sih|ardupilot]
        [--seed N] [--wind-mps 5] [--gust-mps 1] [--wind-from-deg 240] [--no-wind]
        [--state-log FILE] [--home LAT,LON,ALT] [--param NAME=VALUE ...]
        [--camera-socket unix:PATH --radar-link PATH [--sea-state N] [--current-mps V] [--object marker|buoy]
         [--object-ne N,E] [--fail-first-grabs K] [--settings FILE]]    # the pickup's world: sea, object, camera, radar

With ``--camera-socket`` or ``--radar-link`` the process also simulates the pickup's world
(``sim.pickup_serve``): the sea and the floating object, the camera served on the socket, the X4M03 emulator
on a pty at the link path, and the grab judged from the truth (``grab`` records in the state log).

Embedded (tests)::

    with SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0)) as sim:
        ...  # sim.truth(), sim.pilot_address, sim.submit(lambda stack: ...)
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import threading
from pathlib import Path

from app.cli import OneLineParser, handle_signals_in_thread, number, run_cli
from app.settings import load_settings
from sim.airframes import SIM_PROFILES
from sim.autopilot_endpoint import SimAutopilot, SimConfig
from sim.autopilot_modes import DEFAULT_ORIGIN, GeoPoint
from sim.estimator import ESTIMATORS
from sim.pickup_serve import PickupServer, ServeConfig
from sim.pickup_world import PickupScenario
from sim.wind import WindConfig

__all__ = ["SimAutopilot", "SimConfig", "config_from_args", "main"]

_WIND = WindConfig()


def _udp(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT (port 1..65535)")
    return host or "127.0.0.1", int(port)


def _home(text: str) -> GeoPoint:
    try:
        lat, lon, alt = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not LAT,LON,ALT") from None
    if not (abs(lat) <= 90.0 and abs(lon) <= 180.0 and -500.0 <= alt <= 9000.0):
        raise argparse.ArgumentTypeError(f"{text} is outside lat -90..90, lon -180..180, alt -500..9000 m")
    return GeoPoint(lat, lon, alt)


def _param(text: str) -> tuple[str, float]:
    name, eq, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not eq or not name or not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"{text!r} is not NAME=VALUE with a finite number")
    return name, number


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = OneLineParser(prog="python -m sim.autopilot", description=__doc__.split("\n\n")[0])
    ap.add_argument("--udp", type=_udp, default="127.0.0.1:14540", help="HOST:PORT where MAVSDK listens (udpin)")
    ap.add_argument(
        "--pilot-port", type=number(0, 65535, "", int), default=14580, help="pilot/GCS UDP port on 127.0.0.1; 0 = off"
    )
    ap.add_argument(
        "--profile",
        choices=list(SIM_PROFILES),
        default="px4",
        help="calibrated autopilot: PX4 on a real airframe, PX4 SIH as recorded, ArduCopter (sim.airframes)",
    )
    ap.add_argument(
        "--estimator", choices=list(ESTIMATORS), default=None, help="estimator error (default: the profile's)"
    )
    ap.add_argument("--seed", type=int, default=0)
    speed = number(0.0, 30.0, "m/s")
    ap.add_argument("--wind-mps", type=speed, default=_WIND.mean_mps, help="mean wind speed, m/s")
    ap.add_argument("--gust-mps", type=speed, default=_WIND.gust_sigma_mps, help="gust std dev, m/s")
    ap.add_argument("--wind-from-deg", type=number(-360.0, 360.0, "deg"), default=_WIND.from_deg, help="wind from, deg")
    ap.add_argument("--no-wind", action="store_true", help="still air")
    ap.add_argument("--state-log", default=None, help="JSON-lines state log file")
    ap.add_argument("--home", type=_home, default=None, help="LAT,LON,ALT (deg, deg, m AMSL)")
    ap.add_argument("--param", type=_param, action="append", default=[], help="NAME=VALUE parameter override")
    ap.add_argument(
        "--parent-pid", type=number(1, 2**22, "", int), default=None,
        help="stop when this process is no longer the parent (it died: app.main's child)",
    )  # fmt: skip
    world = ap.add_argument_group("the pickup's world (sim.pickup_serve)")
    world.add_argument("--camera-socket", default=None, help="serve the camera here, e.g. unix:/tmp/cam.sock")
    world.add_argument("--radar-link", default=None, help="serve the X4M03 emulator's pty at this symlink")
    world.add_argument("--sea-state", type=number(0, 5, "(WMO code)", int), default=2, help="WMO sea state")
    world.add_argument("--current-mps", type=number(0.0, 3.0, "m/s"), default=0.3, help="surface current")
    world.add_argument("--object", choices=("marker", "buoy"), default="marker", help="what floats (default marker)")
    world.add_argument("--object-ne", type=_pair, default=(40.0, 20.0), help="N,E: the object's start, m")
    world.add_argument("--fail-first-grabs", type=number(0, 100, "", int), default=0, help="grabs that slip")
    world.add_argument("--settings", type=Path, default=None, help="the camera and detector (the app's settings)")
    return ap.parse_args(argv)


def _pair(text: str) -> tuple[float, float]:
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not N,E in metres") from None
    if not (math.isfinite(a) and math.isfinite(b) and abs(a) <= 10_000 and abs(b) <= 10_000):
        raise argparse.ArgumentTypeError(f"{text!r}: N and E must be finite, within ±10 km")
    return a, b


def config_from_args(args: argparse.Namespace) -> SimConfig:
    host, port = args.udp
    origin = args.home or DEFAULT_ORIGIN
    wind = (
        WindConfig.off()
        if args.no_wind
        else WindConfig(
            mean_mps=args.wind_mps,
            from_deg=args.wind_from_deg,
            gust_sigma_mps=args.gust_mps,
            vertical_sigma_mps=_WIND.vertical_sigma_mps if args.gust_mps > 0 else 0.0,
        )
    )
    params = dict(args.param)
    return SimConfig(
        target=(host, port),
        pilot_port=args.pilot_port or None,
        profile=SIM_PROFILES[args.profile].autopilot,
        airframe=SIM_PROFILES[args.profile].airframe,
        estimator=ESTIMATORS[args.estimator] if args.estimator else SIM_PROFILES[args.profile].estimator,
        seed=args.seed,
        wind=wind,
        origin=origin,
        state_log=args.state_log,
        params=params or None,
    )


def pickup_server(sim: SimAutopilot, args: argparse.Namespace) -> PickupServer | None:
    if args.camera_socket is None and args.radar_link is None:
        return None
    settings = load_settings(args.settings)
    scenario = PickupScenario(
        seed=args.seed,
        sea_state=args.sea_state,
        current_mps=args.current_mps,
        object_start_ne_m=args.object_ne,
        marker_size_m=settings.detector.marker_size_m,
        object_kind=args.object,
        fail_first_grabs=args.fail_first_grabs,
    )
    config = ServeConfig(scenario, args.camera_socket, args.radar_link)
    detector = settings.detector.model_copy(update={"kind": "buoy" if args.object == "buoy" else "aruco"})
    return PickupServer(sim, config, settings.camera, detector)


PARENT_POLL_S = 0.2


def _watch_parent(parent_pid: int, stop: threading.Event) -> None:
    """Stop once ``parent_pid`` is no longer the parent: it died (re-parented to init), whether or not the
    parent-death signal came."""
    while not stop.wait(PARENT_POLL_S):
        if os.getppid() != parent_pid:
            print(f"sim.autopilot: parent {parent_pid} is gone, stopping", flush=True)
            stop.set()


def main(argv: list[str] | None = None) -> int:
    args = _parse_args(argv)
    config = config_from_args(args)
    sim = SimAutopilot(config)  # a port in use or an unwritable state log: one line via run_cli
    world = pickup_server(sim, args)
    if world is not None:
        world.start()
    stop = threading.Event()
    handle_signals_in_thread({signal.SIGINT: stop.set, signal.SIGTERM: stop.set})
    if args.parent_pid is not None:
        threading.Thread(target=_watch_parent, args=(args.parent_pid, stop), name="parent", daemon=True).start()
    host, port = config.target
    pilot_port = sim.pilot_address[1] if sim.pilot_address else 0
    print(f"sim.autopilot: sending to {host}:{port}, pilot port {pilot_port}", flush=True)
    try:
        sim.run(stop)
    finally:
        sim.stop()
        if world is not None:
            world.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(run_cli(main, "python -m sim.autopilot"))
