"""A networked camera: mono frames over a local stream socket, stamped at capture by the camera's side.

The simulator serves its rendered camera this way (``sim.camera_serve``); a real camera on another process of the
companion computer could too. Address: ``unix:/path/to/socket`` (Unix domain stream socket) or
``tcp://host:port``. The capture thread of :class:`app.sensors.camera.ThreadedCamera` reads the stream through
:class:`SocketGrabber` and hands the newest frame to the loop (latest wins, drops counted).

Wire format (all little-endian, version 1). Server → client, one message per frame::

    offset size  field
     0      4    magic            b"SPCF"
     4      2    version          u16 = 1
     6      2    pixel format     u16 = 1 (GREY: 8-bit mono, rows top to bottom, no padding)
     8      8    seq              u64, the camera's capture counter (gaps: frames not sent to this client)
    16      8    t_capture_ns     i64, capture instant on CLOCK_MONOTONIC (``time.monotonic_ns``), ns
    24      8    brightness       f64, controls in effect for this capture (V4L2 units)
    32      8    exposure         f64
    40      2    width            u16, px
    42      2    height           u16, px
    44      4    payload_bytes    u32 = width · height
    48      …    pixels           payload_bytes of uint8

Client → server, to request exposure controls for later captures (24 bytes)::

     0      4    magic            b"SPCC"
     4      2    version          u16 = 1
     6      2    reserved         u16 = 0
     8      8    brightness       f64
    16      8    exposure         f64

The capture stamp is CLOCK_MONOTONIC, as V4L2 stamps its buffers; ``to_loop_s`` maps it to the loop clock (the
identity on one machine when the loop runs on ``time.monotonic``, as asyncio's default loop does). A malformed
message, a connection closed mid-message or no data for ``read_timeout_s`` is a ``CameraError``: never a hang.
"""

from __future__ import annotations

import socket
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from app.sensors.camera import CameraError, ExposureControls, Image, StampedImage, StampingGrabber, ThreadedCamera

FRAME_MAGIC = b"SPCF"
CONTROLS_MAGIC = b"SPCC"
WIRE_VERSION = 1
PIXEL_FORMAT_GREY = 1
FRAME_HEADER = struct.Struct("<4sHHQqddHHI")  # 48 bytes, fields as in the module docstring
CONTROLS_MESSAGE = struct.Struct("<4sHHdd")  # 24 bytes
MAX_SIDE_PX = 4096  # as CameraSettings allows


@dataclass(frozen=True, slots=True)
class FrameHeader:
    """The fixed header in front of every frame's pixels."""

    seq: int
    t_capture_ns: int  # CLOCK_MONOTONIC
    controls: ExposureControls
    width_px: int
    height_px: int

    def encode(self) -> bytes:
        c = self.controls
        return FRAME_HEADER.pack(
            FRAME_MAGIC,
            WIRE_VERSION,
            PIXEL_FORMAT_GREY,
            self.seq,
            self.t_capture_ns,
            c.brightness,
            c.exposure,
            self.width_px,
            self.height_px,
            self.width_px * self.height_px,
        )

    @classmethod
    def decode(cls, data: bytes, source: str) -> FrameHeader:
        """Parse and check a header; ``CameraError`` naming ``source`` if it is not one."""
        magic, version, fmt, seq, t_ns, brightness, exposure, w, h, n = FRAME_HEADER.unpack(data)
        if magic != FRAME_MAGIC:
            raise CameraError(source, f"not a frame header (magic {magic!r}, want {FRAME_MAGIC!r})")
        if version != WIRE_VERSION or fmt != PIXEL_FORMAT_GREY:
            raise CameraError(source, f"unsupported frame version {version} / pixel format {fmt}")
        if not (0 < w <= MAX_SIDE_PX and 0 < h <= MAX_SIDE_PX) or n != w * h:
            raise CameraError(source, f"bad frame size {w}x{h} with {n} payload bytes")
        return cls(seq, t_ns, ExposureControls(brightness, exposure), w, h)


def encode_controls(controls: ExposureControls) -> bytes:
    return CONTROLS_MESSAGE.pack(CONTROLS_MAGIC, WIRE_VERSION, 0, controls.brightness, controls.exposure)


def decode_controls(data: bytes) -> ExposureControls:
    """Parse a controls request; ``ValueError`` if it is not one."""
    magic, version, _, brightness, exposure = CONTROLS_MESSAGE.unpack(data)
    if magic != CONTROLS_MAGIC or version != WIRE_VERSION:
        raise ValueError(f"not a controls message (magic {magic!r}, version {version})")
    return ExposureControls(brightness, exposure)


