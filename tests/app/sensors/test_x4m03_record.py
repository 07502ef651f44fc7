"""``python -m app.sensors.x4m03_record``: the real driver records the emulator's frames to a seapick file."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from app.sensors.x4m03_recording import read_recording
from sim.radar import sea_emulator
from sim.radar_firmware import FirmwareConfig
from sim.radar_track import hover

ROOT = Path(__file__).resolve().parents[3]


def test_record_cli_writes_consecutive_frames_from_the_emulator_pty(tmp_path):
    emu = sea_emulator(track=hover(1.5), link_path=str(tmp_path / "x4m03"), firmware_config=FirmwareConfig(0.0, 0.05))
    emu.start()
    try:
        out = tmp_path / "flight.x4rec"
        done = subprocess.run(
            [sys.executable, "-m", "app.sensors.x4m03_record", emu.path, str(out), "--frames", "5"],
            cwd=ROOT, capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    finally:
        emu.stop()
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["frames"] == 5 and summary["connects"] == 1 and summary["dropped_frames"] == 0
    rec = read_recording(out)
    assert rec.axis.bins == 91 and rec.header["settings"]["fps_hz"] == 10.0
    assert rec.counters.tolist() == list(range(int(rec.counters[0]), int(rec.counters[0]) + 5))
    assert emu.firmware.x4.fps_hz == 0.0  # the recorder stopped the stream on its way out


def test_record_cli_refuses_bad_settings_before_touching_the_port(tmp_path):
    settings = tmp_path / "radar.json"
    settings.write_text(json.dumps({"tx_power": 9}))
    args = ["/dev/null", str(tmp_path / "x.x4rec"), "--settings", str(settings)]
    done = subprocess.run(
        [sys.executable, "-m", "app.sensors.x4m03_record", *args], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and "tx_power" in done.stderr
