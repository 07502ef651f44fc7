"""The pickup's sensors in the run directory, decimated, for ``run.mcap`` (``app.foxglove_log``).

- ``RadarProfileLog``, the radar task's ``on_frame`` hook (on the loop): one frame every ``period_s`` of measurement
  time as a ``radar_profile`` record — ``range_start_m``, ``range_step_m`` and the amplitude per bin in dB
  (20·log10 |I + jQ|, re one unit of the X4's baseband floats). The amplitudes themselves run 1e-4 … 1e-2, which
  the event log's four decimals would flatten to one significant digit; in dB they keep 0.01 dB.
- ``CameraFrameLog``, run in the camera task's worker thread (never on the loop): one frame every ``period_s``,
  downscaled to ``width_px`` and JPEG-encoded at ``quality``, to ``run_dir/camera/NNNNNN.jpg``, then a ``camera``
  record naming it (``jpeg``, relative to the run directory). A frame that cannot be encoded or written is counted
  (``failed``) and skipped: the recording must never cost the mission its camera.

Both stamp a record with the measurement's time on the loop clock (the radar frame's, the image's capture time).
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from app.eventlog import EventLog
from app.messages import RadarFrame
from app.sensors.camera import Image

PROFILE_PERIOD_S = 0.5  # 2 Hz of the radar's 10
AMPLITUDE_FLOOR_DB = -160.0  # an exact zero would be −inf
AMPLITUDE_DECIMALS = 2  # dB
CAMERA_PERIOD_S = 1.0
CAMERA_WIDTH_PX = 640  # downscaled to this width (never up), aspect kept
JPEG_QUALITY = 70
CAMERA_DIR = "camera"


class Decimator:
    """``due(t_s)`` is true at most once per ``period_s``, on a grid (a sample a little early does not cost a
    whole period), restarted from the sample after a gap longer than a period."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._next_s: float | None = None

    def due(self, t_s: float) -> bool:
        next_s = self._next_s
        if next_s is not None and t_s < next_s:
            return False
        if next_s is None or t_s >= next_s + self.period_s:
            next_s = t_s  # the first sample, or the first after a gap: the grid starts again here
        self._next_s = next_s + self.period_s
        return True


def amplitude_db(frame: RadarFrame) -> list[float]:
    """20·log10 |I + jQ| per bin, floored at ``AMPLITUDE_FLOOR_DB``, rounded to ``AMPLITUDE_DECIMALS``."""
    amplitude = frame.amplitude().astype(np.float64)
    floor = 10.0 ** (AMPLITUDE_FLOOR_DB / 20.0)
    db = 20.0 * np.log10(np.maximum(np.nan_to_num(amplitude, nan=0.0, posinf=0.0), floor))
    return [round(v, AMPLITUDE_DECIMALS) for v in db.tolist()]


class RadarProfileLog:
    """The radar task's ``on_frame`` hook: a ``radar_profile`` record every ``period_s`` of measurement time."""

    def __init__(self, events: EventLog, period_s: float = PROFILE_PERIOD_S) -> None:
        self.events = events
        self.decimator = Decimator(period_s)
        self.written = 0

    def __call__(self, frame: RadarFrame) -> None:
        if not math.isfinite(frame.t_s) or not self.decimator.due(frame.t_s):
            return
        axis = frame.axis
        self.events.write(
            frame.t_s,
            "radar_profile",
            range_start_m=float(axis.start_m),
            range_step_m=float(axis.bin_m),
            amplitude=amplitude_db(frame),
        )
        self.written += 1


class CameraFrameLog:
    """Camera frames as JPEG files and ``camera`` records: ``due`` on the loop (cheap), ``save`` in a worker."""

    def __init__(
        self,
        run_dir: Path,
        events: EventLog,
        period_s: float = CAMERA_PERIOD_S,
        width_px: int = CAMERA_WIDTH_PX,
        quality: int = JPEG_QUALITY,
    ) -> None:
        self.run_dir = run_dir
        self.events = events
        self.decimator = Decimator(period_s)
        self.width_px = width_px
        self.quality = quality
        self.saved = 0
        self.failed = 0

    def due(self, t_s: float) -> bool:
        """Whether the frame captured at ``t_s`` is one to keep (call once per frame, in capture order)."""
        return self.decimator.due(t_s)

    def save(self, t_s: float, image: Image) -> str | None:
        """Downscale, encode and write the frame, then log its record; the file's run-relative path, or ``None``
        when it failed (counted). Blocking: call it in a worker thread."""
        name = f"{CAMERA_DIR}/{self.saved + self.failed:06d}.jpg"
        try:
            ok, jpeg = cv2.imencode(".jpg", self.downscaled(image), [cv2.IMWRITE_JPEG_QUALITY, self.quality])
            if not ok:
                raise ValueError("cv2.imencode refused the frame")
            path = self.run_dir / name
            path.parent.mkdir(exist_ok=True)
            path.write_bytes(jpeg.tobytes())
        except (OSError, ValueError, cv2.error):
            self.failed += 1
            return None
        self.saved += 1
        self.events.write(t_s, "camera", jpeg=name)
        return name

    def downscaled(self, image: Image) -> Image:
        height_px, width_px = image.shape[:2]
        if width_px <= self.width_px:
            return image
        size = (self.width_px, max(1, round(height_px * self.width_px / width_px)))
        return np.asarray(cv2.resize(image, size, interpolation=cv2.INTER_AREA), dtype=np.uint8)
