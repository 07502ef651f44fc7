"""The simulated camera served over a real socket and read by the app's networked camera: stamps, detection,
exposure round trip, latest-wins drops, bad streams and a closing server — real renderer, real sockets, real time.

Figures measured on the (busy) machine are printed (``pytest -s``); the bounds asserted are deliberately generous.
"""

from __future__ import annotations

import asyncio
import itertools
import socket
import statistics
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from app.sensors.camera import CameraError, CameraFrame, ExposureControls, ThreadedCamera
from app.sensors.camera_socket import CONTROLS_MESSAGE, FrameHeader, SocketAddress, open_socket_camera
from app.sensors.detect_marker import MarkerDetector
from app.sensors.exposure import mean_brightness
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render_poses import Pose, camera_seeing, object_pose
from sim.camera_serve import CameraFrameServer
from sim.sea import FloatingObject, SeaConfig, SeaWorld

CAMERA = CameraSettings()
MARKER = DetectorSettings()
FPS_HZ = 15.0
OBJECT = object_pose(FloatingObject(SeaWorld(SeaConfig(sea_state=2), seed=4)), 10.0, yaw_rad=0.4)
MARKER_AT_PX = (500.0, 400.0)  # where the fixed scene puts the marker (full resolution)
CAM = camera_seeing(CAMERA, OBJECT, MARKER_AT_PX, 5.0, 0.03, -0.05, 0.2)
WAIT_S = 5.0  # generous: the machine is shared


def still(t_s: float) -> tuple[Pose, Pose | None]:
    """The camera hovering still over the marker (a known pose: the marker at MARKER_AT_PX)."""
    assert CAM is not None
    return CAM, OBJECT


@pytest.fixture
def sock_dir() -> Iterator[str]:
    with tempfile.TemporaryDirectory(prefix="seapick-cam") as d:  # short: a Unix socket path has ≤ 107 bytes
        yield d


@contextmanager
def serving(address: str, **kw) -> Iterator[CameraFrameServer]:
    kw.setdefault("fps_hz", FPS_HZ)
    with CameraFrameServer(address, CAMERA, MARKER, still, seed=4, **kw) as server:
        yield server


async def next_frame(camera: ThreadedCamera) -> tuple[CameraFrame, float]:
    """The next frame and the loop time it was handed over."""
    frame = await asyncio.wait_for(camera.next_frame(), WAIT_S)
    return frame, asyncio.get_running_loop().time()


async def frame_where(camera: ThreadedCamera, wanted: Callable[[CameraFrame], bool], limit: int = 30) -> CameraFrame:
    """The first frame (of the next ``limit``) that satisfies ``wanted``."""
    for _ in range(limit):
        frame, _ = await next_frame(camera)
        if wanted(frame):
            return frame
    raise AssertionError(f"no such frame among {limit}")


@pytest.mark.parametrize("transport", ["unix", "tcp"])
async def test_frames_arrive_in_order_stamped_at_capture_one_period_apart(sock_dir: str, transport: str) -> None:
    address = f"unix:{sock_dir}/cam.sock" if transport == "unix" else "tcp://127.0.0.1:0"
    with serving(address) as server:
        async with open_socket_camera(server.address, expected_size=(1280, 960)) as camera:
            got = [await next_frame(camera) for _ in range(12)]
    frames = [f for f, _ in got]
    ages_s = [arrived - f.t_s for f, arrived in got]
    seqs = [f.seq for f in frames]
    assert seqs == sorted(set(seqs))
    assert all(0.0 < age < 1.0 for age in ages_s)  # captured before it arrived, on the same clock
    for a, b in itertools.pairwise(frames):  # stamps sit on the capture grid
        assert b.t_s - a.t_s == pytest.approx((b.seq - a.seq) / FPS_HZ, abs=1e-6)
    assert frames[-1].seq - frames[0].seq <= 2 * (len(frames) - 1)  # a reader this fast loses few frames
    assert frames[0].image.shape == (960, 1280) and frames[0].image.dtype == np.uint8
    print(
        f"\n{transport}: capture→handover median {statistics.median(ages_s) * 1e3:.1f} ms, "
        f"max {max(ages_s) * 1e3:.1f} ms; seqs {seqs}; server dropped {server.dropped_frames}, "
        f"late captures {server.late_captures}"
    )


