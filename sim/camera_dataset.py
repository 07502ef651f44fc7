"""A fixed, seeded set of rendered camera frames with ground truth, for ``python -m app.bench perception``.

``python -m sim.camera_dataset --out DIR --seed N`` writes ``DIR/frames/*.png`` (1280×960 mono, raw — i.e.
distorted — pixels) and ``DIR/truth.json``. The set holds *scenes* of a few consecutive frames at the camera
rate (so a detector can track from one frame to the next), with the marker between ~20 and ~400 px on the
image, the vehicle tilted up to ±20°, the object tilted by the waves, blur, glare, glints and an exposure
that is not always right; plus frames of open sea without the marker (false fixes are counted on those).

``truth.json``: ``{"version", "seed", "camera": CameraSettings, "detector": DetectorSettings, "frames": [...]}``;
each frame has ``file``, ``scene``, ``index`` (in its scene), ``t_s``, ``marker`` (bool), ``corners_px`` (4×2,
ArUco order) / ``center_px`` (mean of the corners) / ``size_px`` (mean edge) when it shows the marker, and the
nuisances it was rendered with.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from app.cli import OneLineParser, number, run_cli
from app.sensors.camera import ExposureControls
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions, Glare
from sim.camera_render_poses import Pose, camera_seeing, euler_zyx, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

VERSION = 4
FPS_HZ = 30.0
# A lens like the thesis's oCam (moderate barrel distortion): the naive pipeline has something to undistort.
DATASET_CAMERA = CameraSettings(distortion=(-0.12, 0.06, 0.0005, -0.0004, 0.0))
DATASET_DETECTOR = DetectorSettings()
EXPOSURE = ExposureControls(brightness=32.0, exposure=48.0)  # thesis defaults: 4.8 ms
EXPOSURE_UNIT_S = 100e-6  # V4L2 exposure_time_absolute


def _scene_conditions(
    rng: np.random.Generator,
    size_px: float,
    centre_px: np.ndarray,
    image_vel_pxps: np.ndarray,
    exposure: ExposureControls,
) -> Conditions:
    """Nuisances for one scene; the motion blur is what the image moves during the exposure."""
    glare = None
    if rng.random() < 0.25:
        radius = float(rng.uniform(40.0, 220.0))
        angle = rng.uniform(0.0, 2 * math.pi)
        dist = (radius + 0.7 * size_px) * rng.uniform(1.0, 2.0)
        glare = Glare(
            (float(centre_px[0] + dist * math.cos(angle)), float(centre_px[1] + dist * math.sin(angle))),
            radius,
            float(rng.uniform(0.4, 1.0)),
        )
    blur_vec = image_vel_pxps * exposure.exposure * EXPOSURE_UNIT_S
    return Conditions(
        # auto-exposure holds the sea in 100–140 grey; the light changes faster than it follows by up to ~±40 %
        illumination=float(np.exp(rng.uniform(math.log(0.7), math.log(1.4)))),
        blur_px=float(np.hypot(*blur_vec)),
        blur_angle_rad=float(math.atan2(blur_vec[1], blur_vec[0])),
        glints=int(rng.integers(10, 120)),
        glint_center_px=(float(rng.uniform(0, 1280)), float(rng.uniform(0, 960))),
        glint_spread_px=float(rng.uniform(100.0, 400.0)),
        glare=glare,
        noise_std_dn=float(rng.uniform(1.0, 3.5)),
    )


def _scene(
    renderer: CameraRenderer, obj: FloatingObject, rng: np.random.Generator, t0_s: float, n_frames: int, marker: bool
) -> list[tuple[float, Pose, Pose | None, Conditions]] | None:
    """Camera and object poses for ``n_frames`` consecutive frames; None if the marker leaves the image."""
    cam = renderer.camera
    size_target_px = float(np.exp(rng.uniform(math.log(20.0), math.log(400.0))))
    roll, pitch, yaw = rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35), rng.uniform(-math.pi, math.pi)
    rates = rng.normal(0.0, 0.3, 3)  # body rates, rad/s
    vel_ned = np.append(rng.normal(0.0, 0.8, 2), rng.normal(0.0, 0.2))
    # where the marker should appear, and how far away it must be for its size
    margin = size_target_px * 0.9 + 20.0
    u = rng.uniform(margin, cam.width_px - margin) if margin < cam.width_px / 2 else cam.width_px / 2
    v = rng.uniform(margin, cam.height_px - margin) if margin < cam.height_px / 2 else cam.height_px / 2
    ray_cam = np.array([(u - cam.cx_px) / cam.fx_px, (v - cam.cy_px) / cam.fy_px, 1.0])
    range_m = cam.fx_px * renderer.detector.marker_size_m / size_target_px * float(np.linalg.norm(ray_cam))
    obj_yaw = rng.uniform(-math.pi, math.pi)
    o0 = object_pose(obj, t0_s, obj_yaw)
    start = camera_seeing(cam, o0, (u, v), range_m, roll, pitch, yaw)
    if start is None:
        return None
    r_body_cam = euler_zyx(roll, pitch, yaw).T @ start.R_ned_from_body

    def poses(dt: float) -> tuple[Pose, Pose]:
        attitude = euler_zyx(roll + rates[0] * dt, pitch + rates[1] * dt, yaw + rates[2] * dt)
        return Pose(start.pos_ned_m + vel_ned * dt, attitude @ r_body_cam), object_pose(obj, t0_s + dt, obj_yaw)

    frames = []
    for k in range(n_frames):
        pose, o = poses(k / FPS_HZ)
        if marker and not renderer.truth(pose, o).in_view:
            return None
        frames.append((t0_s + k / FPS_HZ, pose, o if marker else None, Conditions()))
    # image velocity of the object over 1 ms: the direction and length of the motion blur
    truth0, truth1 = renderer.truth(*poses(0.0)), renderer.truth(*poses(1e-3))
    c0, c1 = np.array(truth0.center_px or (u, v)), np.array(truth1.center_px or (u, v))
    cond = _scene_conditions(rng, truth0.size_px, c0, (c1 - c0) / 1e-3, EXPOSURE)
    return [(t, p, o, cond) for t, p, o, _ in frames]


def generate(out: Path, seed: int, scenes: int = 70, frames_per_scene: int = 4, empty: int = 40) -> dict[str, Any]:
    """Render the set into ``out`` and return the truth document (also written to ``out/truth.json``)."""
    renderer = CameraRenderer(DATASET_CAMERA, DATASET_DETECTOR, seed=seed)
    sea = SeaWorld(SeaConfig(sea_state=3), seed=seed)
    obj = FloatingObject(sea, diameter_m=0.4)
    rng = np.random.default_rng(seed)
    (out / "frames").mkdir(parents=True, exist_ok=True)
    records: list[dict[str, Any]] = []
    jobs: list[tuple[int, bool]] = [(s, True) for s in range(scenes)] + [(scenes + i, False) for i in range(empty)]
    for scene_id, marker in jobs:
        n = frames_per_scene if marker else 1
        planned = None
        while planned is None:
            planned = _scene(renderer, obj, rng, float(rng.uniform(0.0, 600.0)), n, marker)
        for index, (t_s, pose, o, cond) in enumerate(planned):
            frame = renderer.render(t_s, pose, o, EXPOSURE, cond, frame_index=len(records))
            name = f"{len(records):04d}.png"
            cv2.imwrite(str(out / "frames" / name), frame.image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
            truth = frame.truth
            rec: dict[str, Any] = {
                "file": f"frames/{name}",
                "scene": scene_id,
                "index": index,
                "t_s": t_s,
                "marker": o is not None,
                "height_m": float(-pose.pos_ned_m[2]),
                "blur_px": cond.blur_px,
                "glare": cond.glare is not None,
                "illumination": cond.illumination,
            }
            if o is not None and truth.corners_px is not None:
                rec |= {
                    "corners_px": truth.corners_px.tolist(),
                    "center_px": list(truth.center_px or ()),
                    "size_px": truth.size_px,
                }
            records.append(rec)
    doc = {
        "version": VERSION,
        "seed": seed,
        "camera": DATASET_CAMERA.model_dump(mode="json"),
        "detector": DATASET_DETECTOR.model_dump(mode="json"),
        "fps_hz": FPS_HZ,
        "scenes": scenes,
        "frames_per_scene": frames_per_scene,
        "empty": empty,
        "frames": records,
    }
    (out / "truth.json").write_text(json.dumps(doc, indent=1))
    return doc


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m sim.camera_dataset", description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="directory to write frames/ and truth.json into")
    parser.add_argument("--seed", type=int, default=0)
    count = number(0, 100_000, "", int)
    parser.add_argument("--scenes", type=count, default=70, help="marker scenes")
    parser.add_argument("--frames-per-scene", type=number(1, 1000, "", int), default=4, help="frames per scene")
    parser.add_argument("--empty", type=count, default=40, help="frames of open sea without the marker")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    doc = generate(args.out, args.seed, args.scenes, args.frames_per_scene, args.empty)
    print(f"wrote {len(doc['frames'])} frames to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, "python -m sim.camera_dataset"))
