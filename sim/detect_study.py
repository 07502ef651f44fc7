"""``python -m sim.detect_study [--seeds N] [--oscillation-m A] [--json]``: the marker detector through descents.

A vehicle descends at 0.5 m/s from 4 m to 0.3 m above the water at a floating object (sea state 2, 0.3 m/s
current), following it as a multirotor does (:func:`descent`): a tracking loop with the object's velocity fed
forward, aiming with an estimate ~0.1 m off, tilting to accelerate (tan θ = a/g) plus ~2° of gusts. That gives
offsets up to ~0.2–0.3 m and tilts of ~4° (p50) to ~12°. ``--oscillation-m`` adds a 1 Hz ringing of the vehicle's
position — 0.08 m gives tilts of ~18° (p50) to ~30°, what the PX4 vehicle of the end-to-end pickup flies.

The simulator's renderer draws each frame at 15 Hz (the app's camera settings, fixed default exposure, the default
conditions: glints and sensor noise) and the app's detector (``make_detector``) is called frame by frame as the
app calls it: no hint, its own track carried over. Per height band: the detection rate, the longest run of
missed frames (as a time), the frames a perfect detector would report (a marker of the set ≥ 14 px wholly in the
image, a cell clear of its border) and the rate on those, which marker was found (outer or nested), the corner
error against the renderer's truth for that marker, the detector's time and each missed frame's class
(:func:`miss_cause`). Deterministic for the seeds (but for the times).
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from app.cli import OneLineParser, number, run_cli
from app.sensors.camera import ExposureControls
from app.sensors.detect import make_detector
from app.sensors.detect_marker import SEARCH_FULL_MIN_PX, marker_sizes_m
from app.settings import CameraSettings, DetectorSettings, load_settings
from sim.camera_render import CameraRenderer, Conditions, FrameTruth
from sim.camera_render_poses import Pose, camera_pose, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

MIN_EDGE_PX = SEARCH_FULL_MIN_PX  # a smaller marker is not decodable (as the geometric camera has it)
QUIET_CELLS_PER_EDGE = 6.0  # a marker of the default 4×4 dictionary: 4 bits + 2 border cells across

F64 = NDArray[np.float64]
BANDS_M = ((4.0, 3.0), (3.0, 2.0), (2.0, 1.5), (1.5, 1.0), (1.0, 0.6), (0.6, 0.3))  # vehicle height, m


GRAVITY_MPS2 = 9.81
FOLLOW_DAMPING = 0.7  # the tracking loop's damping ratio
STEP_PER_FRAME = 8  # integration steps of the vehicle's motion per frame
WARMUP_S = 5.0  # the vehicle follows the object this long before the descent starts


@dataclass(frozen=True, slots=True)
class DescentConfig:
    """The descent and how the vehicle follows the object (a multirotor: it tilts to accelerate, tan θ = a/g)."""

    sea_state: int = 2
    current_mps: float = 0.3
    start_height_m: float = 4.0  # vehicle (body origin) above the water at the object
    end_height_m: float = 0.3
    descent_mps: float = 0.5
    fps_hz: float = 15.0
    follow_hz: float = 0.4  # bandwidth of the horizontal tracking loop (PD, the object's velocity fed forward)
    aim_error_m: float = 0.1  # error of the estimate it aims at: a bias and a 0.1–0.4 Hz wander, about
    jitter_deg: float = 2.0  # attitude jitter (gusts) at 0.7–1.3 Hz, at most
    oscillation_m: float = 0.0  # an extra horizontal oscillation of the vehicle (a loop that rings), amplitude
    oscillation_hz: float = 1.0
    t0_s: float = 20.0  # the descent starts here (plus a seeded shift), sea time


@dataclass(frozen=True, slots=True)
class FrameResult:
    t_s: float
    height_m: float
    found_id: int | None  # the marker ID the detector reported, None: missed
    detector_pass: str
    detect_ms: float  # wall time of the detector's call
    corner_error_px: float | None  # largest corner error against the truth of the marker found
    outer_border_px: float  # the outer marker's corners from the image border, at least; −1: not wholly in view
    nested_border_px: float
    outer_size_px: float
    nested_size_px: float
    offset_m: float  # vehicle from the object, horizontal
    tilt_deg: float  # vehicle tilt (roll and pitch together)


@dataclass(frozen=True, slots=True)
class DescentFrame:
    index: int
    t_s: float
    height_m: float
    camera: Pose
    object: Pose
    offset_m: float
    tilt_deg: float


def _sinusoids(rng: np.random.Generator, f_lo_hz: float, f_hi_hz: float, n: int = 3) -> F64:
    """``n`` × (frequency Hz, phase rad, weight): a few terms to sum into a smooth random signal."""
    return np.column_stack([rng.uniform(f_lo_hz, f_hi_hz, n), rng.uniform(0, 2 * np.pi, n), rng.uniform(0.5, 1, n)])


def _signal(terms: F64, t_s: F64, derivative: int = 0) -> F64:
    """The terms summed at the times ``t_s`` (|·| ≤ 1), or their first or second derivative."""
    w = 2 * np.pi * terms[:, 0]
    phase = w * t_s[:, None] + terms[:, 1]
    wave = (np.sin(phase), w * np.cos(phase), -(w**2) * np.sin(phase))[derivative]
    return np.asarray(wave @ terms[:, 2] / np.sum(terms[:, 2]), dtype=np.float64)


def descent(config: DescentConfig, camera: CameraSettings, seed: int) -> Iterator[DescentFrame]:
    """Each frame of one descent: the vehicle above the object, following it as a multirotor does.

    Horizontal: a PD loop of bandwidth ``follow_hz`` pulls the vehicle to the object plus the aim error, with the
    object's velocity fed forward: x'' = ω² (p + e − x) + 2 ζ ω (v − x'); plus ``oscillation_m`` at
    ``oscillation_hz``. Attitude: the tilt that gives that acceleration (pitch = −atan(a_fwd / g), roll =
    atan(a_right cos θ / g)) plus the jitter; the yaw drifts slowly. Vertical: ``descent_mps`` down to
    ``end_height_m`` above the water at the object (riding its heave).
    """
    rng = np.random.default_rng((seed, 4711))
    sea = SeaWorld(SeaConfig(sea_state=config.sea_state, current_mps=config.current_mps), seed=seed)
    obj = FloatingObject(sea)
    t0 = config.t0_s + float(rng.uniform(0.0, 10.0))
    n = round((config.start_height_m - config.end_height_m) / config.descent_mps * config.fps_hz) + 1
    dt = 1.0 / (config.fps_hz * STEP_PER_FRAME)
    t: F64 = t0 - WARMUP_S + dt * np.arange(round(WARMUP_S / dt) + (n - 1) * STEP_PER_FRAME + 1, dtype=np.float64)
    p_obj, v_obj, _ = obj.states(t)
    # the aim error: a bias and a wander, together about aim_error_m; the ringing; the jitter
    bias: F64 = rng.uniform(-0.5, 0.5, 2) * config.aim_error_m
    wander = [_sinusoids(rng, 0.1, 0.4) for _ in range(2)]
    aim = bias + 0.5 * config.aim_error_m * np.column_stack([_signal(w, t) for w in wander])
    ring = [np.array([[config.oscillation_hz, rng.uniform(0, 2 * np.pi), 1.0]]) for _ in range(2)]
    jitter = [_sinusoids(rng, 0.7, 1.3) for _ in range(2)]
    omega = 2 * np.pi * config.follow_hz
    x, v = p_obj[0, :2] + aim[0], v_obj[0, :2].copy()
    track, accel = np.empty((len(t), 2)), np.empty((len(t), 2))
    for i in range(len(t)):
        # x'' = ω² (p + e − x) + 2 ζ ω (v_p − x')
        accel[i] = omega**2 * (p_obj[i, :2] + aim[i] - x) + 2 * FOLLOW_DAMPING * omega * (v_obj[i, :2] - v)
        track[i] = x
        v = v + accel[i] * dt
        x = x + v * dt
    track += config.oscillation_m * np.column_stack([_signal(r, t) for r in ring])
    accel += config.oscillation_m * np.column_stack([_signal(r, t, 2) for r in ring])
    yaw0, yaw_rate = float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(-0.1, 0.1))
    jitter_rad = math.radians(config.jitter_deg) * np.column_stack([_signal(j, t) for j in jitter])
    object_yaw = float(rng.uniform(-np.pi, np.pi))
    for k in range(n):
        i = round(WARMUP_S / dt) + k * STEP_PER_FRAME
        height = config.start_height_m - config.descent_mps * k / config.fps_hz
        o = object_pose(obj, float(t[i]), yaw_rad=object_yaw)
        yaw = yaw0 + yaw_rate * (t[i] - t0)
        a_fwd = accel[i, 0] * math.cos(yaw) + accel[i, 1] * math.sin(yaw)
        a_right = -accel[i, 0] * math.sin(yaw) + accel[i, 1] * math.cos(yaw)
        pitch = -math.atan(a_fwd / GRAVITY_MPS2) + jitter_rad[i, 0]
        roll = math.atan(a_right * math.cos(pitch) / GRAVITY_MPS2) + jitter_rad[i, 1]
        pos = np.array([track[i, 0], track[i, 1], o.pos_ned_m[2] - height])
        yield DescentFrame(
            index=k,
            t_s=float(t[i]),
            height_m=height,
            camera=camera_pose(pos, roll, pitch, yaw, camera),
            object=o,
            offset_m=float(np.hypot(*(track[i] - o.pos_ned_m[:2]))),
            tilt_deg=math.degrees(math.acos(math.cos(roll) * math.cos(pitch))),
        )


def run_descent(
    config: DescentConfig,
    camera: CameraSettings,
    detector: DetectorSettings,
    seed: int,
    save_misses: Path | None = None,
) -> list[FrameResult]:
    """Render one descent and run the app's detector over it frame by frame."""
    renderer = CameraRenderer(camera, detector, seed=seed)
    # truth for each marker of the nested set: a renderer whose marker is that size (same centre, same axes)
    sizes = dict(zip((detector.marker_id, *detector.nested_marker_ids), marker_sizes_m(detector), strict=True))
    truths = {
        i: CameraRenderer(camera, detector.model_copy(update={"marker_size_m": s, "nested_marker_ids": ()}), seed)
        for i, s in sizes.items()
    }
    nested_id = detector.nested_marker_ids[0] if detector.nested_marker_ids else None
    det = make_detector(detector, camera)
    out = []
    for f in descent(config, camera, seed):
        frame = renderer.render(f.t_s, f.camera, f.object, ExposureControls(), Conditions(), frame_index=f.index)
        start = time.perf_counter()
        found = det.detect(frame.image, f.t_s)  # as the app calls it: no hint, the detector's own track
        detect_ms = 1e3 * (time.perf_counter() - start)
        nested = truths[nested_id].truth(f.camera, f.object) if nested_id is not None else None
        error = None
        if found is not None and found.marker_id in truths:
            truth = truths[found.marker_id].truth(f.camera, f.object)
            if truth.corners_px is not None:
                error = float(np.max(np.linalg.norm(np.array(found.corners_px) - truth.corners_px, axis=1)))
        elif found is None and save_misses is not None:
            save_misses.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(save_misses / f"seed{seed}_f{f.index:03d}_h{f.height_m:.2f}.png"), frame.image)
        out.append(
            FrameResult(
                t_s=f.t_s,
                height_m=f.height_m,
                found_id=None if found is None else found.marker_id,
                detector_pass=det.last_pass,
                detect_ms=detect_ms,
                corner_error_px=error,
                outer_border_px=_border_px(frame.truth, camera),
                nested_border_px=-1.0 if nested is None else _border_px(nested, camera),
                outer_size_px=frame.truth.size_px,
                nested_size_px=0.0 if nested is None else nested.size_px,
                offset_m=f.offset_m,
                tilt_deg=f.tilt_deg,
            )
        )
    return out


