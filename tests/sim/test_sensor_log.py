"""The pickup's sensors recorded for ``run.mcap`` (``app.missions.sensor_log``): the real radar task against the
emulated X4M03 on a pty, the real camera task against the rendered camera on a socket, then ``write_mcap`` over the
run directory — real time, generous bounds (two busy cores)."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import tempfile
import threading
import time
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.foxglove_log import time_ns, write_mcap
from app.messages import PixelDetection, RadarFrame
from app.missions.pickup_feeds import PickupFeeds, camera_producer
from app.missions.sensor_log import CameraFrameLog, Decimator, RadarProfileLog
from app.report import read_jsonl
from app.sensors.camera import Image
from app.sensors.camera_socket import open_socket_camera
from app.sensors.detect import DetectionHint
from app.sensors.detect_marker import MarkerDetector
from app.sensors.radar_task import RadarTask
from app.sensors.x4m03_driver import X4M03Radar
from app.settings import CameraSettings, DetectorSettings, RadarAltitudeSettings, RadarSettings
from sim.camera_render_poses import Pose, camera_seeing, object_pose
from sim.camera_serve import CameraFrameServer
from sim.radar_firmware import FirmwareConfig
from sim.radar_live import PoseTuple, live_sea_emulator
from sim.radar_signal import RadarSignalConfig
from sim.sea import FloatingObject, SeaConfig, SeaWorld
from tests.mcaputil import read_mcap

RUN_S = 3.0  # each sensor records this long (real time)
CAMERA = CameraSettings()
MARKER = DetectorSettings()
OBJECT = object_pose(FloatingObject(SeaWorld(SeaConfig(sea_state=2), seed=4)), 10.0, yaw_rad=0.4)
CAM = camera_seeing(CAMERA, OBJECT, (500.0, 400.0), 5.0, 0.03, -0.05, 0.2)
CAMERA_PERIOD_S = 0.25  # faster than a flight's 1 s: a short test still sees several frames


def hovering(t_s: float) -> PoseTuple:
    """Level, 3 m above the mean sea."""
    return (0.0, 0.0, -3.0), 0.0, 0.0, 0.0


def still(t_s: float) -> tuple[Pose, Pose | None]:
    assert CAM is not None
    return CAM, OBJECT


def records(run_dir: Path, kind: str) -> list[dict[str, Any]]:
    return [r for r in read_jsonl(run_dir / "events.jsonl") if r["kind"] == kind]


@contextlib.asynccontextmanager
async def radar_running(run_dir: Path, events: EventLog, frames: list[RadarFrame]) -> AsyncIterator[RadarProfileLog]:
    """The radar task on an emulated X4M03 over the sea, its frames kept in ``frames`` and logged as profiles."""
    emulator = live_sea_emulator(
        SeaWorld(SeaConfig(sea_state=1), seed=5), hovering, str(run_dir / "x4m03"), seed=1,
        epoch_monotonic_s=time.monotonic(), firmware_config=FirmwareConfig(boot_delay_s=0.0, ready_delay_s=0.05),
    )  # fmt: skip
    emulator.start()
    lever_arm_frd_m = RadarSignalConfig().antenna_offset_frd_m
    radar = X4M03Radar(RadarSettings(port=emulator.path, reconnect_interval_s=0.1, lever_arm_frd_m=lever_arm_frd_m))
    profiles = RadarProfileLog(events)

    def on_frame(frame: RadarFrame) -> None:
        frames.append(frame)
        profiles(frame)

    task = RadarTask(radar, RadarAltitudeSettings(), lambda t, h: None, lambda t, why: None, on_frame=on_frame)
    runner = asyncio.create_task(task.run(), name="radar.task")
    try:
        yield profiles
    finally:
        runner.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await runner
        emulator.stop()


class KeepingDetector(MarkerDetector):
    """The marker detector, keeping every image it was given by capture time (what the JPEGs must show)."""

    def __init__(self) -> None:
        super().__init__(MARKER, CAMERA)
        self.images: dict[float, Image] = {}

    def detect(
        self, image: Image, t_s: float, hint: DetectionHint | None = None, height_m: float | None = None
    ) -> PixelDetection | None:
        self.images[round(t_s, 4)] = image
        return super().detect(image, t_s, hint, height_m)


class ThreadNoting(CameraFrameLog):
    """The camera's frame log, noting the thread each save ran on."""

    threads: list[str]

    def save(self, t_s: float, image: Image) -> str | None:
        self.threads.append(threading.current_thread().name)
        return super().save(t_s, image)


@pytest.fixture
def sock_dir() -> Iterator[str]:
    with tempfile.TemporaryDirectory(prefix="seapick-log") as d:  # short: a Unix socket path has ≤ 107 bytes
        yield d


@contextlib.asynccontextmanager
async def camera_running(
    run_dir: Path, events: EventLog, sock_dir: str, detector: KeepingDetector
) -> AsyncIterator[ThreadNoting]:
    """The camera task on the rendered camera, saving a frame every ``CAMERA_PERIOD_S``."""
    frame_log = ThreadNoting(run_dir, events, period_s=CAMERA_PERIOD_S)
    frame_log.threads = []
    with CameraFrameServer(f"unix:{sock_dir}/cam.sock", CAMERA, MARKER, still, fps_hz=15.0, seed=4) as server:
        produce = camera_producer(
            lambda: open_socket_camera(server.address), detector, LoopClock(), frame_log=frame_log
        )
        runner = asyncio.create_task(produce(PickupFeeds()), name="camera.task")
        try:
            yield frame_log
        finally:
            runner.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await runner
            await asyncio.sleep(0.3)  # a save in flight finishes in its worker


