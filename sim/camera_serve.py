"""The simulated downward camera served like a networked camera: rendered frames over a local stream socket.

The simulator process owns the world; the app reads this socket through ``app.sensors.camera_socket`` exactly as
it would read a real networked camera, and cannot tell the difference. Wire format (frame header, pixels, the
controls request the other way): see :mod:`app.sensors.camera_socket`, which both sides import.

Transport: a Unix domain stream socket by default (``unix:/path``) — local only, guarded by file permissions, no
port to collide with, no TCP stack on a 1.2 MB frame; ``tcp://127.0.0.1:port`` works the same (port 0 picks a
free one; ``address`` then says which).

Threads. The *render* thread is the camera: capture k happens at ``t0 + k / fps_hz`` on CLOCK_MONOTONIC (the
only clock this module reads, ``time.monotonic_ns``; the same clock as the default asyncio loop's ``loop.time``
on one machine). For each capture it asks ``scene(t_s)`` for the true camera and object poses *at that instant*
(``t_s``: monotonic seconds; the callback runs in the render thread and must return a consistent snapshot),
renders with the exposure controls in effect at the start of the capture, stamps the frame with the capture
instant and offers it to every client. If rendering falls behind, the capture instants already past are skipped
(counted in ``late_captures``; they show as seq gaps). The *accept* thread takes new clients at any time.
Each client has a *sender* thread with a one-message mailbox — a newer frame replaces one not yet sent, and the
replaced one is counted in ``dropped_frames`` — so a slow or stuck client never slows rendering or the other
clients, and nothing is buffered beyond one frame per client; and a *receiver* thread that applies the
client's controls requests to later captures (the last request from any client wins) and notices the client
leaving. Ground truth (:class:`sim.camera_render.FrameTruth`) is kept for the last ``truth_kept`` captures.

Measured on the 2-core dev machine (median, 5 m above the marker): 1280×960 renders in 2.4 ms (5.1 ms with lens
distortion), 640×480 in 0.8 ms (1.3 ms). Rendering is not the bottleneck, so the default is the full resolution
(the intrinsics in the app's camera profile stay valid) at 15 Hz — what the detector uses (10–15 Hz), at half
the transfer and render load of the sensor's 30 Hz. ``scale`` renders smaller; the app then needs
:func:`scaled_camera`'s intrinsics.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import socket
import stat
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from typing import Self

from app.sensors.camera import CameraError, ExposureControls
from app.sensors.camera_socket import CONTROLS_MESSAGE, FrameHeader, SocketAddress, decode_controls, recv_exactly
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render import CameraRenderer, Conditions, FrameTruth
from sim.camera_render_source import Scene

log = logging.getLogger(__name__)

DEFAULT_FPS_HZ = 15.0  # the detector's rate; the renderer keeps up with far more (see the module docstring)
TRUTH_KEPT = 64  # captures whose ground truth is kept
ACCEPT_POLL_S = 0.1  # how often the accept thread checks for close()


def scaled_camera(camera: CameraSettings, scale: float) -> CameraSettings:
    """The same lens sampled at ``scale`` × the resolution: each pixel centre stays on its ray.

    Pixel centres are at integer coordinates, so u' = (u + ½)·s − ½; distortion (normalized) is unchanged.
    """
    w, h = round(camera.width_px * scale), round(camera.height_px * scale)
    sx, sy = w / camera.width_px, h / camera.height_px
    return CameraSettings.model_validate(
        camera.model_dump()
        | {
            "width_px": w,
            "height_px": h,
            "fx_px": camera.fx_px * sx,
            "fy_px": camera.fy_px * sy,
            "cx_px": (camera.cx_px + 0.5) * sx - 0.5,
            "cy_px": (camera.cy_px + 0.5) * sy - 0.5,
        }
    )


class CameraFrameServer:
    """Renders the camera at ``fps_hz`` and serves the frames at ``address``; ``start()``/``close()`` or ``with``."""

    def __init__(
        self,
        address: str,
        camera: CameraSettings,
        detector: DetectorSettings,
        scene: Scene,
        *,
        fps_hz: float = DEFAULT_FPS_HZ,
        scale: float = 1.0,
        seed: int = 0,
        controls: ExposureControls | None = None,
        conditions: Callable[[float], Conditions] | Conditions | None = None,
        truth_kept: int = TRUTH_KEPT,
    ) -> None:
        self.camera = camera if scale == 1.0 else scaled_camera(camera, scale)
        self.renderer = CameraRenderer(self.camera, detector, seed=seed)
        self.fps_hz = fps_hz
        self._requested = SocketAddress.parse(address)
        self._scene = scene
        self._conditions = conditions
        self._truth_kept = truth_kept
        self._lock = threading.Lock()
        self._controls = controls or ExposureControls()
        self._truth: OrderedDict[int, FrameTruth] = OrderedDict()
        self._clients: list[_Client] = []
        self._dropped_by_gone = 0
        self._sent_to_gone = 0
        self._stop = threading.Event()
        self._listener: socket.socket | None = None
        self._threads: list[threading.Thread] = []
        self.address = str(self._requested)  # with the port actually bound once started
        self.last_seq = -1  # the newest capture rendered
        self.frames_rendered = 0
        self.late_captures = 0
        self.error: BaseException | None = None  # why the render thread stopped, if it failed

    # -- state, from any thread -------------------------------------------------------------------------------

    @property
    def controls(self) -> ExposureControls:
        """The controls the next capture will use."""
        with self._lock:
            return self._controls

    @property
    def clients(self) -> int:
        with self._lock:
            return len(self._clients)

    @property
    def dropped_frames(self) -> int:
        """Frames replaced in a client's mailbox before they were sent, over all clients (past ones too)."""
        with self._lock:
            return self._dropped_by_gone + sum(c.dropped for c in self._clients)

    @property
    def sent_frames(self) -> int:
        with self._lock:
            return self._sent_to_gone + sum(c.sent for c in self._clients)

    def truth(self, seq: int) -> FrameTruth | None:
        """Ground truth of capture ``seq`` while it is among the last ``truth_kept``."""
        with self._lock:
            return self._truth.get(seq)

    # -- lifetime ---------------------------------------------------------------------------------------------

    def start(self) -> str:
        """Listen and start capturing; returns the address clients connect to."""
        if self._listener is not None:
            return self.address
        self._listener = _listen(self._requested)
        if self._requested.family == socket.AF_INET:
            host, port = self._listener.getsockname()[:2]
            self.address = str(SocketAddress(socket.AF_INET, (host, port)))
        self._threads = [
            threading.Thread(target=self._accept_loop, name="sim.camera.accept", daemon=True),
            threading.Thread(target=self._render_loop, name="sim.camera.render", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        return self.address

    def close(self) -> None:
        """Stop capturing, disconnect every client and remove the socket."""
        self._stop.set()
        for thread in self._threads:
            thread.join()
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            client.close()
        for client in clients:
            client.join()
        if self._listener is not None:
            self._listener.close()
            self._listener = None
            if isinstance(self._requested.address, str):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(self._requested.address)

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- threads ----------------------------------------------------------------------------------------------

    def _accept_loop(self) -> None:
        assert self._listener is not None
        n = 0
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            conn.settimeout(None)
            if conn.family == socket.AF_INET:
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            client = _Client(conn, f"{self.address}#{n}", self._request_controls, self._forget)
            n += 1
            with self._lock:
                self._clients.append(client)
            client.start()

    def _render_loop(self) -> None:
        period_ns = 1e9 / self.fps_hz
        t0_ns = time.monotonic_ns()
        k = 0
        try:
            while not self._stop.wait(max(0.0, (t0_ns + round(k * period_ns) - time.monotonic_ns()) * 1e-9)):
                due = math.floor((time.monotonic_ns() - t0_ns) / period_ns)  # the newest capture instant passed
                if due > k:  # fell behind: skip to it
                    self.late_captures += due - k
                    k = due
                self._capture(k, t0_ns + round(k * period_ns))
                k += 1
        except Exception as e:
            self.error = e
            log.exception("camera render failed; disconnecting the clients")
            self._stop.set()
            with self._lock:
                clients = list(self._clients)
            for client in clients:
                client.close()

    def _capture(self, seq: int, t_capture_ns: int) -> None:
        t_s = t_capture_ns * 1e-9
        controls = self.controls
        cam, obj = self._scene(t_s)
        cond = self._conditions(t_s) if callable(self._conditions) else self._conditions
        frame = self.renderer.render(t_s, cam, obj, controls, cond, frame_index=seq)
        header = FrameHeader(seq, t_capture_ns, controls, self.camera.width_px, self.camera.height_px)
        message = header.encode() + frame.image.tobytes()
        with self._lock:
            self._truth[seq] = frame.truth
            while len(self._truth) > self._truth_kept:
                self._truth.popitem(last=False)
            self.last_seq = seq
            self.frames_rendered += 1
            clients = list(self._clients)
        for client in clients:
            client.offer(message)

    def _request_controls(self, controls: ExposureControls) -> None:
        with self._lock:
            self._controls = controls

    def _forget(self, client: _Client) -> None:
        with self._lock:
            if client in self._clients:
                self._clients.remove(client)
                self._dropped_by_gone += client.dropped
                self._sent_to_gone += client.sent


class _Client:
    """One connection: a sender with a one-frame mailbox (latest wins, replaced frames counted), a receiver for
    controls requests. The receiver owns the socket: when it ends (peer gone, bad request, ``close()``) it stops
    the sender, closes the socket and tells the server."""

    def __init__(
        self,
        sock: socket.socket,
        name: str,
        on_controls: Callable[[ExposureControls], None],
        on_gone: Callable[[_Client], None],
    ) -> None:
        self.name = name
        self.sent = 0
        self.dropped = 0
        self._sock = sock
        self._on_controls = on_controls
        self._on_gone = on_gone
        self._cond = threading.Condition()
        self._pending: bytes | None = None
        self._closed = False
        self._sender = threading.Thread(target=self._send_loop, name=f"sim.camera.send[{name}]", daemon=True)
        self._receiver = threading.Thread(target=self._receive_loop, name=f"sim.camera.recv[{name}]", daemon=True)

    def start(self) -> None:
        self._sender.start()
        self._receiver.start()

    def offer(self, message: bytes) -> None:
        """Queue ``message`` for sending, replacing (and counting) one still unsent; never blocks."""
        with self._cond:
            if self._closed:
                return
            if self._pending is not None:
                self.dropped += 1
            self._pending = message
            self._cond.notify()

    def close(self) -> None:
        """Disconnect: wakes both threads (a blocked send or receive fails at once)."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify()
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_RDWR)

    def join(self) -> None:
        self._receiver.join()

    def _send_loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._closed or self._pending is not None)
                if self._closed:
                    return
                message, self._pending = self._pending, None
            assert message is not None
            try:
                self._sock.sendall(message)
            except OSError:
                self.close()  # the receiver sees the socket shut down and cleans up
                return
            self.sent += 1

    def _receive_loop(self) -> None:
        request = bytearray(CONTROLS_MESSAGE.size)
        try:
            while True:
                recv_exactly(self._sock, memoryview(request), self.name)
                self._on_controls(decode_controls(bytes(request)))
        except (CameraError, ValueError) as e:
            log.info("camera client %s leaves: %s", self.name, e)
        finally:
            self.close()
            self._sender.join()
            self._sock.close()
            self._on_gone(self)


def _listen(address: SocketAddress) -> socket.socket:
    """A listening socket at ``address``; a stale Unix socket file (nobody accepting) is replaced."""
    if isinstance(address.address, str) and _is_stale_unix_socket(address.address):
        os.unlink(address.address)
    sock = socket.socket(address.family, socket.SOCK_STREAM)
    try:
        if address.family == socket.AF_INET:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address.address)
        sock.listen()
    except OSError:
        sock.close()
        raise
    sock.settimeout(ACCEPT_POLL_S)
    return sock


def _is_stale_unix_socket(path: str) -> bool:
    try:
        if not stat.S_ISSOCK(os.stat(path).st_mode):
            return False
    except FileNotFoundError:
        return False
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        try:
            probe.connect(path)
        except ConnectionRefusedError:
            return True
    return False