def _border_px(truth: FrameTruth, camera: CameraSettings) -> float:
    if truth.corners_px is None:
        return -1.0
    x, y = truth.corners_px[:, 0], truth.corners_px[:, 1]
    return float(min(x.min(), y.min(), camera.width_px - 1 - x.max(), camera.height_px - 1 - y.max()))


def _clear(border_px: float, size_px: float) -> bool:
    """Wholly in the image with a cell's worth of its white margin (a 4×4 marker: 6 cells to an edge)."""
    return border_px >= size_px / QUIET_CELLS_PER_EDGE and size_px >= MIN_EDGE_PX


def decodable(r: FrameResult) -> bool:
    """What a perfect detector would report: a marker of the set in the image, clear of its border, big enough."""
    return _clear(r.outer_border_px, r.outer_size_px) or _clear(r.nested_border_px, r.nested_size_px)


def miss_cause(r: FrameResult) -> str:
    """A missed frame's class, from the truth alone (what the detector could have seen)."""
    if _clear(r.outer_border_px, r.outer_size_px):
        return "MISSED: outer clear"
    if _clear(r.nested_border_px, r.nested_size_px):
        return "MISSED: outer cut, nested clear"
    if r.outer_border_px >= 0 or r.nested_border_px >= 0:
        return "at the border or too small"
    return "out of view"


