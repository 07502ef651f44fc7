"""The pickup's sensor tasks talk to its estimates through bounded latest-wins queues (``app.queues``).

Producers — the camera task (capture → detector, in a worker thread) and the radar task (driver → altitude
estimator), or the simulator's geometric sensors in process — put what they measured, stamped with the
time it was *measured*. Two consumer tasks on the event loop hand each item to ``PickupEstimates`` (the
only place its state changes, always on the loop's thread). A consumer that falls behind loses the oldest
items, never the newest, and every loss is counted for the run's summary.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import threading
from collections.abc import Awaitable, Callable, Coroutine
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

from app.clock import Clock
from app.messages import PixelDetection
from app.missions.pickup import PickupEstimates, RadarCalibrator
from app.missions.sensor_log import CameraFrameLog
from app.queues import LatestQueue
from app.sensors.camera import CameraError, CameraSource
from app.sensors.detect import Detector
from app.sensors.radar_task import FrameCallback, RadarTask
from app.sensors.x4m03_driver import X4M03Radar
from app.settings import Settings

QUEUE_SIZE = 4


@dataclass(frozen=True, slots=True)
class CameraObservation:
    """One processed camera frame: a marker's 4 raw corner pixels, or a buoy's centre and diameter (raw pixels),
    or neither when nothing was found."""

    t_s: float  # capture time (loop clock)
    corners_px: tuple[tuple[float, float], ...] | None = None
    size_m: float | None = None  # the physical edge of the marker seen (a nested one near touchdown); None: outer
    center_px: tuple[float, float] | None = None  # a buoy's centre …
    diameter_px: float | None = None  # … and its diameter on the image

    @classmethod
    def of(cls, t_s: float, det: PixelDetection | None) -> CameraObservation:
        """What the camera task hands on from one detector result."""
        if det is None:
            return cls(t_s)
        if det.corners_px:
            return cls(t_s, det.corners_px, det.size_m)
        return cls(t_s, center_px=det.center_px, diameter_px=det.size_px)


@dataclass(frozen=True, slots=True)
class HeightSample:
    """The radar's height above the sea at ``t_s``; ``None`` when the radar is lost."""

    t_s: float
    height_m: float | None


async def _no_wait() -> None:
    return None


class PickupFeeds:
    """The pickup's queues, and the estimator's two consumers of them. ``make_room`` is awaited before each
    update (the setpoint loop's: an update does not start just before its tick, ``SetpointLoop.make_room``)."""

    def __init__(
        self,
        maxsize: int = QUEUE_SIZE,
        model: PickupEstimates | None = None,
        make_room: Callable[[], Awaitable[None]] = _no_wait,
    ) -> None:
        self.frames: LatestQueue[CameraObservation] = LatestQueue(maxsize)
        self.heights: LatestQueue[HeightSample] = LatestQueue(maxsize)
        self.model = model
        self._make_room = make_room

    def set_radar_calibrator(self, calibrator: RadarCalibrator) -> None:
        """The radar producer offers its background capture to the mission's CALIBRATE_RADAR."""
        if self.model is not None:
            self.model.radar_calibrator = calibrator

    async def consume_frames(self, model: PickupEstimates) -> None:
        while True:
            obs = await self.frames.get()
            await self._make_room()
            if obs.corners_px is not None:
                model.on_marker(obs.t_s, obs.corners_px, obs.size_m)
            elif obs.center_px is not None and obs.diameter_px is not None:
                model.on_buoy(obs.t_s, obs.center_px, obs.diameter_px)
            else:
                model.on_frame(obs.t_s)

    async def consume_heights(self, model: PickupEstimates) -> None:
        while True:
            h = await self.heights.get()
            await self._make_room()
            if h.height_m is None:
                model.on_radar_lost()
            else:
                model.on_height(h.t_s, h.height_m)

    def summary(self) -> dict[str, Any]:
        return {
            "queue_drops": {"camera": self.frames.dropped, "radar": self.heights.dropped},
            "queue_puts": {"camera": self.frames.put_count, "radar": self.heights.put_count},
        }


