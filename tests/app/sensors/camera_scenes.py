"""Rendered scenes for the detector tests: the simulator's renderer, the object placed where a test wants it."""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from app.sensors.camera import ExposureControls
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions, RenderedFrame
from sim.camera_render_poses import Pose, camera_pose, camera_seeing, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

CAMERA = CameraSettings()
MARKER = DetectorSettings()
BUOY = DetectorSettings(kind="buoy")
T_S = 10.0  # when the scene is, s


@functools.lru_cache(maxsize=8)
def renderer(detector: DetectorSettings = MARKER, camera: CameraSettings = CAMERA) -> CameraRenderer:
    return CameraRenderer(camera, detector, seed=5)


@functools.lru_cache(maxsize=1)
def floating_object() -> FloatingObject:
    return FloatingObject(SeaWorld(SeaConfig(sea_state=2), seed=5))


def render_at(
    pixel: tuple[float, float],
    size_px: float,
    *,
    conditions: Conditions | None = None,
    frame_index: int = 0,
    **scene: Any,
) -> RenderedFrame:
    """The object seen at ``pixel`` with an edge (marker) / diameter (buoy) of about ``size_px``; ``scene``: the
    ``detector``, ``camera``, time ``t_s``, camera ``attitude_rad`` and ``object_yaw_rad`` (``scene_poses``)."""
    cam, obj = scene_poses(pixel, size_px, **scene)
    render = renderer(scene.get("detector", MARKER), scene.get("camera", CAMERA)).render
    return render(scene.get("t_s", T_S), cam, obj, ExposureControls(), conditions or Conditions(), frame_index)


def scene_poses(
    pixel: tuple[float, float],
    size_px: float,
    detector: DetectorSettings = MARKER,
    camera: CameraSettings = CAMERA,
    t_s: float = T_S,
    attitude_rad: tuple[float, float, float] = (0.05, -0.08, 0.3),
    object_yaw_rad: float = 0.4,
) -> tuple[Pose, Pose]:
    """``render_at``'s camera and object poses (the object floats on the sea, tilted with its slope at ``t_s``)."""
    obj = object_pose(floating_object(), t_s, object_yaw_rad)
    edge_m = detector.marker_size_m if detector.kind == "aruco" else detector.buoy_diameter_m
    ray = math.hypot((pixel[0] - camera.cx_px) / camera.fx_px, (pixel[1] - camera.cy_px) / camera.fy_px, 1.0)
    cam = camera_seeing(camera, obj, pixel, camera.fx_px * edge_m / size_px * ray, *attitude_rad)
    assert cam is not None
    return cam, obj


def paste(image: np.ndarray, patch: np.ndarray, at: tuple[int, int]) -> np.ndarray:
    """``image`` with ``patch`` copied in at (x, y) — e.g. a second copy of the marker."""
    out = image.copy()
    x, y = at
    out[y : y + patch.shape[0], x : x + patch.shape[1]] = patch
    return out


def open_sea(t_s: float = 10.0, height_m: float = 6.0) -> np.ndarray:
    """A frame of open sea (no object) from ``height_m``."""
    cam = camera_pose(np.array([3.0, -2.0, -height_m]), 0.05, -0.05, 1.0, CAMERA)
    return renderer().render(t_s, cam, None, ExposureControls(), Conditions(glints=100)).image
