"""Auto-exposure: keep the frame's mean brightness in the configured band (thesis §4.2.3: 100–140 grey).

The thesis stepped the exposure by a fixed increment whenever the mean left the band, and noted that a
P controller would correct large errors faster. This is that controller, proportional in log-exposure (a sensor
is linear, so brightness ∝ exposure and the right correction is a *ratio*)::

    e = ln(b_target) − ln(b_mean)                     b_target: the band's centre
    E_{k+1} = E_k · exp(clip(K_p · e, −ln r_max, +ln r_max))    only while b_mean is outside the band

With K_p = 1 on a linear sensor one step lands in the band; K_p < 1 damps noise. The step is capped at
``max_step_ratio``, and a saturated (or black) frame, which hides how far off it is, gets the full cap. A new
request waits until a frame taken *with* the last request arrives (``CameraFrame.controls``), so the controller
never reacts twice to the same exposure (it gives up waiting after ``settle_frames``). Pure: values in, values
out; switched on and off at run time with ``set_enabled``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from app.sensors.camera import ExposureControls
from app.settings import CameraSettings

SATURATED_MEAN = 250.0  # a mean this high (or this low) says only "far too bright (dark)"
BLACK_MEAN = 5.0


@dataclass(frozen=True, slots=True)
class AutoExposureConfig:
    low: float = 100.0  # band, grey levels
    high: float = 140.0
    gain: float = 0.8  # K_p on the log-brightness error
    max_step_ratio: float = 4.0  # largest change per step (either way), ratio
    min_exposure: float = 1.0  # device units (V4L2: 100 µs)
    max_exposure: float = 1000.0
    settle_frames: int = 5  # stop waiting for a request to show in the frames after this many

    @classmethod
    def from_settings(cls, camera: CameraSettings) -> AutoExposureConfig:
        return cls(low=camera.brightness_low, high=camera.brightness_high)


def mean_brightness(image: NDArray[np.uint8]) -> float:
    """Mean grey level, from every 4th pixel of every 4th row (the mean of a frame needs no more)."""
    return float(image[::4, ::4].mean())


class AutoExposure:
    """Proportional auto-exposure; feed it every frame, apply what it returns."""

    def __init__(self, config: AutoExposureConfig | None = None, enabled: bool = True) -> None:
        self.config = config or AutoExposureConfig()
        self.enabled = enabled
        self._pending: ExposureControls | None = None
        self._waited = 0

    def set_enabled(self, enabled: bool) -> None:
        """Switch on or off at run time; switching on starts afresh."""
        self.enabled = enabled
        self._pending = None

    def update(self, mean: float, frame_controls: ExposureControls) -> ExposureControls | None:
        """New controls to request, or None. ``frame_controls``: what the frame with this ``mean`` was taken with."""
        if not self.enabled:
            return None
        if self._pending is not None:
            self._waited += 1
            if frame_controls != self._pending and self._waited < self.config.settle_frames:
                return None  # that request has not reached a frame yet
            self._pending = None
        c = self.config
        if c.low <= mean <= c.high:
            return None
        target = 0.5 * (c.low + c.high)
        # e = ln b_target − ln b_mean; the step K_p·e, capped; a clipped frame hides its error: the full cap
        max_step = math.log(c.max_step_ratio)
        if mean >= SATURATED_MEAN:
            step = -max_step
        elif mean <= BLACK_MEAN:
            step = max_step
        else:
            step = max(-max_step, min(max_step, c.gain * (math.log(target) - math.log(mean))))
        exposure = min(c.max_exposure, max(c.min_exposure, frame_controls.exposure * math.exp(step)))
        if exposure == frame_controls.exposure:
            return None  # at a limit: nothing more to do
        self._pending = ExposureControls(brightness=frame_controls.brightness, exposure=exposure)
        self._waited = 0
        return self._pending
