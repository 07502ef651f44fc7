"""The simulated autopilot as a MAVLink endpoint (PX4 or ArduCopter dialect), in real time.

The command line: it runs the endpoint (``SimAutopilot`` in ``sim.autopilot_endpoint``; its UDP links
are ``sim.autopilot_link``) in the main thread until SIGINT or SIGTERM, sending to ``--udp`` where
MAVSDK listens and taking mode switches from a pilot tool (``sim.pilot``) on ``--pilot-port``. See
``sim.state_log`` for the JSON-lines log. ``SimAutopilot`` and ``SimConfig`` are importable from here.

CLI::

    python -m sim.autopilot --udp 127.0.0.1:14540 [--pilot-port 14580] [--profile px4|ardupilot]
        [--seed N] [--wind-mps 5] [--gust-mps 1] [--wind-from-deg 240] [--no-wind]
        [--state-log FILE] [--home LAT,LON,ALT] [--param NAME=VALUE ...]

Embedded (tests)::

    with SimAutopilot(SimConfig(target=("127.0.0.1", port), pilot_port=0)) as sim:
        ...  # sim.truth(), sim.pilot_address, sim.submit(lambda stack: ...)
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from types import FrameType

from sim.autopilot_endpoint import SimAutopilot, SimConfig
from sim.autopilot_modes import DEFAULT_ORIGIN, GeoPoint, Profile
from sim.wind import WindConfig

__all__ = ["SimAutopilot", "SimConfig", "config_from_args", "main"]

_WIND = WindConfig()


def _parse_args(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m sim.autopilot", description=__doc__.split("\n\n")[0])
    ap.add_argument("--udp", default="127.0.0.1:14540", help="HOST:PORT where MAVSDK listens (udpin)")
    ap.add_argument("--pilot-port", type=int, default=14580, help="pilot/GCS UDP port on 127.0.0.1; 0 = off")
    ap.add_argument("--profile", choices=[p.value for p in Profile], default=Profile.PX4.value)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--wind-mps", type=float, default=_WIND.mean_mps, help="mean wind speed, m/s")
    ap.add_argument("--gust-mps", type=float, default=_WIND.gust_sigma_mps, help="gust std dev, m/s")
    ap.add_argument("--wind-from-deg", type=float, default=_WIND.from_deg, help="wind from, deg")
    ap.add_argument("--no-wind", action="store_true", help="still air")
    ap.add_argument("--state-log", default=None, help="JSON-lines state log file")
    ap.add_argument("--home", default=None, help="LAT,LON,ALT (deg, deg, m AMSL)")
    ap.add_argument("--param", action="append", default=[], help="NAME=VALUE parameter override")
    return ap.parse_args(argv)


def config_from_args(args: argparse.Namespace) -> SimConfig:
    host, _, port = args.udp.rpartition(":")
    origin = DEFAULT_ORIGIN
    if args.home:
        lat, lon, alt = (float(v) for v in args.home.split(","))
        origin = GeoPoint(lat, lon, alt)
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
    params = {k: float(v) for k, v in (item.split("=", 1) for item in args.param)}
    return SimConfig(
        target=(host or "127.0.0.1", int(port)),
        pilot_port=args.pilot_port or None,
        profile=Profile(args.profile),
        seed=args.seed,
        wind=wind,
        origin=origin,
        state_log=args.state_log,
        params=params or None,
    )


def main(argv: list[str] | None = None) -> int:
    config = config_from_args(_parse_args(argv))
    try:
        sim = SimAutopilot(config)
    except OSError as e:
        print(f"sim.autopilot: cannot open the pilot port {config.pilot_port}: {e}", file=sys.stderr)
        return 2
    stop = threading.Event()

    def _on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    host, port = config.target
    pilot_port = sim.pilot_address[1] if sim.pilot_address else 0
    print(f"sim.autopilot: sending to {host}:{port}, pilot port {pilot_port}", flush=True)
    try:
        sim.run(stop)
    finally:
        sim.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
