"""The real camera: a V4L2 device through OpenCV (thesis: oCam-1MGN-U, 1280×960 GREY at 30 fps).

:class:`V4l2Grabber` is the blocking part (opened, configured and read only by the capture thread of
:class:`app.sensors.camera.ThreadedCamera`). The driver queue is cut to one buffer where the backend allows it —
the thesis patched the oCam library for the same reason — and the capture thread's latest-wins handoff drops
whatever the detector could not keep up with. Exposure is set manually (``auto_exposure`` = 1 is V4L2's
"manual mode"); our own controller (:mod:`app.sensors.exposure`) closes the loop.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from app.sensors.camera import CameraError, ExposureControls, Image, ThreadedCamera
from app.settings import CameraSettings

V4L2_MANUAL_EXPOSURE = 1  # V4L2_EXPOSURE_MANUAL, as OpenCV's V4L2 backend passes CAP_PROP_AUTO_EXPOSURE


class V4l2Grabber:
    """Blocking frame grabs from one V4L2 device; ``CameraError`` on failure."""

    def __init__(self, settings: CameraSettings) -> None:
        self.name = settings.device
        self._settings = settings
        self._cap: cv2.VideoCapture | None = None

    def _open(self) -> cv2.VideoCapture:
        s = self._settings
        device: int | str = int(s.device) if s.device.isdigit() else s.device
        cap = cv2.VideoCapture(device, cv2.CAP_V4L2)
        if not cap.isOpened():
            raise CameraError(self.name, "cannot open the device")
        cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*"GREY"))
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, s.width_px)
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, s.height_px)
        cap.set(cv2.CAP_PROP_FPS, s.fps_hz)
        cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if (w, h) != (s.width_px, s.height_px):
            cap.release()
            raise CameraError(self.name, f"delivers {w}x{h}, settings want {s.width_px}x{s.height_px}")
        self._cap = cap
        return cap

    def grab(self) -> Image:
        cap = self._cap or self._open()
        ok, frame = cap.read()
        if not ok or frame is None:
            raise CameraError(self.name, "read failed")
        if frame.ndim == 3:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        return np.ascontiguousarray(frame, dtype=np.uint8)

    def apply_controls(self, controls: ExposureControls) -> None:
        cap = self._cap or self._open()
        cap.set(cv2.CAP_PROP_AUTO_EXPOSURE, V4L2_MANUAL_EXPOSURE)
        cap.set(cv2.CAP_PROP_EXPOSURE, round(controls.exposure))
        cap.set(cv2.CAP_PROP_BRIGHTNESS, round(controls.brightness))

    def close(self) -> None:
        if self._cap is not None:
            self._cap.release()
            self._cap = None


def open_v4l2_camera(
    settings: CameraSettings,
    clock: Callable[[], float],
    *,
    controls: ExposureControls | None = None,
    latency_s: float = 0.0,
) -> ThreadedCamera:
    """The V4L2 camera as a ``CameraSource``; use ``async with``. ``clock``: loop-clock seconds, thread-safe."""
    return ThreadedCamera(V4l2Grabber(settings), clock, controls=controls, latency_s=latency_s)
