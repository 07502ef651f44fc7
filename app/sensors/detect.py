"""One interface for the object detectors; ``DetectorSettings.kind`` picks the marker or the buoy detector.

A detector takes one raw (distorted) mono image and returns a :class:`app.messages.PixelDetection` in raw
pixels, or ``None``. Detectors never undistort images: the points they return are undistorted later
(``CameraModel.undistort_to_rays``, in triangulation).

Tracking: a detector keeps the object's last image position and size and, on the next frame, first searches a
window around where it expects it (``roi_margin`` × its size, at a reduced scale when it is large); a miss there
falls back to a full-frame search (at a reduced scale first). The caller may pass a :class:`DetectionHint` — the
target filter's prediction projected into the image — which overrides the detector's own guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import NDArray

from app.messages import PixelDetection
from app.settings import CameraSettings, DetectorSettings

Image = NDArray[np.uint8]
Pass = Literal["none", "track", "search_reduced", "search_full"]

MIN_WINDOW_PX = 96  # the smallest tracking window: a small marker still moves a few pixels a frame
LOST_AFTER_MISSES = 1  # frames without a fix before the detector drops its own track


@dataclass(frozen=True, slots=True)
class DetectionHint:
    """Where the object is expected in this frame, raw pixels (e.g. the filter's prediction projected)."""

    center_px: tuple[float, float]
    size_px: float  # expected marker edge / buoy diameter on the image
    radius_px: float = 0.0  # uncertainty of the centre: widens the window


class Detector(Protocol):
    @property
    def last_pass(self) -> Pass:
        """Which pass produced the last result: the tracking window, a reduced-scale or a full-resolution search."""
        ...

    def detect(
        self, image: Image, t_s: float, hint: DetectionHint | None = None, height_m: float | None = None
    ) -> PixelDetection | None:
        """The object in ``image`` (captured at ``t_s``), or None. ``height_m``: camera height above the sea."""
        ...

    def reset(self) -> None:
        """Forget the track: the next frame is searched in full."""
        ...


@dataclass(frozen=True, slots=True)
class Window:
    """A crop of the image: columns x0..x1, rows y0..y1 (exclusive ends)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @classmethod
    def around(cls, center_px: tuple[float, float], side_px: float, width: int, height: int) -> Window:
        half = side_px / 2
        x0, y0 = max(int(center_px[0] - half), 0), max(int(center_px[1] - half), 0)
        x1, y1 = min(int(center_px[0] + half) + 1, width), min(int(center_px[1] + half) + 1, height)
        return cls(x0, y0, max(x1, x0), max(y1, y0))

    @property
    def empty(self) -> bool:
        return self.x1 - self.x0 < 8 or self.y1 - self.y0 < 8


class Track:
    """The detector's own prediction: last centre plus the last frame-to-frame motion (constant velocity)."""

    def __init__(self) -> None:
        self._last: PixelDetection | None = None
        self._velocity_pxps = (0.0, 0.0)
        self._misses = 0

    def reset(self) -> None:
        self._last, self._velocity_pxps, self._misses = None, (0.0, 0.0), 0

    def update(self, detection: PixelDetection | None) -> None:
        if detection is None:
            self._misses += 1
            if self._misses >= LOST_AFTER_MISSES:
                self.reset()
            return
        last = self._last
        if last is not None and detection.t_s > last.t_s:
            dt = detection.t_s - last.t_s
            self._velocity_pxps = (
                (detection.center_px[0] - last.center_px[0]) / dt,
                (detection.center_px[1] - last.center_px[1]) / dt,
            )
        self._last, self._misses = detection, 0

    def hint(self, t_s: float) -> DetectionHint | None:
        last = self._last
        if last is None:
            return None
        dt = max(t_s - last.t_s, 0.0)
        vx, vy = self._velocity_pxps
        moved = (vx * dt, vy * dt)
        # the window also covers the motion itself: a wrong velocity costs at most one step
        return DetectionHint(
            (last.center_px[0] + moved[0], last.center_px[1] + moved[1]),
            last.size_px,
            radius_px=0.5 * float(np.hypot(*moved)),
        )


class TrackingDetector:
    """What both detectors share: their own track and which pass produced the last result."""

    def __init__(self) -> None:
        self._track = Track()
        self._last_pass: Pass = "none"

    @property
    def last_pass(self) -> Pass:
        return self._last_pass

    def reset(self) -> None:
        self._track.reset()
        self._last_pass = "none"


def make_detector(detector: DetectorSettings, camera: CameraSettings) -> Detector:
    """The detector ``detector.kind`` names."""
    if detector.kind == "buoy":
        from app.sensors.detect_buoy import BuoyDetector

        return BuoyDetector(detector, camera)
    from app.sensors.detect_marker import MarkerDetector

    return MarkerDetector(detector, camera)
