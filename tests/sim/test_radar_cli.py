"""``python -m sim.radar``: prints the pty path, answers like the firmware, unplugs/replugs on SIGUSR1."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import serial

WAIT_S = 15.0


def read_exactly(port: serial.Serial, n: int) -> bytes:
    port.timeout = WAIT_S
    return port.read(n)


def wait_for(check, timeout_s: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not check():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.02)


def test_cli_emulator_on_a_pty_answers_ping_and_unplugs_and_replugs(tmp_path: Path):
    link = tmp_path / "radar"
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim.radar", "--link", str(link), "--boot-delay-s", "0", "--ready-delay-s", "0.05"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], WAIT_S)
        assert ready, "the emulator printed no path"
        assert proc.stdout.readline().strip() == str(link)
        assert os.path.realpath(link).startswith("/dev/pts/")

        def answers_ping() -> None:
            with serial.Serial(str(link), 115200) as port:
                port.reset_input_buffer()

                def pong() -> bytes:
                    port.write(bytes.fromhex("7D 01 AE EA AA EE 7C 7E"))
                    return read_exactly(port, 8)

                wait_for(lambda: pong() == bytes.fromhex("7D 01 EA AE EE AA 7C 7E"))  # once READY

        answers_ping()
        proc.send_signal(signal.SIGUSR1)
        assert json.loads(proc.stdout.readline()) == {"plugged": False}
        assert not link.exists()
        proc.send_signal(signal.SIGUSR1)
        assert json.loads(proc.stdout.readline()) == {"plugged": True}
        assert link.exists()
        answers_ping()  # the replugged device booted again and is READY
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(WAIT_S) == 0
        summary = json.loads(proc.stdout.readline())
        assert summary["boots"] == 2 and summary["crc_errors"] == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
