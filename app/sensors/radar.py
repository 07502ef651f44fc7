"""The radar as the rest of the app sees it: frames on a range axis, one interface, its errors. Pure data.

``Radar`` is the one interface per hardware kind: the X4M03 driver (``app.sensors.x4m03_driver``)
implements it over a serial port, and the simulator's emulator speaks the same bytes on a pseudo-terminal,
so the flight code cannot tell them apart. Frames carry the loop time they were measured (``t_s``) and
their own range axis, so a consumer never guesses the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from app.errors import AppError


@dataclass(frozen=True, slots=True)
class RangeAxis:
    """Ranges of a frame's bins: ``r[k] = start_m + k·bin_m`` for k in 0..bins−1."""

    start_m: float
    bin_m: float
    bins: int

    @property
    def end_m(self) -> float:
        return self.start_m + (self.bins - 1) * self.bin_m

    def ranges_m(self) -> np.ndarray:
        return self.start_m + self.bin_m * np.arange(self.bins)

    def bin_of(self, range_m: float) -> float:
        """Fractional bin index of ``range_m``."""
        return (range_m - self.start_m) / self.bin_m


@dataclass(frozen=True, slots=True, eq=False)
class RadarFrame:
    """One radar frame: complex baseband ``I + jQ`` per bin (the X4 sends Q negated: only the phase sign)."""

    t_s: float  # loop time the frame was measured (the driver: received minus the sweep's half)
    frame_counter: int
    axis: RangeAxis
    baseband: np.ndarray  # complex64, shape (axis.bins,)

    @staticmethod
    def from_floats(t_s: float, frame_counter: int, axis: RangeAxis, values: np.ndarray) -> RadarFrame:
        """From the DataFloat values of downconversion 1: the I block, then the Q block."""
        if values.size != 2 * axis.bins:
            raise ValueError(f"a {axis.bins}-bin baseband frame has {2 * axis.bins} floats, got {values.size}")
        baseband = (values[: axis.bins] + 1j * values[axis.bins :]).astype(np.complex64)
        return RadarFrame(t_s, frame_counter, axis, baseband)

    def amplitude(self) -> np.ndarray:
        """|I + jQ| per bin (thesis §4.2.2)."""
        return np.abs(self.baseband)


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
