"""Switch the simulated vehicle's flight mode as an RC pilot would, through its pilot/GCS port.

Sends MAV_CMD_DO_SET_MODE (PX4 main/sub mode, or the ArduCopter mode number when the vehicle's
HEARTBEAT says ArduPilot) to ``sim.autopilot``'s pilot port, waits for the COMMAND_ACK and for a
HEARTBEAT that shows the new mode. Speaks as a ground station (sysid 255, compid 190).

CLI::

    python -m sim.pilot --mode POSCTL [--port 14580] [--host 127.0.0.1] [--timeout-s 3]
    python -m sim.pilot --status

Modes: MANUAL, ALTCTL, POSCTL, STABILIZED, HOLD, OFFBOARD, RTL, LAND. Exit 0 on success, 1 otherwise.
"""

from __future__ import annotations

import socket
import time
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

from app.cli import OneLineParser, number, run_cli
from app.messages import FlightMode
from sim.autopilot_modes import Mode, Profile, mode_for, mode_from_custom

MSG = mavlink
PILOT_MODE_NAMES: dict[str, FlightMode] = {
    "MANUAL": FlightMode.MANUAL,
    "ALTCTL": FlightMode.ALTCTL,
    "POSCTL": FlightMode.POSCTL,
    "STABILIZED": FlightMode.STABILIZED,
    "HOLD": FlightMode.HOLD,
    "OFFBOARD": FlightMode.OFFBOARD,
    "RTL": FlightMode.RETURN_TO_LAUNCH,
    "LAND": FlightMode.LAND,
}
RETRY_S = 0.5


@dataclass(frozen=True, slots=True)
class PilotResult:
    ok: bool
    message: str
    mode: Mode | None = None
    armed: bool = False


