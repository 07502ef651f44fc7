"""X4M03 emulator on a pseudo-terminal: ``python -m sim.radar [--link PATH] [options]``.

Creates a pty in raw mode (``tty.setraw`` before anyone opens it: a cooked pty would echo and rewrite
0x0A/0x7F), prints the path to open on the first line of stdout, and runs the firmware state machine
(``sim.radar_firmware``) on the wall clock, with echoes from the simulated sea (``sim.radar_signal``).
Output is written in random-sized chunks (USB delivers ≤ 512-byte bulk packets); if nobody drains the
port, whole messages are dropped after ~1 s of backlog, as the firmware does.

``--link PATH`` keeps a stable symlink to the current pty, like udev's /dev/serial/by-id names: unplugging
removes it and closes the pty (the host's reads fail), replugging makes a new pty, points the link at it
and boots again. In the CLI, SIGUSR1 toggles unplug/replug and SIGUSR2 corrupts the next host command.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import fcntl
import json
import math
import os
import select
import signal
import sys
import threading
import time
import tty
from collections.abc import Sequence

import numpy as np

from app.cli import OneLineParser, handle_signals_in_thread, number, run_cli
from app.messages import RangeAxis
from sim.radar_firmware import FirmwareConfig, FirmwareFaults, X4M03Firmware
from sim.radar_signal import RadarSignalConfig, SeaRadarScene
from sim.radar_track import TrackConfig, VehicleTrack
from sim.sea import SeaConfig, SeaWorld

MAX_BACKLOG_BYTES = 8192  # ≈ 1 s of frames: beyond it new messages are dropped
USB_PACKET_BYTES = 512


class RadarEmulator:
    """The firmware on a pty, served by one thread; ``unplug``/``replug``/faults from any thread."""

    def __init__(self, firmware: X4M03Firmware, link_path: str | None = None, seed: int = 0) -> None:
        self.firmware = firmware
        self.link_path = link_path
        self.dropped_bytes = 0
        self._rng = np.random.default_rng(seed)
        self._lock = threading.RLock()
        self._master: int | None = None
        self._slave: int | None = None
        self._pts_path: str | None = None
        self._out = bytearray()
        self._wake_r, self._wake_w = os.pipe()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = time.monotonic()

    @property
    def path(self) -> str:
        """The path a host opens: the symlink if there is one, else the current pty."""
        if self.link_path is not None:
            return self.link_path
        assert self._pts_path is not None, "not plugged in"
        return self._pts_path

    @property
    def plugged(self) -> bool:
        return self._master is not None

    def now_s(self) -> float:
        return time.monotonic() - self._t0

    def start(self) -> str:
        self.replug()
        self._thread = threading.Thread(target=self._serve, name="sim.radar", daemon=True)
        self._thread.start()
        return self.path

    def stop(self) -> None:
        self._stop.set()
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.unplug()
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    def unplug(self) -> None:
        """The device disappears: the pty closes (host reads fail) and the link goes away."""
        with self._lock:
            if self.link_path is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(self.link_path)
            for fd in (self._master, self._slave):
                if fd is not None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._master = self._slave = None
            self._pts_path = None
            self._out.clear()
        self._wake()

    def replug(self) -> None:
        """A new pty (raw mode), the link pointed at it, and the firmware powered on."""
        with self._lock:
            if self._master is not None:
                return
            master, slave = os.openpty()
            tty.setraw(slave)
            fcntl.fcntl(master, fcntl.F_SETFL, fcntl.fcntl(master, fcntl.F_GETFL) | os.O_NONBLOCK)
            self._master, self._slave, self._pts_path = master, slave, os.ttyname(slave)
            if self.link_path is not None:
                tmp = f"{self.link_path}.tmp{os.getpid()}"
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
                os.symlink(self._pts_path, tmp)
                os.replace(tmp, self.link_path)
            self.firmware.power_on(self.now_s())
        self._wake()

    def faults(self) -> FirmwareFaults:
        return self.firmware.faults

    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")

    def _serve(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                master = self._master
                due = self.firmware.next_due_s() if master is not None else None
                want_write = master is not None and bool(self._out)
            timeout = None if due is None else max(0.0, due - self.now_s())
            readers = [self._wake_r] + ([master] if master is not None else [])
            try:
                readable, writable, _ = select.select(readers, [master] if want_write else [], [], timeout)
            except (OSError, ValueError):
                continue  # the pty was closed under us (unplug): go round again
            if self._wake_r in readable:
                os.read(self._wake_r, 4096)
            with self._lock:
                if self._master is None or self._master != master:
                    continue
                if master in readable:
                    self._read_host(master)
                self._emit(self.firmware.poll(self.now_s()))
                if master in writable or self._out:
                    self._flush(master)

    def _read_host(self, master: int) -> None:
        try:
            data = os.read(master, 4096)
        except OSError as e:
            if e.errno in (errno.EAGAIN, errno.EIO):  # EIO: no host has the port open right now
                return
            raise
        self._emit(self.firmware.receive(data, self.now_s()))

    def _emit(self, data: bytes) -> None:
        if not data:
            return
        if len(self._out) + len(data) > MAX_BACKLOG_BYTES:
            self.dropped_bytes += len(data)  # the host is not draining: drop whole messages
            return
        self._out += data

    def _flush(self, master: int) -> None:
        while self._out:
            n = int(self._rng.integers(1, USB_PACKET_BYTES + 1))
            try:
                written = os.write(master, self._out[:n])
            except BlockingIOError:
                return
            except OSError:
                self._out.clear()
                return
            del self._out[:written]


def sea_emulator(
    sea_state: int = 1,
    track: TrackConfig | None = None,
    seed: int = 0,
    link_path: str | None = None,
    firmware_config: FirmwareConfig | None = None,
    faults: FirmwareFaults | None = None,
    signal: RadarSignalConfig | None = None,
) -> RadarEmulator:
    """An emulator whose echoes come from a seeded sea under a vehicle following ``track``."""
    sea = SeaWorld(SeaConfig(sea_state=sea_state), seed)
    scene = SeaRadarScene(sea, VehicleTrack(track or TrackConfig(), seed), signal, seed)

    def frames(t_s: float, axis: RangeAxis) -> np.ndarray:
        return scene.baseband(t_s, axis)[0]

    return RadarEmulator(X4M03Firmware(frames, firmware_config, faults, seed), link_path, seed)


def _parse_profile(text: str) -> tuple[tuple[float, float], ...]:
    """``"0:6.5,5:6.5,10:1.5"`` → ((0, 6.5), (5, 6.5), (10, 1.5))."""
    points: list[tuple[float, float]] = []
    for item in text.split(","):
        t_text, _, h_text = item.partition(":")
        try:
            t, h = float(t_text), float(h_text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not t_s:height_m,... (e.g. 0:6.5,5:6.5,10:1.5)") from None
        if not (math.isfinite(t) and 0.0 <= t and 0.05 <= h <= 50.0) or (points and t <= points[-1][0]):
            raise argparse.ArgumentTypeError(f"{item}: times rise from 0, heights 0.05..50 m")
        points.append((t, h))
    return tuple(points)


def main(argv: Sequence[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m sim.radar", description=__doc__.split("\n")[0])
    ap.add_argument("--link", help="stable symlink to the current pty (like /dev/serial/by-id/...)")
    ap.add_argument("--sea-state", type=int, default=1, choices=range(6))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--height-m", type=number(0.05, 50.0, "m"), default=2.0, help="hover height above the mean sea")
    ap.add_argument("--profile", type=_parse_profile, help="height waypoints t_s:height_m,... instead")
    ap.add_argument("--tilt-deg", type=number(0.0, 45.0, "deg"), default=3.0, help="RMS roll/pitch wobble")
    ap.add_argument("--boot-delay-s", type=number(0.0, 60.0, "s"), default=1.0, help="power-on to BOOTING, s")
    ap.add_argument("--ready-delay-s", type=number(0.0, 60.0, "s"), default=1.0, help="BOOTING to READY, s")
    ap.add_argument("--escaped-frames", action="store_true", help="legacy escaped DataFloat frames")
    prob = number(0.0, 1.0)
    ap.add_argument("--garbage-prob", type=prob, default=0.0, help="chance of line noise before a frame")
    ap.add_argument("--drop-prob", type=prob, default=0.0, help="chance a frame is dropped")
    ap.add_argument("--corrupt-reply-prob", type=prob, default=0.0, help="chance a reply is corrupted")
    ap.add_argument(
        "--duration-s", type=number(0.0, 1e6, "s"), default=0.0, help="exit after this long (0: until SIGINT)"
    )
    args = ap.parse_args(argv)
    track = TrackConfig(waypoints=args.profile or ((0.0, args.height_m),), tilt_wobble_deg=args.tilt_deg)
    emulator = sea_emulator(
        args.sea_state,
        track,
        args.seed,
        args.link,
        FirmwareConfig(args.boot_delay_s, args.ready_delay_s, args.escaped_frames),
        FirmwareFaults(args.garbage_prob, 40, args.drop_prob, args.corrupt_reply_prob),
    )
    done = threading.Event()

    def toggle_plug() -> None:
        emulator.unplug() if emulator.plugged else emulator.replug()
        print(json.dumps({"plugged": emulator.plugged}), flush=True)

    def corrupt_next() -> None:
        emulator.faults().corrupt_next_commands += 1

    handle_signals_in_thread({signal.SIGUSR1: toggle_plug, signal.SIGUSR2: corrupt_next, signal.SIGTERM: done.set})
    print(emulator.start(), flush=True)
    try:
        done.wait(args.duration_s if args.duration_s > 0 else None)
    except KeyboardInterrupt:
        pass
    finally:
        emulator.stop()
    log = emulator.firmware.log
    summary = {"frames_sent": log.frames_sent, "frames_dropped": log.frames_dropped, "crc_errors": log.crc_errors}
    print(json.dumps({**summary, "boots": log.boots, "commands": len(log.commands)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.radar"))
