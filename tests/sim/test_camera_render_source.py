"""The simulated camera source on the loop clock: latest wins, capture stamps, exposure control, auto-exposure."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from app.clock import LoopClock
from app.sensors.camera import ExposureControls
from app.sensors.exposure import AutoExposure, AutoExposureConfig, mean_brightness
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions
from sim.camera_render_poses import Pose, camera_pose, object_pose
from sim.camera_render_source import SimCamera
from sim.sea import FloatingObject, SeaConfig, SeaWorld

pytestmark = pytest.mark.looptime

CAMERA = CameraSettings()
OBJECT = FloatingObject(SeaWorld(SeaConfig(sea_state=2), seed=4))
RENDERER = CameraRenderer(CAMERA, DetectorSettings(), seed=4)


def hover(t_s: float) -> tuple[Pose, Pose | None]:
    """5 m above the object, drifting slowly."""
    obj = object_pose(OBJECT, t_s)
    return camera_pose(obj.pos_ned_m + np.array([0.3, 0.2, -5.0]), 0.02, -0.03, 0.1, CAMERA), obj


def camera(**kw) -> SimCamera:
    return SimCamera(RENDERER, hover, LoopClock(), fps_hz=30.0, latency_s=0.03, **kw)


async def test_a_slow_consumer_gets_the_newest_frame_stamped_with_its_capture_time() -> None:
    clock = LoopClock()
    async with camera() as cam:
        t0 = clock.now_s()
        last_seq = -1
        for _ in range(5):
            await asyncio.sleep(0.1)  # three frame periods
            frame = await cam.next_frame()
            newest = math.floor((clock.now_s() - 0.03 - t0) * 30.0 + 1e-9)
            assert frame.seq == newest > last_seq
            assert frame.t_s == pytest.approx(t0 + frame.seq / 30.0)
            assert cam.truth[frame.seq].in_view
            last_seq = frame.seq
        assert cam.dropped_frames == last_seq + 1 - 5


async def test_a_fast_consumer_waits_for_capture_plus_latency() -> None:
    clock = LoopClock()
    async with camera() as cam:
        first = await cam.next_frame()
        second = await cam.next_frame()
        assert second.seq == first.seq + 1
        assert clock.now_s() == pytest.approx(second.t_s + 0.03, abs=1e-5)
        assert cam.dropped_frames == 0


async def test_exposure_requests_apply_from_the_next_frame_period() -> None:
    async with camera(controls=ExposureControls(32.0, 48.0)) as cam:
        before = await cam.next_frame()
        cam.set_controls(ExposureControls(32.0, 24.0))
        frames = [await cam.next_frame() for _ in range(3)]
    assert frames[0].controls == ExposureControls(32.0, 48.0)  # the sensor was already exposing it
    assert frames[-1].controls == ExposureControls(32.0, 24.0)
    assert mean_brightness(frames[-1].image) < 0.7 * mean_brightness(before.image)


@pytest.mark.parametrize(("start_exposure", "illumination"), [(6.0, 1.0), (48.0, 4.0), (800.0, 1.0)])
async def test_auto_exposure_brings_the_mean_into_the_band(start_exposure: float, illumination: float) -> None:
    """From too dark, too bright (bright day) and saturated starts, within a few frames, and it stays there."""
    ae = AutoExposure(AutoExposureConfig.from_settings(CAMERA))
    async with camera(
        controls=ExposureControls(32.0, start_exposure), conditions=Conditions(illumination=illumination)
    ) as cam:
        means = []
        for _ in range(16):
            frame = await cam.next_frame()
            means.append(mean_brightness(frame.image))
            request = ae.update(means[-1], frame.controls)
            if request is not None:
                cam.set_controls(request)
    assert not 100.0 <= means[0] <= 140.0
    settled = next(i for i, m in enumerate(means) if 100.0 <= m <= 140.0)
    assert settled <= 8  # a request shows two frames later: at most ~4 steps
    assert all(100.0 <= m <= 140.0 for m in means[settled:])
