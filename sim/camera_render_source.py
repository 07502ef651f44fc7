"""The simulated camera behind ``app.sensors.camera.CameraSource``: rendered frames on the loop clock.

Frames are captured at ``fps_hz`` on the clock (capture k at ``t0 + k / fps``), rendered from the true poses at
that instant (:class:`sim.camera_render.CameraRenderer`) and become available ``latency_s`` later — like a
real camera's exposure, readout and transfer. ``next_frame`` hands over the newest available frame not yet
handed over, waiting on the clock if there is none; frames the consumer was too slow for are dropped and
counted (latest wins), exactly like the real capture thread. Only the frame handed over is rendered.

Exposure requests apply from the first capture that starts one frame period after the request (a real sensor
finishes the frame it is exposing). Ground truth of every handed-over frame is kept by sequence number.
Under looptime the whole thing runs in virtual time.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Self

from app.clock import Clock, sleep_until
from app.sensors.camera import CameraFrame, CameraSource, ExposureControls
from sim.camera_render import CameraRenderer, Conditions, FrameTruth, Pose

Scene = Callable[[float], tuple[Pose, Pose | None]]  # t_s → (camera pose, object pose or None)
TRUTH_KEPT = 64


class SimCamera:
    """A ``CameraSource`` that renders the simulated world."""

    def __init__(
        self,
        renderer: CameraRenderer,
        scene: Scene,
        clock: Clock,
        *,
        fps_hz: float | None = None,
        latency_s: float = 0.03,
        controls: ExposureControls | None = None,
        conditions: Callable[[float], Conditions] | Conditions | None = None,
        t0_s: float | None = None,
    ) -> None:
        self.renderer = renderer
        self._scene = scene
        self._clock = clock
        self.fps_hz = fps_hz or renderer.camera.fps_hz
        self.latency_s = latency_s
        self._requests: list[tuple[float, ExposureControls]] = [(-math.inf, controls or ExposureControls())]
        self._conditions = conditions
        self._t0_s = t0_s
        self._last_seq = -1
        self._dropped = 0
        self.truth: OrderedDict[int, FrameTruth] = OrderedDict()

    @property
    def controls(self) -> ExposureControls:
        return self._requests[-1][1]

    @property
    def dropped_frames(self) -> int:
        return self._dropped

    def set_controls(self, controls: ExposureControls) -> None:
        self._requests.append((self._clock.now_s(), controls))
        del self._requests[:-8]  # only the recent ones can still matter

    async def __aenter__(self) -> Self:
        if self._t0_s is None:
            self._t0_s = self._clock.now_s()
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        return None

    def capture_time_s(self, seq: int) -> float:
        return (self._t0_s or 0.0) + seq / self.fps_hz

    async def next_frame(self) -> CameraFrame:
        if self._t0_s is None:
            self._t0_s = self._clock.now_s()
        # the newest capture already delivered (captured at least latency_s ago)
        newest = math.floor((self._clock.now_s() - self.latency_s - self._t0_s) * self.fps_hz + 1e-9)
        if newest <= self._last_seq:
            newest = self._last_seq + 1
            await sleep_until(self._clock, self.capture_time_s(newest) + self.latency_s)
        else:
            self._dropped += newest - self._last_seq - 1  # captured, never handed over
        self._last_seq = newest
        t_s = self.capture_time_s(newest)
        controls = self._controls_at(t_s)
        cam, obj = self._scene(t_s)
        cond = self._conditions(t_s) if callable(self._conditions) else self._conditions
        frame = self.renderer.render(t_s, cam, obj, controls, cond, frame_index=newest)
        self.truth[newest] = frame.truth
        while len(self.truth) > TRUTH_KEPT:
            self.truth.popitem(last=False)
        return CameraFrame(t_s=t_s, seq=newest, image=frame.image, controls=controls)

    def _controls_at(self, t_capture_s: float) -> ExposureControls:
        """The last request made at least one frame period before the capture."""
        chosen = self._requests[0][1]
        for t_request, controls in self._requests:
            if t_request <= t_capture_s - 1.0 / self.fps_hz:
                chosen = controls
        return chosen


if TYPE_CHECKING:

    def _is_a_camera_source(camera: SimCamera) -> CameraSource:
        return camera  # mypy checks SimCamera against the protocol here
