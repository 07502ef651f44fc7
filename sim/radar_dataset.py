"""``python -m sim.radar_dataset --out DIR``: radar recordings over the simulated sea, with their ground truth.

For the radar benchmark (``python -m app.bench radar``), which must not import the simulator: the data go
to disk in seapick's own recording format. Per sea state and hover height, one run of the thesis's crane
manoeuvre made a multirotor's: hold at a calibration height with the sea out of range (the background map
is taken there), descend at 1 m/s, hover. Frames at the X4's 10.032 Hz on the thesis's quantised axis.

``DIR/manifest.json`` lists the runs; per run ``NAME.x4rec`` (frames) and ``NAME.truth.npz``:
``t_s``, ``height_m`` (truth: reference point above the instantaneous sea surface under it) and the
attitude the vehicle would report, ``roll_rad``, ``pitch_rad``.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from app.cli import OneLineParser, int_list, number, run_cli
from app.messages import RadarFrame
from app.sensors.x4m03_frame_area import quantise_frame_area
from app.sensors.x4m03_recording import RecordingWriter
from sim.radar_firmware import measured_fps
from sim.radar_signal import RadarSignalConfig, SeaRadarScene
from sim.radar_track import VehicleTrack, calibrate_then_hover
from sim.sea import SeaConfig, SeaWorld

CALIBRATION_S = 3.0
CALIBRATION_CLEARANCE_M = 2.5  # calibration height above the frame-area end, plus the crest height


def hover_heights_m(sea_state: int, hs_m: float) -> list[float]:
    """Hover heights above the mean sea: 0.5–4.5 m, lifted by Hs/2 + 0.25 m in waves so the sea stays below."""
    lift_m = 0.0 if hs_m <= 0.1 else round(hs_m / 2 + 0.25, 1)
    return [round(0.5 + 0.5 * k + lift_m, 2) for k in range(9)]


def make_run(out: Path, name: str, sea_state: int, hover_m: float, hover_s: float, seed: int) -> dict[str, Any]:
    sea = SeaWorld(SeaConfig(sea_state=sea_state), seed)
    axis = quantise_frame_area(0.4, 5.0, 0.18)
    calibration_m = axis.end_m + CALIBRATION_CLEARANCE_M + sea.sea_state.hs_m / 2
    track = VehicleTrack(calibrate_then_hover(calibration_m, hover_m, CALIBRATION_S), seed)
    config = RadarSignalConfig()
    scene = SeaRadarScene(sea, track, config, seed)
    period_s = 1.0 / measured_fps(10.0)
    duration_s = track.config.waypoints[-1][0] + hover_s
    times = np.arange(1, int(duration_s / period_s) + 1) * period_s
    height_m: list[float] = []
    roll_rad: list[float] = []
    pitch_rad: list[float] = []
    with RecordingWriter(out / f"{name}.x4rec", axis, {"fps_hz": 1.0 / period_s, "source": "sim.radar_dataset"}) as rec:
        for counter, t_s in enumerate(times, start=1):
            z, t = scene.baseband(float(t_s), axis)
            rec.write(RadarFrame(float(t_s), counter, axis, z))
            height_m.append(t.height_m)
            roll_rad.append(t.pose.roll_rad)
            pitch_rad.append(t.pose.pitch_rad)
    np.savez(
        out / f"{name}.truth.npz",
        t_s=times,
        height_m=np.asarray(height_m),
        roll_rad=np.asarray(roll_rad),
        pitch_rad=np.asarray(pitch_rad),
    )
    return {
        "name": name,
        "sea_state": sea_state,
        "hover_height_m": hover_m,
        "calibration_height_m": round(calibration_m, 3),
        "calibration_frames": int(CALIBRATION_S / period_s),
        "frames": len(times),
        "recording": f"{name}.x4rec",
        "truth": f"{name}.truth.npz",
    }


def main(argv: Sequence[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m sim.radar_dataset", description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sea-states", type=int_list(0, 5), default="0,1,3", help="comma-separated WMO codes 0..5")
    ap.add_argument("--hover-s", type=number(0.5, 3600.0, "s"), default=30.0, help="hover time per run, s")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    runs = []
    for sea_state in args.sea_states:
        hs_m = SeaWorld(SeaConfig(sea_state=sea_state), args.seed).sea_state.hs_m
        for k, hover_m in enumerate(hover_heights_m(sea_state, hs_m)):
            name = f"ss{sea_state}_h{hover_m:.2f}".replace(".", "p")
            runs.append(make_run(args.out, name, sea_state, hover_m, args.hover_s, args.seed * 100 + k))
    manifest = {
        "format": 1,
        "seed": args.seed,
        "antenna_offset_frd_m": list(RadarSignalConfig().antenna_offset_frd_m),
        "runs": runs,
    }
    (args.out / "manifest.json").write_text(json.dumps(manifest, indent=1))
    print(json.dumps({"out": str(args.out), "runs": len(runs), "frames": sum(int(r["frames"]) for r in runs)}))
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.radar_dataset"))