Producer = Callable[[PickupFeeds], Coroutine[Any, Any, None]]
CAMERA_OPEN_TIMEOUT_S = 15.0  # a networked camera (the simulator's) may come up after the app
# The detector's thread runs this much nicer than the event loop (Linux: per-thread niceness): when both cores
# are busy, the loop's 50 Hz setpoint tick is not queued behind a detection (the kernel's wake-up granularity
# is milliseconds); a detection that finishes a little later only makes its frame a little older.
DETECTOR_NICE = 5


def lower_this_threads_priority(nice: int = DETECTOR_NICE) -> None:
    """Make the calling thread ``nice`` steps nicer (Linux; elsewhere, or when refused, nothing happens)."""
    with contextlib.suppress(OSError, AttributeError):
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + nice)


def camera_producer(
    open_camera: Callable[[], CameraSource],
    detector: Detector,
    clock: Clock,
    open_timeout_s: float = CAMERA_OPEN_TIMEOUT_S,
    frame_log: CameraFrameLog | None = None,
) -> Producer:
    """The camera task: frames → the detector (in its own worker thread, never on the loop, at a lower priority
    than the loop: ``DETECTOR_NICE``) → ``feeds.frames``. With a ``frame_log``, the frames it finds due are
    downscaled, encoded and written by the same worker thread after their detection.

    Opening is retried for ``open_timeout_s``; after that, and for a camera that fails later, the
    ``CameraError`` ends the task (the mission sees the camera's frames age: a guard input).
    """

    async def produce(feeds: PickupFeeds) -> None:
        worker = ThreadPoolExecutor(1, "camera.detector", initializer=lower_this_threads_priority)
        try:
            await _produce(feeds, worker)
        finally:
            worker.shutdown(wait=False, cancel_futures=True)  # never block the loop on a detection in flight

    async def _produce(feeds: PickupFeeds, worker: ThreadPoolExecutor) -> None:
        loop = asyncio.get_running_loop()
        deadline_s = clock.now_s() + open_timeout_s
        while True:
            camera = open_camera()
            try:
                await camera.__aenter__()
                frame = await camera.next_frame()
                break
            except CameraError:
                await camera.__aexit__(None, None, None)
                if clock.now_s() >= deadline_s:
                    raise
                await clock.sleep(0.5)
        try:
            while True:
                # the buoy detector sizes its search from the height (a marker's decoding needs none)
                height_m = feeds.model.latest_height_m() if feeds.model is not None else None
                det = await loop.run_in_executor(worker, detector.detect, frame.image, frame.t_s, None, height_m)
                feeds.frames.put(CameraObservation.of(frame.t_s, det))
                if frame_log is not None and frame_log.due(frame.t_s):
                    await loop.run_in_executor(worker, frame_log.save, frame.t_s, frame.image)
                frame = await camera.next_frame()
        finally:
            await camera.__aexit__(None, None, None)

    return produce


def radar_producer(make_task: Callable[[PickupFeeds], RadarTask]) -> Producer:
    """The radar task (driver → altitude estimator): heights and losses into ``feeds.heights``."""

    async def produce(feeds: PickupFeeds) -> None:
        await make_task(feeds).run()

    return produce


def radar_task_for(
    settings: Settings, port: str, on_frame: FrameCallback | None = None
) -> Callable[[PickupFeeds], RadarTask]:
    """The radar task on ``port``, its heights into ``feeds``; every frame also to ``on_frame`` (the run's decimated
    profiles: ``app.missions.sensor_log.RadarProfileLog``) when one is given."""

    def make(feeds: PickupFeeds) -> RadarTask:
        radar = X4M03Radar(settings.radar.model_copy(update={"port": port}))
        task = RadarTask(
            radar,
            settings.radar_altitude,
            on_height=lambda t_s, h_m: feeds.heights.put(HeightSample(t_s, h_m)),
            on_lost=lambda t_s, why: feeds.heights.put(HeightSample(t_s, None)),
            on_frame=on_frame,
        )
        feeds.set_radar_calibrator(RadarCalibrator(settings.radar.frame_area_end_m, task.capture_background))
        return task

    return make
