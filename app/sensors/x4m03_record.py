"""``python -m app.sensors.x4m03_record PORT OUT [--frames N]``: record X4M03 frames to a seapick recording.

Connects with the thesis settings (or ``--settings FILE.json``), streams, and writes every frame it gets
(``app.sensors.x4m03_recording``) until N frames or Ctrl-C; the radar keeps reconnecting if unplugged.
Prints one JSON summary line with the driver's counters. Works on the emulator's pty just the same.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import sys
from dataclasses import asdict
from pathlib import Path

from app.cli import OneLineParser, number, run_cli
from app.config_yaml import validate_section
from app.errors import AppError
from app.sensors.radar import Radar
from app.sensors.x4m03_driver import X4M03Radar
from app.sensors.x4m03_recording import RecordingWriter, read_recording
from app.settings import RadarSettings


async def record(radar: Radar, out: Path, frames: int, header: dict[str, object]) -> int:
    """Run ``radar`` and write ``frames`` frames to ``out`` (the axis of the first frame); returns the count."""
    async with asyncio.TaskGroup() as group:
        task = group.create_task(radar.run(), name="radar.run")
        first = await radar.next_frame()
        with RecordingWriter(out, first.axis, header) as writer:
            writer.write(first)
            while writer.frames < frames:
                frame = await radar.next_frame()
                if frame.axis == writer.axis:
                    writer.write(frame)
        task.cancel()
    return writer.frames


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m app.sensors.x4m03_record", description=__doc__.split("\n")[0])
    ap.add_argument("port", help="the radar's serial device (or the emulator's pty link)")
    ap.add_argument("out", type=Path, help="the recording to write (.x4rec)")
    ap.add_argument("--frames", type=number(1, 1_000_000_000, "", int), default=100, help="stop after N frames")
    ap.add_argument("--settings", type=Path, help="JSON object of RadarSettings fields")
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    if not Path(args.port).exists():  # once recording, an unplugged radar is waited for; at the start, a typo is not
        ap.error(f"{args.port}: no such device")
    try:
        fields = json.loads(args.settings.read_text()) if args.settings else {}
        settings = validate_section(
            RadarSettings, {**fields, "port": args.port}, str(args.settings or "radar settings")
        )
    except (AppError, OSError, ValueError) as e:
        print(f"cannot record: {e}", file=sys.stderr)
        return 2
    radar = X4M03Radar(settings)
    header: dict[str, object] = {"settings": settings.model_dump(), "source": "app.sensors.x4m03_record"}
    status = 0
    try:
        with contextlib.suppress(KeyboardInterrupt):
            asyncio.run(record(radar, args.out, args.frames, header))
    except* AppError as group:
        print(f"cannot record: {group.exceptions[0]}", file=sys.stderr)
        status = 1
    written = len(read_recording(args.out)) if args.out.exists() else 0
    print(json.dumps({"out": str(args.out), "frames": written, **_counters(radar)}))
    return status


def _counters(radar: X4M03Radar) -> dict[str, object]:
    stats = asdict(radar.stats)
    stats["parser"] = {k: v for k, v in stats["parser"].items() if v}
    return stats


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m app.sensors.x4m03_record"))
