"""The radar as the rest of the app sees it: one interface and its errors (its frames, ``RadarFrame`` on a
``RangeAxis``, are in ``app.messages``).

``Radar`` is the one interface per hardware kind: the X4M03 driver (``app.sensors.x4m03_driver``)
implements it over a serial port, and the simulator's emulator speaks the same bytes on a pseudo-terminal,
so the flight code cannot tell them apart. Frames carry the loop time they were measured (``t_s``) and
their own range axis, so a consumer never guesses the geometry.
"""

from __future__ import annotations

from typing import Protocol

from app.errors import AppError
from app.messages import RadarFrame, RangeAxis


class Radar(Protocol):
    """A radar that streams frames: open and configure, stream, recover, stop."""

    @property
    def axis(self) -> RangeAxis | None:
        """The range axis the device reported (``None`` until configured)."""
        ...

    async def run(self) -> None:
        """Connect, configure and stream until cancelled, reconnecting when the device goes away."""
        ...

    async def next_frame(self) -> RadarFrame:
        """The oldest frame still queued (the queue is bounded and drops the oldest when full)."""
        ...


class RadarError(AppError):
    """Base of the radar's errors; ``port`` names the device."""

    def __init__(self, port: str, message: str) -> None:
        self.port = port
        super().__init__(f"radar {port}: {message}")


class RadarDisconnected(RadarError):
    """Raised when the port cannot be opened, or it vanishes (unplugged) while in use."""


class RadarTimeout(RadarError):
    """Raised when the device does not answer ``command`` within ``timeout_s`` (a command that arrived with
    a bad checksum is dropped silently by the firmware, so this is what a corrupted command looks like)."""

    def __init__(self, port: str, command: str, timeout_s: float) -> None:
        self.command = command
        self.timeout_s = timeout_s
        super().__init__(port, f"no answer to {command} within {timeout_s:g} s")


class RadarCommandError(RadarError):
    """Raised when the device answers ``command`` with ERROR ``code`` (``meaning`` from the x4driver codes)."""

    def __init__(self, port: str, command: str, code: int, meaning: str) -> None:
        self.command = command
        self.code = code
        self.meaning = meaning
        super().__init__(port, f"{command} refused with error {code} ({meaning})")


class RadarNotReady(RadarError):
    """Raised when the device keeps answering ping with not-ready or safe mode (``pong`` is the last value)."""

    def __init__(self, port: str, pong: int | None, timeout_s: float) -> None:
        self.pong = pong
        what = "no PONG" if pong is None else f"PONG 0x{pong:08X}"
        super().__init__(port, f"not ready after {timeout_s:g} s ({what})")