def _longest_run(flags: Sequence[bool]) -> int:
    best = run = 0
    for f in flags:
        run = run + 1 if f else 0
        best = max(best, run)
    return best


def _p(values: Sequence[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)), 3) if len(values) else None


def summarise(runs: Sequence[Sequence[FrameResult]], fps_hz: float) -> list[dict[str, Any]]:
    """One row per height band: rate, longest gap (over the runs), markers found, corner error, miss classes."""
    rows = []
    for hi, lo in BANDS_M:
        frames, longest = [], 0
        for run in runs:
            band = [r for r in run if lo < r.height_m <= hi or (lo == BANDS_M[-1][1] and r.height_m == lo)]
            frames += band
            longest = max(longest, _longest_run([r.found_id is None for r in band]))
        hits = [r for r in frames if r.found_id is not None]
        seen = [r for r in frames if decodable(r)]
        errors = [r.corner_error_px for r in hits if r.corner_error_px is not None]
        rows.append(
            {
                "band_m": f"{hi:g}-{lo:g}",
                "frames": len(frames),
                "rate": round(len(hits) / max(len(frames), 1), 4),
                "longest_gap_s": round(longest / fps_hz, 3),
                "decodable": len(seen),  # frames a perfect detector would report
                "rate_decodable": round(sum(r.found_id is not None for r in seen) / max(len(seen), 1), 4),
                "found_ids": dict(sorted(Counter(str(r.found_id) for r in hits).items())),
                "corner_error_p50_px": _p(errors, 50),
                "corner_error_max_px": round(max(errors), 3) if errors else None,
                "misses_by_class": dict(Counter(miss_cause(r) for r in frames if r.found_id is None).most_common()),
                "offset_p95_m": _p([r.offset_m for r in frames], 95),
                "tilt_p95_deg": _p([r.tilt_deg for r in frames], 95),
                "detect_p95_ms": _p([r.detect_ms for r in frames], 95),
            }
        )
    return rows