@pytest.mark.parametrize("scale", [1.0, 0.5])
async def test_the_marker_is_detected_where_the_server_truth_puts_it(sock_dir: str, scale: float) -> None:
    with serving(f"unix:{sock_dir}/cam.sock", scale=scale) as server:
        async with open_socket_camera(server.address) as camera:
            frame, _ = await next_frame(camera)
        truth = server.truth(frame.seq)
    assert truth is not None and truth.center_px is not None and truth.corners_px is not None
    expected_px = np.multiply(np.add(MARKER_AT_PX, 0.5), scale) - 0.5  # the same ray on the scaled sensor
    assert np.hypot(*np.subtract(truth.center_px, expected_px)) < 3.0 * scale  # mean of corners ≈ centre ray
    found = MarkerDetector(MARKER, server.camera).detect(frame.image, frame.t_s)
    assert found is not None and found.marker_id == MARKER.marker_id
    assert np.hypot(*np.subtract(found.center_px, truth.center_px)) < 0.5
    assert np.max(np.linalg.norm(np.array(found.corners_px) - truth.corners_px, axis=1)) < 1.5  # 30–60 px marker


async def test_exposure_requests_round_trip_to_later_frames(sock_dir: str) -> None:
    darker = ExposureControls(32.0, 24.0)
    with serving(f"unix:{sock_dir}/cam.sock", controls=ExposureControls(10.0, 10.0)) as server:
        async with open_socket_camera(server.address, controls=ExposureControls(32.0, 48.0)) as camera:
            before = await frame_where(camera, lambda f: f.controls == ExposureControls(32.0, 48.0))  # initial request
            camera.set_controls(darker)
            frames = [(await next_frame(camera))[0] for _ in range(8)]
        assert server.controls == darker
    switched = next((i for i, f in enumerate(frames) if f.controls == darker), None)
    assert switched is not None
    assert all(f.controls == ExposureControls(32.0, 48.0) for f in frames[:switched])
    assert all(f.controls == darker for f in frames[switched:])  # and it stays
    assert frames[switched].seq > before.seq
    assert mean_brightness(frames[-1].image) < 0.7 * mean_brightness(before.image)
    print(f"\nnew controls from the {switched + 1}. frame after the request")


async def test_a_slow_consumer_gets_the_newest_frame_and_drops_are_counted(sock_dir: str) -> None:
    with serving(f"unix:{sock_dir}/cam.sock") as server:
        async with open_socket_camera(server.address) as camera:
            await next_frame(camera)
            behind = []
            frames = []
            for _ in range(4):
                await asyncio.sleep(0.3)  # ~4.5 frame periods
                newest_rendered = server.last_seq
                frame, _ = await next_frame(camera)
                behind.append(newest_rendered - frame.seq)
                frames.append(frame)
            local_dropped = camera.dropped_frames
        gaps = sum(b.seq - a.seq - 1 for a, b in itertools.pairwise(frames))
        assert gaps >= 3 * 2  # most of what was captured between reads was never handed over
        assert local_dropped >= 1
        assert local_dropped + server.dropped_frames + server.late_captures >= gaps  # every gap is accounted for
    assert all(b <= 3 for b in behind)  # the newest received frame, not an old buffered one
    print(f"\nnewest rendered − handed over: {behind}; gaps {gaps}, dropped in the app {local_dropped}")


