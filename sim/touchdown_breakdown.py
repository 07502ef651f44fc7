"""``python -m sim.touchdown_breakdown RUN_DIR [RUN_DIR ...] [--json]``: where a grab's touchdown error came from.

Reads a run directory — a MAVLink flight's (``app.main --sim``) or an evaluation run's (``sim.evaluate``, a run
written with its ``run_dir``) — and splits the horizontal distance from the vehicle to the object at each grab
into what the mission believed and what it did, at the last ``pickup`` record (5 Hz) before the gripper closed:

    vehicle_true − object_true = (vehicle_est − estimate) + (estimate − offset − object_true)
                                 └── tracking error ────┘   └── estimate error ─────────────┘

``offset`` = vehicle_est − vehicle_true, the autopilot's estimate error at that instant (the mission sees the
object in the autopilot's frame, so the same offset is taken off its estimate). The tracking error is guidance
and the autopilot not putting the vehicle over the estimate; the estimate error is the target filter's, which
grows while the camera is blind (``blind_s``: from the capture of the last fused fix to the grab). Also given:
the estimate error at the last fused fix (what the filter knew before going blind).

Times: ``sim_state.jsonl`` counts from the simulator's boot; adding its ``start`` record's ``boot_monotonic_s``
gives the app's loop time of ``events.jsonl`` (0 for the in-process vehicle, where both are the loop's clock).
Truth is interpolated linearly between its records (10 Hz MAVLink, 5 Hz in process).
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.cli import OneLineParser, run_cli
from app.report import read_jsonl

PICKUP_MAX_LEAD_S = 0.3  # the pickup record used is at most this long before the grab (its period is 0.2 s)


@dataclass(frozen=True)
class GrabBreakdown:
    t_s: float  # the grab, app loop time
    touchdown_error_m: float  # the simulator's: gripper to object, horizontal
    blind_s: float | None  # capture of the last fused fix → grab
    record_lead_s: float  # how long before the grab the pickup record is
    tracking_error_m: float  # |vehicle_est − estimate| at the record
    estimate_error_m: float  # |estimate − offset − object_true| at the record
    estimate_error_at_last_fix_m: float | None  # the same at the last record up to the last fused fix


def _track(rows: list[dict[str, Any]], event: str, boot_s: float) -> tuple[np.ndarray, np.ndarray]:
    pts = [(r["t_s"] + boot_s, r["pos_ned_m"][0], r["pos_ned_m"][1]) for r in rows if r.get("event") == event]
    if len(pts) < 2:
        raise ValueError(f"sim_state.jsonl has fewer than 2 '{event}' records")
    a = np.asarray(pts, dtype=np.float64)
    return a[:, 0], a[:, 1:]


def _at(track: tuple[np.ndarray, np.ndarray], t_s: float) -> np.ndarray:
    ts, ne = track
    return np.array([np.interp(t_s, ts, ne[:, 0]), np.interp(t_s, ts, ne[:, 1])])


def _errors(
    record: dict[str, Any], vehicle: tuple[np.ndarray, np.ndarray], obj: tuple[np.ndarray, np.ndarray]
) -> tuple[float, float]:
    """(tracking error, estimate error) at a pickup record, m."""
    t_s = record["t_s"]
    vehicle_est, estimate = np.asarray(record["vehicle_ne_m"]), np.asarray(record["estimate_ne_m"])
    offset = vehicle_est - _at(vehicle, t_s)
    return float(np.hypot(*(vehicle_est - estimate))), float(np.hypot(*(estimate - offset - _at(obj, t_s))))


def breakdown(run_dir: Path) -> list[GrabBreakdown]:
    """One ``GrabBreakdown`` per grab of the run that has a pickup record with an estimate just before it."""
    state = list(read_jsonl(run_dir / "sim_state.jsonl"))  # (a last line cut off by a crash is skipped)
    events = list(read_jsonl(run_dir / "events.jsonl"))
    start = next((r for r in state if r.get("event") == "start"), {})
    boot_s = float(start.get("boot_monotonic_s") or 0.0)
    vehicle, obj = _track(state, "truth", boot_s), _track(state, "object", boot_s)
    fixes = sorted(e["t_s"] for e in events if e.get("kind") == "fix" and e.get("result") == "fused")
    records = [e for e in events if e.get("kind") == "pickup" and e.get("estimate_ne_m") and e.get("vehicle_ne_m")]
    out = []
    for grab in (r for r in state if r.get("event") == "grab"):
        t_s = grab["t_s"] + boot_s
        before = [r for r in records if t_s - PICKUP_MAX_LEAD_S <= r["t_s"] <= t_s]
        if not before:
            continue
        record = before[-1]
        tracking_m, estimate_m = _errors(record, vehicle, obj)
        last_fix = next((f for f in reversed(fixes) if f <= t_s), None)
        at_fix = [r for r in records if last_fix is not None and last_fix - PICKUP_MAX_LEAD_S <= r["t_s"] <= last_fix]
        out.append(
            GrabBreakdown(
                t_s=round(t_s, 3),
                touchdown_error_m=round(float(grab["error_m"]), 4),
                blind_s=None if last_fix is None else round(t_s - last_fix, 3),
                record_lead_s=round(t_s - record["t_s"], 3),
                tracking_error_m=round(tracking_m, 4),
                estimate_error_m=round(estimate_m, 4),
                estimate_error_at_last_fix_m=round(_errors(at_fix[-1], vehicle, obj)[1], 4) if at_fix else None,
            )
        )
    return out


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="python -m sim.touchdown_breakdown", description=__doc__.split("\n\n")[0])
    p.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout: {run_dir: [grab, …]}")
    args = p.parse_args(argv)
    result = {str(d): [asdict(g) for g in breakdown(d)] for d in args.run_dirs}
    if args.json:
        print(json.dumps(result))
        return 0
    print("run                          grab t s  touchdown m  blind s  tracking m  estimate m  (at last fix m)")
    for d, grabs in result.items():
        for g in grabs:
            blind = "-" if g["blind_s"] is None else f"{g['blind_s']:.2f}"
            at_fix = "-" if g["estimate_error_at_last_fix_m"] is None else f"{g['estimate_error_at_last_fix_m']:.3f}"
            print(
                f"{d[-28:]:28s} {g['t_s']:9.2f} {g['touchdown_error_m']:12.3f} {blind:>8} "
                f"{g['tracking_error_m']:11.3f} {g['estimate_error_m']:11.3f}  ({at_fix})"
            )
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.touchdown_breakdown"))