def study(seeds: Sequence[int], config: DescentConfig | None = None, save_misses: Path | None = None) -> dict[str, Any]:
    """The descents for ``seeds`` with the app's default settings, summarised per height band."""
    config = config or DescentConfig()
    settings = load_settings()
    runs = [run_descent(config, settings.camera, settings.detector, s, save_misses) for s in seeds]
    every = [r for run in runs for r in run]
    return {
        "seeds": list(seeds),
        "config": asdict(config),
        "offset_m": {"p50": _p([r.offset_m for r in every], 50), "max": round(max(r.offset_m for r in every), 3)},
        "tilt_deg": {"p50": _p([r.tilt_deg for r in every], 50), "max": round(max(r.tilt_deg for r in every), 3)},
        "bands": summarise(runs, config.fps_hz),
    }


def print_table(result: dict[str, Any]) -> None:
    seeds, c = result["seeds"], result["config"]
    print(
        f"marker detection through a descent {c['start_height_m']:g} → {c['end_height_m']:g} m at "
        f"{c['descent_mps']:g} m/s, sea state {c['sea_state']}, {c['fps_hz']:g} Hz, seeds {seeds[0]}..{seeds[-1]}; "
        f"offset p50 {result['offset_m']['p50']:.2f} max {result['offset_m']['max']:.2f} m, "
        f"tilt p50 {result['tilt_deg']['p50']:.1f} max {result['tilt_deg']['max']:.1f}°"
    )
    print(
        "rate/gap: all frames; decod: frames with a marker of the set ≥ 14 px in view, a cell clear of the border "
        "(what a perfect detector sees), and the rate on those"
    )
    print(
        f"{'band m':>8} {'frames':>6} {'rate':>6} {'gap s':>6} {'decod':>5} {'rate':>6} {'found ids':>14} "
        f"{'err p50':>7} {'err max':>7} {'tilt95':>6} {'ms p95':>6}  missed frames"
    )
    for r in result["bands"]:
        ids = " ".join(f"{k}:{v}" for k, v in r["found_ids"].items()) or "-"
        p50, mx = r["corner_error_p50_px"], r["corner_error_max_px"]
        misses = ", ".join(f"{k} {v}" for k, v in r["misses_by_class"].items()) or "-"
        print(
            f"{r['band_m']:>8} {r['frames']:>6} {r['rate']:>6.3f} {r['longest_gap_s']:>6.2f} "
            f"{r['decodable']:>5} {r['rate_decodable']:>6.3f} {ids:>14} "
            f"{'-' if p50 is None else f'{p50:.2f}':>7} {'-' if mx is None else f'{mx:.2f}':>7} "
            f"{r['tilt_p95_deg']:>6.1f} {r['detect_p95_ms']:>6.1f}  {misses}"
        )


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="python -m sim.detect_study", description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=number(1, 500, kind=int), default=20, help="descents (seeds 0..N-1)")
    p.add_argument(
        "--oscillation-m", type=number(0.0, 1.0, "m"), default=0.0, help="vehicle ringing at 1 Hz, amplitude"
    )
    p.add_argument("--aim-error-m", type=number(0.0, 2.0, "m"), default=0.1, help="error of the aim point, at most")
    p.add_argument("--save-misses", type=Path, help="write the missed frames as PNG here (git-ignored runs/…)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    args = p.parse_args(argv)
    config = DescentConfig(aim_error_m=args.aim_error_m, oscillation_m=args.oscillation_m)
    result = study(range(int(args.seeds)), config, args.save_misses)
    if args.json:
        json.dump(result, sys.stdout)
        print()
    else:
        print_table(result)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.detect_study"))