def test_the_decimator_keeps_one_sample_per_period_on_a_grid_and_restarts_after_a_gap() -> None:
    decimator = Decimator(0.5)
    t_s = [100.0 + k / 10.032 for k in range(600)]  # a minute of the X4's 10.032 Hz
    kept = [t for t in t_s if decimator.due(t)]
    assert len(kept) == pytest.approx(60.0 / 0.5, abs=1)
    assert all(0.39 < b - a < 0.61 for a, b in itertools.pairwise(kept))
    assert decimator.due(200.0) and not decimator.due(200.45) and decimator.due(200.5)  # after a gap: from 200


async def test_the_radar_task_logs_each_profile_it_keeps_in_db_at_2_hz(tmp_path: Path) -> None:
    frames: list[RadarFrame] = []
    events = EventLog(tmp_path / "events.jsonl")
    async with radar_running(tmp_path, events, frames) as profiles:
        await asyncio.sleep(RUN_S)
    events.close()
    logged = records(tmp_path, "radar_profile")
    assert len(frames) >= 15  # the emulator streamed at ~10 Hz
    assert len(logged) == profiles.written == pytest.approx((frames[-1].t_s - frames[0].t_s) / 0.5, abs=1.5)
    times_s = [r["t_s"] for r in logged]
    assert all(0.39 < b - a < 0.61 for a, b in itertools.pairwise(times_s))
    by_t = {round(f.t_s, 4): f for f in frames}
    for r in logged:
        frame = by_t[r["t_s"]]  # stamped with the frame's measurement time
        assert r["range_start_m"] == pytest.approx(frame.axis.start_m, abs=1e-4)
        assert r["range_step_m"] == pytest.approx(frame.axis.bin_m, abs=1e-4)
        expected_db = 20 * np.log10(frame.amplitude().astype(np.float64))
        np.testing.assert_allclose(r["amplitude"], expected_db, atol=0.006)
        assert -120.0 < min(r["amplitude"]) and max(r["amplitude"]) < 0.0  # 1e-4 … 1e-2 kept as dB, not rounded away
        assert max(r["amplitude"]) - np.median(r["amplitude"]) > 20.0  # the sea's echo stands out


async def test_the_camera_task_saves_downscaled_jpegs_in_its_worker_and_logs_them(
    tmp_path: Path, sock_dir: str
) -> None:
    detector = KeepingDetector()
    events = EventLog(tmp_path / "events.jsonl")
    async with camera_running(tmp_path, events, sock_dir, detector) as frame_log:
        await asyncio.sleep(RUN_S)
    events.close()
    logged = records(tmp_path, "camera")
    assert len(logged) == frame_log.saved >= 5 and frame_log.failed == 0
    assert frame_log.threads and all(name.startswith("camera.detector") for name in frame_log.threads)  # off the loop
    times_s = [r["t_s"] for r in logged]
    assert all(b - a > CAMERA_PERIOD_S - 0.07 for a, b in itertools.pairwise(times_s))  # 15 fps grid
    assert [r["jpeg"] for r in logged] == [f"camera/{k:06d}.jpg" for k in range(len(logged))]
    for r in logged:
        jpeg = cv2.imread(str(tmp_path / r["jpeg"]), cv2.IMREAD_UNCHANGED)
        assert jpeg is not None and jpeg.shape == (480, 640) and jpeg.dtype == np.uint8
        original = detector.images[r["t_s"]]  # the frame captured at the record's time
        expected = cv2.resize(original, (640, 480), interpolation=cv2.INTER_AREA)
        assert np.mean(np.abs(jpeg.astype(np.int16) - expected)) < 3.0  # that frame, not another


async def test_a_run_dir_with_both_sensors_logged_makes_a_run_mcap_with_profile_and_image(
    tmp_path: Path, sock_dir: str
) -> None:
    events = EventLog(tmp_path / "events.jsonl")
    async with radar_running(tmp_path, events, []), camera_running(tmp_path, events, sock_dir, KeepingDetector()):
        await asyncio.sleep(RUN_S)
    events.close()
    rec = read_mcap(write_mcap(tmp_path))
    profiles, images = records(tmp_path, "radar_profile"), records(tmp_path, "camera")
    assert profiles and images
    assert rec.schemas["/radar/profile"] == "seapick.RadarProfile" and rec.counts["/radar/profile"] == len(profiles)
    assert rec.schemas["/camera/image"] == "foxglove.CompressedImage" and rec.counts["/camera/image"] == len(images)
    for (t_ns, message), r in zip(rec.messages["/radar/profile"], profiles, strict=True):
        assert t_ns == time_ns(r["t_s"]) and message == {k: v for k, v in r.items() if k not in ("t_s", "kind")}
    for (t_ns, image), r in zip(rec.messages["/camera/image"], images, strict=True):
        assert t_ns == time_ns(r["t_s"]) and image.format == "jpeg"
        assert image.data == (tmp_path / r["jpeg"]).read_bytes()
