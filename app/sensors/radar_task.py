"""The app's radar task: driver frames → altitude estimator → heights above the sea, and "radar lost".

``RadarTask.run()`` is one long-lived task for the app's TaskGroup (named ``radar.task``); inside its own
TaskGroup it runs the driver (``radar.driver``: connect, stream, reconnect), the consumer (``radar.altitude``)
and a watchdog (``radar.watchdog``). Each frame goes to ``RadarAltitudeEstimator`` with the vehicle's roll and
pitch at the frame's measured time when an ``attitude_at`` provider is given (else level flight: with the
specular tilt model the attitude only moves the antenna's lever arm); each accepted height is handed to
``on_height(t_s, height_m)`` with the frame's time. Every frame, before the estimator sees it, also goes to
``on_frame`` when one is given (the run's decimated profiles, ``app.missions.sensor_log``: it must be quick).
Wiring to the mission (``app.missions.pickup_feeds``)::

    RadarTask(radar, settings.radar_altitude,
              on_height=lambda t_s, h_m: feeds.heights.put(HeightSample(t_s, h_m)),
              on_lost=lambda t_s, why: feeds.heights.put(HeightSample(t_s, None)))

"Radar lost" goes to ``on_lost(t_s, reason)`` once per loss (again only after a height came through):

- the port went away (the driver counted a disconnect; it keeps trying to reconnect on its own);
- no frame for ``frame_timeout_s`` (``startup_timeout_s`` until the first frame: the device boots);
- the estimator, after tracking, found no echo for its ``timeout_s`` (sea out of range, or lost in clutter).

Background map (thesis §4.2.2; the mission's CALIBRATE_RADAR state): climb until the sea is out of range,
``await capture_background(n)``, come back. It takes the next ``n`` frames measured after the call, checks
them (``calibrate_background``) and, with ``method: background``, switches the estimator to the map. It
raises ``RadarCalibrationError`` (``reason``) when the frames hold an echo (the sea is still in range: try
higher), too few arrive in time, or the port goes away meanwhile. Until a calibration succeeds the estimator
runs the adaptive clutter map (thesis eq. 5.1) on amplitudes (``FALLBACK_DOMAIN``) — whenever the settings
say ``background``, which is their default: a background method without a map would give no height at all.
With ``method: clutter_map`` the settings are used as they are, and a calibration is only checked and kept.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from app.clock import Clock, LoopClock
from app.errors import AppError
from app.estimators.radar_altitude import (
    AltitudeEstimate,
    BackgroundCalibration,
    RadarAltitudeEstimator,
    calibrate_background,
)
from app.messages import RadarFrame
from app.sensors.radar import RadarError
from app.sensors.x4m03_driver import X4M03Radar
from app.settings import RadarAltitudeSettings

HeightCallback = Callable[[float, float], None]  # (t_s measured, height_m above the sea)
LostCallback = Callable[[float, str], None]  # (t_s, reason)
AttitudeAt = Callable[[float], tuple[float, float] | None]  # t_s → (roll_rad, pitch_rad), None when unknown
FrameCallback = Callable[[RadarFrame], None]  # every frame as it arrives, on the loop

FRAME_TIMEOUT_S = 1.0  # no frame for this long → lost (ten frames at the thesis's 10 Hz)
STARTUP_TIMEOUT_S = 10.0  # … before the first frame: boot, ping until ready, configure
WATCHDOG_PERIOD_S = 0.1
# The clutter map used while there is no background map runs on amplitudes (the thesis's eq. 5.1). Measured on
# the emulator, sea state 1: on the complex baseband a map that has absorbed a hovering vehicle's echo leaves a
# ghost |−C| as strong as the echo where it was, and the gate locks onto it when the vehicle climbs (hover 1 s,
# climb 0.5 m/s, 16 seeds: 6 runs locked, errors to 2 m; on amplitudes none, p95 4 cm). The price: in a steady
# hover amplitudes give a height on ~75 % of the frames (complex ~100 %), p95 7 cm (complex 2.5 cm). Both read
# false heights when the sea is nearer than the first range (to 22 cm off on amplitudes, 41 cm complex); the
# background map does not.
FALLBACK_DOMAIN: Literal["amplitude"] = "amplitude"


class RadarCalibrationError(RadarError):
    """Raised by ``capture_background`` when no background map came out; ``reason`` says why, ``frames`` how
    many frames were captured."""

    def __init__(self, port: str, reason: str, frames: int) -> None:
        self.reason = reason
        self.frames = frames
        super().__init__(port, f"background calibration failed: {reason}")


@dataclass(slots=True)
class _Capture:
    n_frames: int
    since_s: float  # only frames measured from here on
    future: asyncio.Future[list[RadarFrame]]
    frames: list[RadarFrame] = field(default_factory=list)


class RadarTask:
    """The radar as the mission sees it: heights above the sea and losses, through two callbacks."""

    def __init__(
        self,
        radar: X4M03Radar,
        settings: RadarAltitudeSettings,
        on_height: HeightCallback,
        on_lost: LostCallback,
        *,
        attitude_at: AttitudeAt | None = None,
        on_frame: FrameCallback | None = None,
        clock: Clock | None = None,
        frame_timeout_s: float = FRAME_TIMEOUT_S,
        startup_timeout_s: float = STARTUP_TIMEOUT_S,
        fallback_domain: Literal["complex", "amplitude"] = FALLBACK_DOMAIN,
    ) -> None:
        self.radar = radar
        self.settings = settings
        self.on_height = on_height
        self.on_lost = on_lost
        self.attitude_at = attitude_at
        self.on_frame = on_frame
        self.clock: Clock = clock if clock is not None else LoopClock()
        self.frame_timeout_s = frame_timeout_s
        self.startup_timeout_s = startup_timeout_s
        self.fallback_domain = fallback_domain
        self.calibration: BackgroundCalibration | None = None
        self.estimator = self._estimator(None)
        self.last: AltitudeEstimate | None = None
        self.heights = 0
        self.lost_reports = 0
        self.last_lost_reason: str | None = None
        self.attitude_missing = 0  # frames processed as level because the attitude at their time was unknown
        self.non_finite_frames = 0  # frames with a NaN/inf bin, across estimators
        self._lost_reported = False
        self._capture: _Capture | None = None
        self._last_frame_s: float | None = None  # loop time the last frame arrived
        self._started_s: float | None = None
        self._disconnects_seen = 0

    # ------------------------------------------------------------------------------------------ the task

    async def run(self) -> None:
        """The driver, the consumer and the watchdog, until cancelled (the driver then stops the stream)."""
        self._started_s = self.clock.now_s()
        self._disconnects_seen = self.radar.stats.disconnects
        async with asyncio.TaskGroup() as tg:
            tg.create_task(self.radar.run(), name="radar.driver")
            tg.create_task(self._consume(), name="radar.altitude")
            tg.create_task(self._watch(), name="radar.watchdog")

    async def capture_background(self, n_frames: int, timeout_s: float | None = None) -> BackgroundCalibration:
        """The background map from the next ``n_frames`` frames (sea out of range); raises
        ``RadarCalibrationError`` with the reason when it fails. ``timeout_s`` defaults to twice the frames'
        time at the configured rate plus 2 s. Needs ``run()`` going."""
        if self._capture is not None:
            raise RuntimeError("a background capture is already running")
        if n_frames < self.settings.calibration_min_frames:
            raise ValueError(f"n_frames {n_frames} < calibration_min_frames {self.settings.calibration_min_frames}")
        wait_s = 2.0 * n_frames / self.radar.settings.fps_hz + 2.0 if timeout_s is None else timeout_s
        capture = _Capture(n_frames, self.clock.now_s(), asyncio.get_running_loop().create_future())
        self._capture = capture
        try:
            frames = await asyncio.wait_for(capture.future, wait_s)
        except TimeoutError:
            got = len(capture.frames)
            raise RadarCalibrationError(
                self.radar.port, f"only {got} of {n_frames} frames arrived within {wait_s:g} s", got
            ) from None
        finally:
            self._capture = None
        calibration = calibrate_background(frames, self.settings)
        if not calibration.ok:
            raise RadarCalibrationError(self.radar.port, calibration.reason, len(frames))
        self.calibration = calibration
        if self.settings.method == "background":
            self.estimator = self._estimator(calibration)  # a fresh track: it acquires over every bin
            self.last = None
        return calibration

    def summary(self) -> dict[str, Any]:
        """Counters for the run's summary: frames, heights, losses, and every frame lost or spoilt on the way."""
        s, p = self.radar.stats, self.radar.stats.parser
        return {
            "method": self.estimator.config.method,
            "domain": self.estimator.config.domain,
            "calibrated": self.calibration is not None,
            "status": None if self.last is None else self.last.status,
            "frames": s.frames,
            "heights": self.heights,
            "lost_reports": self.lost_reports,
            "last_lost_reason": self.last_lost_reason,
            "dropped_frames": s.dropped_frames,  # gaps in the device's frame counter
            "queue_drops": s.queue_drops,  # the consumer was slower than the radar
            "rejected_frames": s.rejected_frames,  # wrong size / no range axis yet
            "corrupt_packets": p.crc_errors + p.bad_packets + p.bad_lengths,
            "garbage_bytes": p.garbage_bytes,
            "non_finite_frames": self.non_finite_frames,
            "attitude_missing": self.attitude_missing,
            "connects": s.connects,
            "disconnects": s.disconnects,
            "connect_failures": s.connect_failures,
        }

    # ---------------------------------------------------------------------------------------- internals

    def _estimator(self, calibration: BackgroundCalibration | None) -> RadarAltitudeEstimator:
        config = self.settings
        if calibration is None and config.method == "background":  # no map yet: the adaptive one
            config = config.model_copy(update={"method": "clutter_map", "domain": self.fallback_domain})
        offset = self.radar.settings.lever_arm_frd_m
        return RadarAltitudeEstimator(config, calibration if config.method == "background" else None, offset)

    async def _consume(self) -> None:
        while True:
            frame = await self.radar.next_frame()
            self._on_frame(frame)

    def _on_frame(self, frame: RadarFrame) -> None:
        self._last_frame_s = self.clock.now_s()
        capture = self._capture
        if capture is not None and frame.t_s >= capture.since_s and not capture.future.done():
            capture.frames.append(frame)
            if len(capture.frames) >= capture.n_frames:
                capture.future.set_result(list(capture.frames))
        if self.on_frame is not None:
            self.on_frame(frame)
        roll_rad, pitch_rad = self._attitude(frame.t_s)
        estimator = self.estimator
        before = estimator.rejected_non_finite
        was_tracking = self.last is not None and self.last.status in ("tracking", "holding")
        est = estimator.update(frame, roll_rad, pitch_rad)
        self.non_finite_frames += estimator.rejected_non_finite - before
        self.last = est
        if est.accepted and est.altitude_m is not None:
            self.heights += 1
            self._lost_reported = False
            self.on_height(frame.t_s, est.altitude_m)
        elif est.status == "lost" and was_tracking:
            self._lost(frame.t_s, f"no echo for {self.estimator.config.timeout_s:g} s (sea out of range or in clutter)")

    def _attitude(self, t_s: float) -> tuple[float, float]:
        if self.attitude_at is None:
            return 0.0, 0.0
        try:
            attitude = self.attitude_at(t_s)
        except AppError:  # e.g. OutsideHistoryError: no vehicle state around the frame's time
            attitude = None
        if attitude is None:
            self.attitude_missing += 1
            return 0.0, 0.0
        return attitude

    async def _watch(self) -> None:
        while True:
            await self.clock.sleep(WATCHDOG_PERIOD_S)
            now_s = self.clock.now_s()
            disconnects = self.radar.stats.disconnects
            if disconnects != self._disconnects_seen:
                self._disconnects_seen = disconnects
                self._fail_capture(f"the radar port {self.radar.port} went away during the capture")
                self._lost(now_s, f"port {self.radar.port} gone")
                continue
            if self._last_frame_s is None:
                assert self._started_s is not None
                if now_s - self._started_s > self.startup_timeout_s:
                    self._lost(now_s, f"no frame within {self.startup_timeout_s:g} s of starting")
            elif now_s - self._last_frame_s > self.frame_timeout_s:
                self._lost(now_s, f"no frame for {now_s - self._last_frame_s:.1f} s")

    def _fail_capture(self, reason: str) -> None:
        capture = self._capture
        if capture is not None and not capture.future.done():
            capture.future.set_exception(RadarCalibrationError(self.radar.port, reason, len(capture.frames)))

    def _lost(self, t_s: float, reason: str) -> None:
        if self._lost_reported:
            return
        self._lost_reported = True
        self.lost_reports += 1
        self.last_lost_reason = reason
        self.on_lost(t_s, reason)