@dataclass(frozen=True, slots=True)
class SocketAddress:
    """Where a camera stream is served: ``family`` AF_UNIX with a path, or AF_INET with (host, port)."""

    family: socket.AddressFamily
    address: str | tuple[str, int]

    @classmethod
    def parse(cls, text: str) -> SocketAddress:
        """``unix:/path`` or ``tcp://host:port``; ``CameraError`` otherwise."""
        if text.startswith("unix:") and len(text) > len("unix:"):
            return cls(socket.AF_UNIX, text.removeprefix("unix:"))
        if text.startswith("tcp://"):
            host, sep, port = text.removeprefix("tcp://").rpartition(":")
            if sep and host and port.isdigit() and int(port) < 65536:
                return cls(socket.AF_INET, (host, int(port)))
        raise CameraError(text, "address must be unix:/path or tcp://host:port")

    def __str__(self) -> str:
        if isinstance(self.address, str):
            return f"unix:{self.address}"
        return f"tcp://{self.address[0]}:{self.address[1]}"


def recv_exactly(sock: socket.socket, buffer: memoryview, source: str) -> None:
    """Fill ``buffer`` from ``sock``; ``CameraError`` if the peer closes first or sends nothing for the timeout."""
    got = 0
    while got < len(buffer):
        try:
            n = sock.recv_into(buffer[got:])
        except TimeoutError as e:
            raise CameraError(source, f"no data for {sock.gettimeout()} s ({got}/{len(buffer)} bytes)") from e
        except ConnectionResetError:  # the peer closed with our request unread: a close all the same
            n = 0
        except OSError as e:
            raise CameraError(source, f"read failed: {e}") from e
        if n == 0:
            where = "between messages" if got == 0 else f"mid-message, truncated at {got}/{len(buffer)} bytes"
            raise CameraError(source, f"connection closed {where}")
        got += n


class SocketGrabber:
    """Blocking reads of the frame stream (used only by the capture thread); connects on first use."""

    def __init__(
        self,
        address: str,
        *,
        to_loop_s: Callable[[float], float] | None = None,
        expected_size: tuple[int, int] | None = None,
        connect_timeout_s: float = 2.0,
        read_timeout_s: float = 2.0,
    ) -> None:
        self.name = address
        self._address = SocketAddress.parse(address)
        self._to_loop_s = to_loop_s or (lambda t_s: t_s)
        self._expected_size = expected_size
        self._connect_timeout_s = connect_timeout_s
        self._read_timeout_s = read_timeout_s
        self._sock: socket.socket | None = None
        self._header = bytearray(FRAME_HEADER.size)

    def _connect(self) -> socket.socket:
        sock = socket.socket(self._address.family, socket.SOCK_STREAM)
        sock.settimeout(self._connect_timeout_s)
        try:
            sock.connect(self._address.address)
        except OSError as e:
            sock.close()
            raise CameraError(self.name, f"cannot connect: {e}") from e
        if self._address.family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(self._read_timeout_s)
        self._sock = sock
        return sock

    def grab_stamped(self) -> StampedImage:
        sock = self._sock or self._connect()
        recv_exactly(sock, memoryview(self._header), self.name)
        header = FrameHeader.decode(bytes(self._header), self.name)
        size = (header.width_px, header.height_px)
        if self._expected_size is not None and size != self._expected_size:
            want = "x".join(map(str, self._expected_size))
            raise CameraError(self.name, f"delivers {size[0]}x{size[1]}, settings want {want}")
        image: Image = np.empty((header.height_px, header.width_px), np.uint8)
        recv_exactly(sock, image.data.cast("B"), self.name)
        t_s = self._to_loop_s(header.t_capture_ns * 1e-9)
        return StampedImage(image=image, t_s=t_s, seq=header.seq, controls=header.controls)

    def grab(self) -> Image:
        return self.grab_stamped().image

    def apply_controls(self, controls: ExposureControls) -> None:
        sock = self._sock or self._connect()
        try:
            sock.sendall(encode_controls(controls))
        except OSError as e:
            raise CameraError(self.name, f"cannot send controls: {e}") from e

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def open_socket_camera(
    address: str,
    *,
    controls: ExposureControls | None = None,
    to_loop_s: Callable[[float], float] | None = None,
    expected_size: tuple[int, int] | None = None,
    connect_timeout_s: float = 2.0,
    read_timeout_s: float = 2.0,
) -> ThreadedCamera:
    """The networked camera at ``address`` as a ``CameraSource``; use ``async with``.

    ``to_loop_s`` maps CLOCK_MONOTONIC seconds to loop-clock seconds (default: the identity, right for the default
    event loop on the same machine); ``expected_size`` (width, height) makes another frame size a ``CameraError``.
    """
    grabber = SocketGrabber(
        address,
        to_loop_s=to_loop_s,
        expected_size=expected_size,
        connect_timeout_s=connect_timeout_s,
        read_timeout_s=read_timeout_s,
    )
    return ThreadedCamera(grabber, controls=controls)


if TYPE_CHECKING:

    def _is_a_stamping_grabber(grabber: SocketGrabber) -> StampingGrabber:
        return grabber  # mypy checks SocketGrabber against the protocol here
