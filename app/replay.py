"""``python -m app.replay radar FILE [--json]``: replay a radar recording through the altitude estimator.

Exit status: 0 done; 1 done but the plot could not be written (the figures are still printed); 2 bad
input (a file that cannot be read or holds no complete frame, an option out of range, a failed
calibration) — always with one line on stderr.

FILE is a seapick recording (``.x4rec``) or a Novelda ``xethru_datafloat_*.dat`` / ``xethru_baseband_iq_*.dat``
(see ``app.sensors.x4m03_recording``). Per frame it prints the range and amplitude of the strongest echo
(after background removal), and the altitude or ``lost``; ``--json`` prints one JSON object instead. A
plot (amplitude over range and time, with the altitude on top) goes to ``--plot`` (default under
``runs/replay/``; ``--plot ''`` for none).

Method: by default the adaptive clutter map, as the thesis replayed its crane test (§5.1.4); with
``--calibration-frames N`` the background map from the first N frames (which must see the sea out of
range: a failed calibration is reported with its reason, exit status 2). Recordings hold no attitude,
so no tilt correction is applied.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path
from typing import Literal

import numpy as np

from app.cli import OneLineParser, number, run_cli
from app.errors import AppError
from app.estimators.radar_altitude import (
    AltitudeEstimate,
    RadarAltitudeEstimator,
    calibrate_background,
)
from app.messages import RangeAxis
from app.sensors.x4m03_recording import DEFAULT_FPS_HZ, Recording, read_recording
from app.settings import RadarAltitudeSettings

ROOT = Path(__file__).resolve().parents[1]


def replay_radar(
    recording: Recording, config: RadarAltitudeSettings, calibration_frames: int
) -> tuple[list[AltitudeEstimate], int]:
    """Estimates for every frame and the number of frames rejected for NaN/inf; raises ValueError with the
    reason when the calibration fails."""
    frames = list(recording.frames())
    estimator = RadarAltitudeEstimator(config)
    if config.method == "background":
        result = calibrate_background(frames[:calibration_frames], config)
        estimator.calibrate(result)  # ValueError("calibration failed: …") when it did not work
    return [estimator.update(f) for f in frames], estimator.rejected_non_finite


def _number(x: float | None, digits: int) -> float | None:
    return None if x is None or not math.isfinite(x) else round(x, digits)


def as_rows(recording: Recording, estimates: list[AltitudeEstimate]) -> list[dict[str, object]]:
    return [
        {
            "t_s": round(float(t), 4),
            "counter": int(c),
            "range_m": _number(e.range_m, 4),
            "amplitude": _number(e.amplitude, 6) if e.range_m is not None else None,
            "altitude_m": _number(e.altitude_m, 4) if e.accepted else None,
            "status": e.status,
        }
        for t, c, e in zip(recording.t_s, recording.counters, estimates, strict=True)
    ]


def plot(recording: Recording, estimates: list[AltitudeEstimate], path: Path) -> Path | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    axis, t = recording.axis, recording.t_s
    fig, ax = plt.subplots(figsize=(10, 4))
    extent = (float(t[0]), float(t[-1]) if len(t) > 1 else float(t[0]) + 1.0, axis.start_m, axis.end_m)
    amplitude_db = 20.0 * np.log10(np.abs(recording.baseband).T + 1e-7)
    image = ax.imshow(amplitude_db, aspect="auto", origin="lower", extent=extent, cmap="viridis", vmin=-90)
    fig.colorbar(image, ax=ax, label="|I + jQ|, dB")
    accepted = [(float(tt), e.altitude_m) for tt, e in zip(t, estimates, strict=True) if e.accepted]
    if accepted:
        ax.plot(*zip(*accepted, strict=True), "r.", markersize=3, label="altitude (accepted)")
        ax.legend(loc="upper right")
    ax.set_xlabel("t, s")
    ax.set_ylabel("range / altitude, m")
    ax.set_title(f"{recording.path.name}: |I + jQ| and the altitude")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _axis(values: list[float]) -> RangeAxis:
    start_m, bin_m, bins = values
    if not math.isfinite(start_m) or not -10.0 <= start_m <= 100.0:
        raise ValueError(f"--axis START_M {start_m:g} is outside -10..100 m")
    if not (math.isfinite(bin_m) and 0.0 < bin_m <= 1.0):
        raise ValueError(f"--axis BIN_M {bin_m:g} is outside 0 (exclusive)..1 m")
    if not (math.isfinite(bins) and bins == int(bins) and 1 <= bins <= 4096):
        raise ValueError(f"--axis BINS {bins:g} is not a whole number in 1..4096")
    return RangeAxis(start_m, bin_m, int(bins))


def radar_main(argv: list[str]) -> int:
    ap = OneLineParser(
        prog="python -m app.replay radar",
        description=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("file", type=Path, help="a .x4rec recording or a Novelda xethru_datafloat/baseband_iq .dat file")
    ap.add_argument("--json", action="store_true", help="one JSON object on stdout")
    ap.add_argument(
        "--calibration-frames",
        type=number(0, 1e6, "frames", int),
        default=0,
        help="background map from the first N frames (0: the adaptive clutter map)",
    )
    ap.add_argument(
        "--threshold",
        type=number(0.0, 1e3, ""),
        default=RadarAltitudeSettings().threshold_amplitude,
        help="T_abs, the absolute amplitude threshold of an echo",
    )
    ap.add_argument(
        "--axis",
        nargs=3,
        type=float,
        metavar=("START_M", "BIN_M", "BINS"),
        help="range axis of a datafloat file (which holds none): first bin's range, bin length, bin count",
    )
    ap.add_argument(
        "--fps", type=number(0.01, 1000.0, "Hz"), default=DEFAULT_FPS_HZ, help="frame rate of Novelda files, Hz"
    )
    ap.add_argument("--plot", default=None, help="PNG path ('' for none; default runs/replay/<name>_radar.png)")
    args = ap.parse_args(argv)
    try:
        axis = _axis(args.axis) if args.axis else None
    except ValueError as e:
        ap.error(str(e))
    try:
        recording = read_recording(args.file, axis, args.fps)
    except (AppError, OSError) as e:
        print(f"cannot replay: {e}", file=sys.stderr)
        return 2
    if len(recording) == 0:
        print(
            f"cannot replay: {args.file} holds no complete frame ({recording.truncated_bytes} bytes)", file=sys.stderr
        )
        return 2
    method: Literal["background", "clutter_map"] = "background" if args.calibration_frames > 0 else "clutter_map"
    config = RadarAltitudeSettings(method=method, threshold_amplitude=args.threshold)
    try:
        estimates, rejected = replay_radar(recording, config, args.calibration_frames)
    except ValueError as e:
        print(f"cannot replay: {e}", file=sys.stderr)
        return 2
    rows = as_rows(recording, estimates)
    figure_path = ROOT / "runs" / "replay" / f"{args.file.name}_radar.png" if args.plot is None else Path(args.plot)
    figure, figure_error = None, None
    if args.plot != "":
        try:
            figure = plot(recording, estimates, figure_path)
        except OSError as e:
            figure_error = f"cannot write the plot {figure_path}: {e.strerror or e}"
    summary = {
        "frames": len(rows),
        "tracking": sum(r["status"] == "tracking" for r in rows),
        "holding": sum(r["status"] == "holding" for r in rows),
        "lost": sum(r["status"] == "lost" for r in rows),
        "non_finite_frames": rejected,
        "truncated_bytes": recording.truncated_bytes,
    }
    status = 0 if figure_error is None else 1
    if args.json:
        head = {"file": str(args.file), "kind": recording.kind, "method": method}
        axis_out = {"start_m": recording.axis.start_m, "bin_m": recording.axis.bin_m, "bins": recording.axis.bins}
        print(
            json.dumps({**head, "axis": axis_out, "summary": summary, "figure": figure and str(figure), "frames": rows})
        )
        if figure_error:
            print(figure_error, file=sys.stderr)
        return status
    print(f"{args.file} ({recording.kind}, {recording.axis.bins} bins from {recording.axis.start_m:.4f} m), {method}")
    print(f"{'t_s':>9} {'counter':>8} {'range_m':>8} {'amplitude':>10}  altitude_m")
    for r in rows:
        altitude = r["status"] if r["altitude_m"] is None else f"{r['altitude_m']:.3f}"
        echo = "     NaN/inf frame" if r["range_m"] is None else f"{r['range_m']:8.3f} {r['amplitude']:10.6f}"
        print(f"{r['t_s']:9.3f} {r['counter']:8d} {echo}  {altitude}")
    print(json.dumps(summary))
    if figure:
        print(f"figure: {figure}")
    if figure_error:
        print(figure_error, file=sys.stderr)
    return status


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if args and args[0] in ("-h", "--help"):
        print(f"usage: python -m app.replay radar FILE [--json] [options]\n\n{__doc__}")
        print("python -m app.replay radar --help lists the options.")
        return 0
    if not args or args[0] != "radar":
        print("python -m app.replay: error: the first argument must be 'radar' (--help for more)", file=sys.stderr)
        return 2
    try:
        return radar_main(args[1:])
    except BrokenPipeError:  # piped into head: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m app.replay radar"))
