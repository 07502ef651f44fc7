"""``python -m app.bench perception [--json]``: marker detection speed and recall, seapick against the thesis way.

The data set is rendered by the simulator in a subprocess (``python -m sim.camera_dataset``; ``app`` never imports
``sim``) and cached under ``runs/``. OpenCV runs on one thread. Per frame:

- **naive** (thesis §4.2.3): ``cv2.undistort`` of the whole frame, then the default ``ArucoDetector`` on it;
- **search**: seapick's detector with no track (reduced-scale pass, full resolution only if that missed);
- **track**: seapick's detector on the frames after the first of each scene, carrying its track from frame to
  frame as in flight (a window around the expected position; full-frame fallback on a miss); and on the open-sea
  frames with a stale track at a random place (the window misses, the fallback searches, nothing may be found).
  Its recall is compared with the naive pipeline's on the same frames.

Each frame is timed ``--repeat`` times and its fastest run kept (the machine may be shared); the figures are the
median and 95th percentile over frames. A fix counts when its centre (mean of the corners, eq. 4.3, in raw
pixels) is within ``max(3 px, 10 % of the marker edge)`` of the truth; any other fix — on a frame without the
marker, or off the marker — is a false fix.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from app.cli import OneLineParser, number, run_child
from app.messages import CameraModel
from app.sensors.detect import DetectionHint
from app.sensors.detect_marker import MarkerDetector
from app.settings import CameraSettings, DetectorSettings

DATASET_VERSION = 4  # sim.camera_dataset.VERSION this bench was written against
ROOT = Path(__file__).resolve().parents[2]
GOALS = {"track_ms_median": 5.0, "search_ms_median": 10.0, "speedup_track": 5.0, "recall_ge30": 0.99}


@dataclass
class Frame:
    image: np.ndarray
    scene: int
    index: int
    t_s: float
    center_px: np.ndarray | None
    size_px: float


@dataclass
class Tally:
    times_ms: list[float] = field(default_factory=list)
    hits: int = 0
    markers: int = 0
    hits_ge30: int = 0
    markers_ge30: int = 0
    false_fixes: int = 0
    errors_px: list[float] = field(default_factory=list)

    def score(self, frame: Frame, centre_px: np.ndarray | None) -> None:
        if frame.center_px is None:
            self.false_fixes += centre_px is not None
            return
        self.markers += 1
        self.markers_ge30 += frame.size_px >= 30.0
        if centre_px is None:
            return
        error = float(np.hypot(*(centre_px - frame.center_px)))
        if error > max(3.0, 0.1 * frame.size_px):
            self.false_fixes += 1
            return
        self.hits += 1
        self.hits_ge30 += frame.size_px >= 30.0
        self.errors_px.append(error)

    def summary(self, prefix: str) -> dict[str, float]:
        t = np.array(self.times_ms)
        return {
            f"{prefix}_ms_median": float(np.median(t)),
            f"{prefix}_ms_p95": float(np.percentile(t, 95)),
            f"{prefix}_recall": self.hits / max(self.markers, 1),
            f"{prefix}_recall_ge30": self.hits_ge30 / max(self.markers_ge30, 1),
            f"{prefix}_false_fixes": self.false_fixes,
            f"{prefix}_center_error_px_median": float(np.median(self.errors_px)) if self.errors_px else float("nan"),
            f"{prefix}_frames": len(t),
        }


def ensure_dataset(directory: Path, seed: int, size: dict[str, int], regenerate: bool) -> dict[str, Any]:
    """The data set in ``directory``, rendered (by the simulator, in a subprocess) unless already there."""
    truth = directory / "truth.json"
    if not regenerate and truth.exists():
        doc = json.loads(truth.read_text())
        wanted = {"version": DATASET_VERSION, "seed": seed} | size
        if all(doc.get(k) == v for k, v in wanted.items()):
            return dict(doc)
    cmd = [sys.executable, "-m", "sim.camera_dataset", "--out", str(directory), "--seed", str(seed)]
    cmd += [f"--{k.replace('_', '-')}={v}" for k, v in size.items()]
    run_child(cmd, ROOT)
    return dict(json.loads(truth.read_text()))


def load_frames(directory: Path, doc: dict[str, Any]) -> list[Frame]:
    frames = []
    for rec in doc["frames"]:
        image = cv2.imread(str(directory / rec["file"]), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise FileNotFoundError(directory / rec["file"])
        centre = np.array(rec["center_px"]) if rec.get("center_px") else None
        frames.append(Frame(image, rec["scene"], rec["index"], rec["t_s"], centre, float(rec.get("size_px", 0.0))))
    return frames


def timed(fn: Callable[[], np.ndarray | None], repeat: int) -> tuple[float, np.ndarray | None]:
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3, result


class Naive:
    """The thesis pipeline: undistort the whole frame, default detector, the ID exactly once (corners → raw px)."""

    def __init__(self, camera: CameraSettings, detector: DetectorSettings) -> None:
        self.model = CameraModel.from_settings(camera)
        self.marker_id = detector.marker_id
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, detector.dictionary))
        self.aruco = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())

    def detect(self, image: np.ndarray) -> np.ndarray | None:
        undistorted = cv2.undistort(image, self.model.K, self.model.dist_coeffs)
        corners, ids, _ = self.aruco.detectMarkers(undistorted)
        found = [] if ids is None else [int(i) for i in ids.ravel()]
        if found.count(self.marker_id) != 1:
            return None
        return np.asarray(corners[found.index(self.marker_id)].reshape(4, 2), dtype=np.float64)

    def to_raw(self, quad: np.ndarray | None) -> np.ndarray | None:
        """Undistorted-image corners back to raw pixels, then their mean (eq. 4.3)."""
        if quad is None:
            return None
        k = self.model
        xy1 = np.column_stack([(quad[:, 0] - k.cx_px) / k.fx_px, (quad[:, 1] - k.cy_px) / k.fy_px, np.ones(4)])
        return np.asarray(k.project(xy1).mean(axis=0))


def run(frames: list[Frame], camera: CameraSettings, detector: DetectorSettings, repeat: int) -> dict[str, Any]:
    cv2.setNumThreads(1)
    naive, seapick = Naive(camera, detector), MarkerDetector(detector, camera)
    for f in frames[:3]:  # warm up (first calls allocate)
        naive.detect(f.image)
        seapick.detect(f.image, f.t_s)
    n_tally, s_tally, t_tally = Tally(), Tally(), Tally()
    naive_on_track_frames = Tally()  # the naive pipeline on exactly the frames tracking is scored on
    naive_centres: dict[int, np.ndarray | None] = {}
    passes: dict[str, int] = {}

    def seapick_centre(f: Frame, hint: DetectionHint | None = None, reset: bool = False) -> np.ndarray | None:
        if reset:
            seapick.reset()
        found = seapick.detect(f.image, f.t_s, hint)
        return None if found is None else np.array(found.center_px)

    for f in frames:
        ms, quad = timed(partial(naive.detect, f.image), repeat)
        n_tally.times_ms.append(ms)
        naive_centres[id(f)] = naive.to_raw(quad)
        n_tally.score(f, naive_centres[id(f)])
        ms, centre = timed(partial(seapick_centre, f, reset=True), repeat)
        s_tally.times_ms.append(ms)
        s_tally.score(f, centre)

    # tracking: each scene in order; frames after the first carry the detector's track from the frame before
    scenes: dict[int, list[Frame]] = {}
    for f in frames:
        scenes.setdefault(f.scene, []).append(f)
    rng = np.random.default_rng(0)
    for scene in scenes.values():
        if scene[0].center_px is None:  # open sea: a stale track somewhere must not make a fix
            for f in scene:
                hint = DetectionHint((float(rng.uniform(100, 1180)), float(rng.uniform(100, 860))), 60.0)
                ms, centre = timed(partial(seapick_centre, f, hint, reset=True), repeat)
                t_tally.times_ms.append(ms)
                t_tally.score(f, centre)
                naive_on_track_frames.score(f, naive_centres[id(f)])
            continue
        # run the scene `repeat` times from its first frame; keep each frame's fastest run
        best_ms = [float("inf")] * (len(scene) - 1)
        centres: list[np.ndarray | None] = [None] * (len(scene) - 1)
        for run_index in range(repeat):
            seapick_centre(scene[0], reset=True)
            for k, f in enumerate(scene[1:]):
                ms, centres[k] = timed(partial(seapick_centre, f), 1)
                best_ms[k] = min(best_ms[k], ms)
                if run_index == 0:
                    passes[seapick.last_pass] = passes.get(seapick.last_pass, 0) + 1
        for f, ms, centre in zip(scene[1:], best_ms, centres, strict=True):
            t_tally.times_ms.append(ms)
            t_tally.score(f, centre)
            naive_on_track_frames.score(f, naive_centres[id(f)])

    out: dict[str, Any] = {}
    for prefix, tally in (("naive", n_tally), ("search", s_tally), ("track", t_tally)):
        out |= tally.summary(prefix)
    out["speedup_track"] = out["naive_ms_median"] / out["track_ms_median"]
    out["speedup_search"] = out["naive_ms_median"] / out["search_ms_median"]
    out["naive_recall_track_frames"] = naive_on_track_frames.hits / max(naive_on_track_frames.markers, 1)
    out["recall"] = out["search_recall"]
    out["recall_ge30"] = min(out["search_recall_ge30"], out["track_recall_ge30"])
    out["false_fixes"] = out["search_false_fixes"] + out["track_false_fixes"]
    out["track_passes"] = passes
    out["frames"] = len(frames)
    out["marker_frames"] = sum(f.center_px is not None for f in frames)
    out["repeat"] = repeat
    out["goals_met"] = {
        "track_ms_median<=5": out["track_ms_median"] <= GOALS["track_ms_median"],
        "search_ms_median<=10": out["search_ms_median"] <= GOALS["search_ms_median"],
        "speedup_track>=5": out["speedup_track"] >= GOALS["speedup_track"],
        "recall>=naive": out["search_recall"] >= out["naive_recall"]
        and out["track_recall"] >= out["naive_recall_track_frames"],
        "recall_ge30>=0.99": out["recall_ge30"] >= GOALS["recall_ge30"],
        "false_fixes==0": out["false_fixes"] == 0,
    }
    return out


def report(r: dict[str, Any]) -> str:
    lines = [
        f"perception bench: {r['frames']} frames 1280x960 ({r['marker_frames']} with the marker), OpenCV 1 thread, "
        f"best of {r['repeat']} per frame",
        f"{'pipeline':<8} {'median ms':>10} {'p95 ms':>8} {'recall':>7} {'≥30 px':>7} {'false':>6} {'centre err':>11}",
    ]
    for name in ("naive", "search", "track"):
        lines.append(
            f"{name:<8} {r[name + '_ms_median']:>10.2f} {r[name + '_ms_p95']:>8.2f} {r[name + '_recall']:>7.1%} "
            f"{r[name + '_recall_ge30']:>7.1%} {r[name + '_false_fixes']:>6d} "
            f"{r[name + '_center_error_px_median']:>8.2f} px"
        )
    lines.append(f"naive recall on the tracked frames: {r['naive_recall_track_frames']:.1%}")
    lines.append(f"speed-up vs naive (medians): search {r['speedup_search']:.1f}x, track {r['speedup_track']:.1f}x")
    lines.append("tracking passes: " + ", ".join(f"{k} {v}" for k, v in sorted(r["track_passes"].items())))
    lines.append("goals: " + ", ".join(f"{k} {'ok' if v else 'MISSED'}" for k, v in r["goals_met"].items()))
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = OneLineParser(prog="python -m app.bench perception", description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.add_argument("--seed", type=int, default=1, help="data set seed")
    parser.add_argument("--data", type=Path, default=None, help="data set directory (default: under runs/)")
    parser.add_argument("--regenerate", action="store_true", help="render the data set again")
    count = number(0, 100_000, "", int)
    parser.add_argument(
        "--repeat", type=number(1, 100, "", int), default=3, help="time each frame this often, keep the fastest"
    )
    parser.add_argument("--scenes", type=count, default=70, help="marker scenes in the data set")
    parser.add_argument(
        "--frames-per-scene", type=number(1, 1000, "", int), default=4, help="consecutive frames per scene"
    )
    parser.add_argument("--empty", type=count, default=40, help="open-sea frames in the data set")
    args = parser.parse_args(argv)
    size = {"scenes": args.scenes, "frames_per_scene": args.frames_per_scene, "empty": args.empty}
    name = f"perception-seed{args.seed}-{args.scenes}x{args.frames_per_scene}-{args.empty}"
    directory = args.data or ROOT / "runs" / name
    doc = ensure_dataset(directory, args.seed, size, args.regenerate)
    frames = load_frames(directory, doc)
    camera = CameraSettings.model_validate(doc["camera"])
    detector = DetectorSettings.model_validate(doc["detector"])
    result = run(frames, camera, detector, max(1, args.repeat))
    print(json.dumps(result) if args.json else report(result))
    return 0