class PilotLink:
    """A UDP socket to the pilot port, with a MAVLink 2 parser and sender."""

    def __init__(self, host: str, port: int) -> None:
        self.addr = (host, port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.tx = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.rx = mavlink.MAVLink(None)
        self.rx.robust_parsing = True

    def send(self, msg: mavlink.MAVLink_message) -> None:
        self.sock.sendto(msg.pack(self.tx), self.addr)

    def hello(self) -> None:
        self.send(self.tx.heartbeat_encode(MSG.MAV_TYPE_GCS, MSG.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3))

    def receive(self, deadline: float) -> list[mavlink.MAVLink_message]:
        self.sock.settimeout(max(0.001, deadline - time.monotonic()))
        try:
            data, _ = self.sock.recvfrom(65535)
        except (TimeoutError, OSError):
            return []
        return [m for m in (self.rx.parse_buffer(data) or []) if m.get_srcSystem() == 1]

    def close(self) -> None:
        self.sock.close()


def _decode(hb: mavlink.MAVLink_message) -> tuple[Profile, Mode | None, bool]:
    profile = Profile.ARDUPILOT if hb.autopilot == MSG.MAV_AUTOPILOT_ARDUPILOTMEGA else Profile.PX4
    armed = bool(hb.base_mode & MSG.MAV_MODE_FLAG_SAFETY_ARMED)
    return profile, mode_from_custom(profile, hb.custom_mode), armed


def _wait_heartbeat(link: PilotLink, deadline: float) -> mavlink.MAVLink_message | None:
    next_hello = 0.0
    while time.monotonic() < deadline:
        if time.monotonic() >= next_hello:
            link.hello()
            next_hello = time.monotonic() + RETRY_S
        for msg in link.receive(min(deadline, next_hello)):
            if msg.get_type() == "HEARTBEAT":
                return msg
    return None


def status(host: str = "127.0.0.1", port: int = 14580, timeout_s: float = 3.0) -> PilotResult:
    """The vehicle's current mode, from one heartbeat."""
    link = PilotLink(host, port)
    try:
        hb = _wait_heartbeat(link, time.monotonic() + timeout_s)
    finally:
        link.close()
    if hb is None:
        return PilotResult(False, f"no heartbeat from {host}:{port} within {timeout_s} s")
    profile, mode, armed = _decode(hb)
    name = mode.flight_mode.value if mode else f"custom_mode {hb.custom_mode}"
    label = mode.label if mode else "?"
    return PilotResult(True, f"mode {name} ({label}), armed {armed}, autopilot {profile.value}", mode, armed)


def set_mode(mode_name: str, host: str = "127.0.0.1", port: int = 14580, timeout_s: float = 3.0) -> PilotResult:
    """Switch to ``mode_name`` (one of ``PILOT_MODE_NAMES``) and wait until a heartbeat shows it."""
    flight_mode = PILOT_MODE_NAMES.get(mode_name.upper())
    if flight_mode is None:
        return PilotResult(False, f"unknown mode {mode_name!r}; use one of {', '.join(PILOT_MODE_NAMES)}")
    t_start = time.monotonic()
    deadline = t_start + timeout_s
    link = PilotLink(host, port)
    try:
        hb = _wait_heartbeat(link, deadline)
        if hb is None:
            return PilotResult(False, f"no heartbeat from {host}:{port} within {timeout_s} s")
        profile, _, armed = _decode(hb)
        target = (
            Mode.AP_LOITER
            if (profile, flight_mode) == (Profile.ARDUPILOT, FlightMode.HOLD)
            else (mode_for(profile, flight_mode))
        )
        if target is None:
            return PilotResult(False, f"{profile.value} has no {mode_name} mode")
        if profile is Profile.ARDUPILOT:
            p2, p3 = float(target.custom_mode), 0.0
        else:
            p2, p3 = float((target.custom_mode >> 16) & 0xFF), float((target.custom_mode >> 24) & 0xFF)
        base = MSG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (MSG.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
        command = link.tx.command_long_encode(1, 1, MSG.MAV_CMD_DO_SET_MODE, 0, base, p2, p3, 0, 0, 0, 0)
        acked = False
        next_send = 0.0
        while time.monotonic() < deadline:
            if not acked and time.monotonic() >= next_send:
                link.send(command)
                next_send = time.monotonic() + RETRY_S
            for msg in link.receive(min(deadline, next_send) if not acked else deadline):
                kind = msg.get_type()
                if kind == "COMMAND_ACK" and msg.command == MSG.MAV_CMD_DO_SET_MODE and not acked:
                    if msg.result != MSG.MAV_RESULT_ACCEPTED:
                        result = MSG.enums["MAV_RESULT"][msg.result].name.removeprefix("MAV_RESULT_")
                        return PilotResult(False, f"{mode_name} refused: {result}")
                    acked = True
                elif kind == "HEARTBEAT" and acked and msg.custom_mode == target.custom_mode:
                    dt_s = time.monotonic() - t_start
                    return PilotResult(
                        True,
                        f"mode {target.flight_mode.value} ({target.label}) confirmed in {dt_s:.2f} s",
                        target,
                        bool(msg.base_mode & 128),
                    )
        return PilotResult(False, f"{mode_name}: {'no heartbeat showing it' if acked else 'no ACK'} in {timeout_s} s")
    finally:
        link.close()


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m sim.pilot", description="Switch flight mode like an RC pilot.")
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--mode", choices=list(PILOT_MODE_NAMES), type=str.upper)
    group.add_argument("--status", action="store_true", help="print the current mode and exit")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=number(1, 65535, "", int), default=14580, help="the simulator's pilot port")
    ap.add_argument("--timeout-s", type=number(0.05, 60.0, "s"), default=3.0, help="wait for the answer, s")
    args = ap.parse_args(argv)
    if args.status:
        result = status(args.host, args.port, args.timeout_s)
    else:
        result = set_mode(args.mode, args.host, args.port, args.timeout_s)
    print(f"sim.pilot: {result.message}")
    return 0 if result.ok else 1


if __name__ == "__main__":
    raise SystemExit(run_cli(main, "python -m sim.pilot"))