async def test_a_client_that_never_reads_neither_slows_the_camera_nor_blocks_the_next_client(sock_dir: str) -> None:
    with serving(f"unix:{sock_dir}/cam.sock") as server:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as stuck:
            stuck.connect(SocketAddress.parse(server.address).address)
            async with open_socket_camera(server.address) as camera:
                first, _ = await next_frame(camera)
                await asyncio.sleep(1.0)
                last = await frame_where(camera, lambda f: f.seq >= server.last_seq - 1)  # caught up
            rendered = last.seq - first.seq  # ~15 captures in 1 s
            assert rendered >= 0.6 * FPS_HZ
            assert server.dropped_frames >= rendered // 2  # dropped for the stuck client, not buffered
        async with open_socket_camera(server.address) as again:  # one leaves, another connects
            frame, _ = await next_frame(again)
            assert frame.seq > last.seq
        print(f"\nrendered {rendered} in ~1 s beside a stuck client; dropped for it {server.dropped_frames}")


@contextmanager
def fake_camera(sock_dir: str, payload: bytes, *, then_close: bool) -> Iterator[str]:
    """A socket that takes its one client's controls request, sends ``payload``, then closes or stays silent."""
    path = f"{sock_dir}/fake.sock"
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen()
    done = threading.Event()

    def serve() -> None:
        conn, _ = listener.accept()
        with conn:
            conn.recv(CONTROLS_MESSAGE.size, socket.MSG_WAITALL)  # as a camera would: a close leaves nothing unread
            conn.sendall(payload)
            if not then_close:
                done.wait(WAIT_S)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"unix:{path}"
    finally:
        done.set()
        thread.join(WAIT_S)
        listener.close()


def header(width: int = 64, height: int = 48) -> bytes:
    return FrameHeader(7, time.monotonic_ns(), ExposureControls(), width, height).encode()


@pytest.mark.parametrize(
    ("payload", "then_close", "says"),
    [
        (b"GET / HTTP/1.1\r\n" * 8, True, "not a frame header"),
        (header()[:20], True, "truncated at 20/48"),
        (header() + bytes(1000), True, "truncated at 1000/3072"),
        (header() + bytes(1000), False, "no data for 0.3 s"),
        (header(width=0), True, "bad frame size"),
        (header().replace(b"\x01\x00\x01\x00", b"\x02\x00\x01\x00", 1), True, "unsupported frame version 2"),
    ],
    ids=["garbage", "cut-header", "cut-pixels", "stalled", "empty-frame", "version"],
)
async def test_a_bad_stream_is_a_camera_error_not_a_hang(
    sock_dir: str, payload: bytes, then_close: bool, says: str
) -> None:
    with fake_camera(sock_dir, payload, then_close=then_close) as address:
        async with open_socket_camera(address, read_timeout_s=0.3) as camera:
            with pytest.raises(CameraError) as err:
                await asyncio.wait_for(camera.next_frame(), WAIT_S)
    assert isinstance(err.value.__cause__, CameraError) and says in str(err.value.__cause__)


async def test_a_closed_server_makes_next_frame_raise(sock_dir: str) -> None:
    with serving(f"unix:{sock_dir}/cam.sock") as server:
        async with open_socket_camera(server.address) as camera:
            await next_frame(camera)
            t0 = time.monotonic()
            server.close()
            close_s = time.monotonic() - t0
            with pytest.raises(CameraError) as err:
                for _ in range(3):  # a frame may still be queued
                    await asyncio.wait_for(camera.next_frame(), WAIT_S)
    assert "connection closed" in str(err.value.__cause__)
    assert close_s < 2.0
    print(f"\nserver closed in {close_s * 1e3:.0f} ms")


async def test_nothing_listening_is_a_camera_error(sock_dir: str) -> None:
    async with open_socket_camera(f"unix:{sock_dir}/nobody.sock") as camera:
        with pytest.raises(CameraError) as err:
            await asyncio.wait_for(camera.next_frame(), WAIT_S)
    assert "cannot connect" in str(err.value.__cause__)


@pytest.mark.parametrize("text", ["/tmp/cam.sock", "unix:", "tcp://127.0.0.1", "tcp://:80", "udp://127.0.0.1:9"])
def test_a_bad_address_is_a_camera_error(text: str) -> None:
    with pytest.raises(CameraError):
        SocketAddress.parse(text)
