"""The camera source: one interface that the V4L2 camera and the simulator (``sim.camera_render_source``) implement.

A blocking capture runs in its own thread and hands frames to the asyncio loop through a one-item, latest-wins
queue (:class:`app.queues.LatestQueue`): when the consumer is slower than the camera, the older frame is dropped
and counted, so the detector always gets the *newest* frame — never a stale buffered one (the thesis had to patch
the oCam library for this, §4.2.3). Each frame is stamped with its capture time by a clock function the caller
injects (mapped to the loop clock); this module reads no clock of its own. A grabber whose source stamps its own
frames (a networked camera, :mod:`app.sensors.camera_socket`) implements ``grab_stamped`` instead: its stamp,
frame counter and controls in effect are used as they come.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, Self, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from app.errors import AppError
from app.queues import LatestQueue, QueueShutDown

Image = NDArray[np.uint8]


class CameraError(AppError):
    """Raised when the camera cannot be opened or stops delivering frames; ``device`` names it."""

    def __init__(self, device: str, detail: str) -> None:
        self.device = device
        self.detail = detail
        super().__init__(f"camera {device}: {detail}")


@dataclass(frozen=True, slots=True)
class ExposureControls:
    """The camera's brightness and exposure, in device units (V4L2 ``brightness``; ``exposure_time_absolute``
    in 100 µs steps). Thesis defaults: brightness 32, exposure 48."""

    brightness: float = 32.0
    exposure: float = 48.0


@dataclass(frozen=True, slots=True, eq=False)
class CameraFrame:
    """One raw (distorted) mono image and the loop-clock time ``t_s`` it was captured."""

    t_s: float
    seq: int  # the source's frame counter: gaps are frames that were dropped
    image: Image  # H×W uint8
    controls: ExposureControls  # in effect when the frame was captured


class CameraSource(Protocol):
    """What the app needs from a camera; the V4L2 adapter and the simulator implement it."""

    @property
    def controls(self) -> ExposureControls:
        """The controls last requested (they apply to frames captured after the request)."""
        ...

    @property
    def dropped_frames(self) -> int:
        """Frames captured but never handed over because a newer one replaced them."""
        ...

    def set_controls(self, controls: ExposureControls) -> None:
        """Request new brightness/exposure; never blocks."""
        ...

    async def next_frame(self) -> CameraFrame:
        """The newest frame not yet handed over; waits for one. Raises ``CameraError`` if capture failed."""
        ...

    async def __aenter__(self) -> Self: ...

    async def __aexit__(self, *exc_info: object) -> None: ...


class FrameGrabber(Protocol):
    """A blocking frame producer, used only from the capture thread (the real V4L2 device, or a test double)."""

    name: str

    def grab(self) -> Image:
        """Block until the next frame; raise ``CameraError`` when the device fails."""
        ...

    def apply_controls(self, controls: ExposureControls) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True, slots=True, eq=False)
class StampedImage:
    """A frame as a self-stamping source delivers it: capture time already on the loop clock, its own counter."""

    image: Image
    t_s: float  # capture time, loop clock
    seq: int  # the source's frame counter
    controls: ExposureControls  # what the source says was in effect


@runtime_checkable
class StampingGrabber(FrameGrabber, Protocol):
    """A grabber whose source stamps each frame at capture (a networked camera); ``ThreadedCamera`` calls
    ``grab_stamped`` instead of ``grab`` and needs no clock of its own."""

    def grab_stamped(self) -> StampedImage:
        """Block until the next frame; raise ``CameraError`` when the source fails."""
        ...


@dataclass
class _CaptureState:
    stop: threading.Event = field(default_factory=threading.Event)
    error: BaseException | None = None


class ThreadedCamera:
    """``CameraSource`` over a blocking :class:`FrameGrabber`: capture thread → one-item queue → the loop.

    ``clock`` is called in the capture thread right after each grab and must return loop-clock seconds (the
    default event loop's ``loop.time`` does); ``latency_s`` is subtracted (exposure + readout before the grab
    returns). A :class:`StampingGrabber` brings its own stamps: ``clock`` and ``latency_s`` are not used.
    Control changes are applied by the capture thread between grabs.
    """

    def __init__(
        self,
        grabber: FrameGrabber,
        clock: Callable[[], float] | None = None,
        *,
        controls: ExposureControls | None = None,
        latency_s: float = 0.0,
    ) -> None:
        if clock is None and not isinstance(grabber, StampingGrabber):
            raise ValueError(f"camera {grabber.name}: a grabber that does not stamp its frames needs a clock")
        self._grabber = grabber
        self._clock = clock
        self._latency_s = latency_s
        self._controls = controls or ExposureControls()
        self._pending_controls: ExposureControls | None = self._controls
        self._controls_lock = threading.Lock()
        self._frames: LatestQueue[CameraFrame] = LatestQueue(maxsize=1)
        self._state = _CaptureState()
        self._thread: threading.Thread | None = None

    @property
    def controls(self) -> ExposureControls:
        return self._controls

    @property
    def dropped_frames(self) -> int:
        return self._frames.dropped

    @property
    def captured_frames(self) -> int:
        return self._frames.put_count

    def set_controls(self, controls: ExposureControls) -> None:
        with self._controls_lock:
            self._controls = controls
            self._pending_controls = controls

    def start(self) -> None:
        """Start the capture thread."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(target=self._run, name=f"camera.capture[{self._grabber.name}]", daemon=True)
        self._thread.start()

    async def close(self) -> None:
        """Stop the capture thread and release the device."""
        self._state.stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            await asyncio.to_thread(thread.join)
        self._grabber.close()

    async def __aenter__(self) -> Self:
        self.start()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.close()

    async def next_frame(self) -> CameraFrame:
        frame = self._frames.take()
        if frame is not None:
            return frame
        if self._state.error is not None:
            raise CameraError(self._grabber.name, "capture stopped") from self._state.error
        if self._thread is None:
            raise CameraError(self._grabber.name, "not started")
        try:
            return await self._frames.get()
        except QueueShutDown:  # the capture thread failed while we waited
            raise CameraError(self._grabber.name, "capture stopped") from self._state.error

    def _run(self) -> None:
        seq = 0
        in_effect = self._controls
        stamping = self._grabber if isinstance(self._grabber, StampingGrabber) else None
        try:
            while not self._state.stop.is_set():
                with self._controls_lock:
                    pending, self._pending_controls = self._pending_controls, None
                if pending is not None:
                    self._grabber.apply_controls(pending)
                    in_effect = pending
                if stamping is not None:
                    got = stamping.grab_stamped()
                    self._frames.put(CameraFrame(t_s=got.t_s, seq=got.seq, image=got.image, controls=got.controls))
                    continue
                image = self._grabber.grab()
                assert self._clock is not None  # checked in __init__
                t_s = self._clock() - self._latency_s
                self._frames.put(CameraFrame(t_s=t_s, seq=seq, image=image, controls=in_effect))
                seq += 1
        except BaseException as e:  # the loop side re-raises it as CameraError
            self._state.error = e
            self._frames.shutdown()


if TYPE_CHECKING:

    def _is_a_camera_source(camera: ThreadedCamera) -> CameraSource:
        return camera  # mypy checks ThreadedCamera against the protocol here
