"""The capture thread and its latest-wins handoff: the consumer always gets the newest frame, drops are counted."""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np
import pytest

from app.sensors.camera import CameraError, ExposureControls, ThreadedCamera
from app.sensors.camera_v4l2 import open_v4l2_camera
from app.settings import CameraSettings


class FastGrabber:
    """Makes a frame every ``period_s`` (far faster than the test reads), its number written into pixel (0, 0)."""

    name = "fake"

    def __init__(self, period_s: float = 0.0005, fail_after: int | None = None) -> None:
        self.period_s = period_s
        self.fail_after = fail_after
        self.count = 0
        self.applied: list[tuple[ExposureControls, int, str]] = []
        self.closed = False

    def grab(self) -> np.ndarray:
        time.sleep(self.period_s)
        if self.fail_after is not None and self.count >= self.fail_after:
            raise OSError("device unplugged")
        image = np.zeros((4, 4), np.uint8)
        image[0, 0] = self.count % 256
        self.count += 1
        return image

    def apply_controls(self, controls: ExposureControls) -> None:
        self.applied.append((controls, self.count, threading.current_thread().name))

    def close(self) -> None:
        self.closed = True


async def test_capture_thread_hands_over_the_newest_frame_to_a_slow_consumer() -> None:
    grabber = FastGrabber()
    stamps = iter(range(10**9))
    camera = ThreadedCamera(grabber, clock=lambda: 100.0 + next(stamps), latency_s=0.5)
    async with camera:
        frames = []
        for _ in range(15):
            await asyncio.sleep(0.01)  # much slower than the camera
            captured_before = camera.captured_frames
            frame = await camera.next_frame()
            assert frame.seq >= captured_before - 1  # nothing newer was waiting
            frames.append(frame)
    seqs = [f.seq for f in frames]
    assert seqs == sorted(set(seqs))
    assert all(int(f.image[0, 0]) == f.seq % 256 for f in frames)
    assert all(f.t_s == 100.0 + f.seq - 0.5 for f in frames)  # stamped by the injected clock, minus latency
    assert camera.dropped_frames >= frames[-1].seq - len(frames)
    assert grabber.closed


async def test_controls_are_applied_by_the_capture_thread_and_stamped_on_later_frames() -> None:
    grabber = FastGrabber(period_s=0.002)
    camera = ThreadedCamera(grabber, clock=time.monotonic, controls=ExposureControls(30.0, 40.0))
    async with camera:
        first = await camera.next_frame()
        assert first.controls == ExposureControls(30.0, 40.0)
        camera.set_controls(ExposureControls(30.0, 90.0))
        assert camera.controls == ExposureControls(30.0, 90.0)
        while (frame := await camera.next_frame()).controls != ExposureControls(30.0, 90.0):
            pass
        assert frame.seq > first.seq
    assert [c for c, _, _ in grabber.applied] == [ExposureControls(30.0, 40.0), ExposureControls(30.0, 90.0)]
    assert all(name.startswith("camera.capture") for _, _, name in grabber.applied)


async def test_a_failing_device_surfaces_as_camera_error() -> None:
    camera = ThreadedCamera(FastGrabber(fail_after=3), clock=time.monotonic)
    async with camera:
        with pytest.raises(CameraError) as err:
            for _ in range(100):
                await camera.next_frame()
                await asyncio.sleep(0.001)
    assert err.value.device == "fake"


async def test_a_consumer_waiting_for_a_frame_is_woken_by_the_failure() -> None:
    camera = ThreadedCamera(FastGrabber(period_s=0.05, fail_after=0), clock=time.monotonic)
    async with camera:
        with pytest.raises(CameraError) as err:
            await asyncio.wait_for(camera.next_frame(), 5.0)  # waits: the grabber fails before its first frame
    assert isinstance(err.value.__cause__, OSError)


async def test_a_missing_v4l2_device_is_a_camera_error_naming_it() -> None:
    camera = open_v4l2_camera(CameraSettings(device="/dev/video-seapick-missing"), clock=time.monotonic)
    async with camera:
        with pytest.raises(CameraError) as err:
            await camera.next_frame()
    assert err.value.device == "/dev/video-seapick-missing"
    assert "cannot open" in str(err.value.__cause__)
