"""Where the radar is: a vehicle track for the radar emulator and its data sets (pose as a function of time).

The height above the *mean* sea follows piecewise-linear waypoints ``(t_s, height_m)`` (held before the
first and after the last), plus what a multirotor holding altitude and position really does: a small
vertical wobble, a horizontal wander and roll/pitch wobble, each a seeded sum of sinusoids with the given
RMS. Deterministic for a seed; no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

_TERMS = 3


@dataclass(frozen=True, slots=True)
class Pose:
    """Vehicle reference point (NED, m; down = −height above the mean sea) and attitude (rad) at ``t_s``."""

    t_s: float
    pos_ned_m: tuple[float, float, float]
    roll_rad: float
    pitch_rad: float
    yaw_rad: float


@dataclass(frozen=True, slots=True)
class TrackConfig:
    waypoints: tuple[tuple[float, float], ...] = ((0.0, 2.0),)  # (t_s, height above mean sea m)
    north_m: float = 0.0
    east_m: float = 0.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0  # constant attitude, the wobble comes on top
    pitch_deg: float = 0.0
    height_wobble_m: float = 0.03  # RMS of the altitude-hold error
    position_wobble_m: float = 0.2  # RMS of the horizontal wander (per axis)
    tilt_wobble_deg: float = 3.0  # RMS of roll and of pitch

    def __post_init__(self) -> None:
        if not self.waypoints:
            raise ValueError("a track needs at least one waypoint")
        times = [t for t, _ in self.waypoints]
        if times != sorted(times):
            raise ValueError("waypoint times must increase")
        if min(min(self.height_wobble_m, self.position_wobble_m), self.tilt_wobble_deg) < 0.0:
            raise ValueError("wobbles are RMS values: not negative")


def hover(height_m: float, **kw: Any) -> TrackConfig:
    return TrackConfig(waypoints=((0.0, height_m),), **kw)


def calibrate_then_hover(
    calibration_height_m: float, hover_height_m: float, calibration_s: float, speed_mps: float = 1.0, **kw: Any
) -> TrackConfig:
    """Hold at ``calibration_height_m`` (sea out of range), then move at ``speed_mps`` to ``hover_height_m``."""
    travel_s = abs(calibration_height_m - hover_height_m) / speed_mps
    waypoints = (
        (0.0, calibration_height_m),
        (calibration_s, calibration_height_m),
        (calibration_s + travel_s, hover_height_m),
    )
    return TrackConfig(waypoints=waypoints, **kw)


class _Wobble:
    """A zero-mean sum of sinusoids with RMS ``rms`` and frequencies in [f_lo, f_hi] Hz."""

    def __init__(self, rng: np.random.Generator, rms: float, f_lo_hz: float, f_hi_hz: float) -> None:
        self.omega = 2.0 * math.pi * rng.uniform(f_lo_hz, f_hi_hz, _TERMS)
        self.phase = rng.uniform(0.0, 2.0 * math.pi, _TERMS)
        self.amplitude = rms * math.sqrt(2.0 / _TERMS)  # each term has RMS a/√2

    def __call__(self, t_s: float) -> float:
        return float(self.amplitude * np.sum(np.sin(self.omega * t_s + self.phase)))


class VehicleTrack:
    def __init__(self, config: TrackConfig, seed: int = 0) -> None:
        self.config = config
        rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7AC]))
        c = config
        self._t = np.array([t for t, _ in c.waypoints])
        self._h = np.array([h for _, h in c.waypoints])
        self._dz = _Wobble(rng, c.height_wobble_m, 0.1, 0.6)
        self._dn = _Wobble(rng, c.position_wobble_m, 0.03, 0.2)
        self._de = _Wobble(rng, c.position_wobble_m, 0.03, 0.2)
        tilt_rad = math.radians(c.tilt_wobble_deg)
        self._roll = _Wobble(rng, tilt_rad, 0.2, 1.5)
        self._pitch = _Wobble(rng, tilt_rad, 0.2, 1.5)

    def nominal_height_m(self, t_s: float) -> float:
        return float(np.interp(t_s, self._t, self._h))

    def pose(self, t_s: float) -> Pose:
        c = self.config
        height_m = self.nominal_height_m(t_s) + self._dz(t_s)
        return Pose(
            t_s=t_s,
            pos_ned_m=(c.north_m + self._dn(t_s), c.east_m + self._de(t_s), -height_m),
            roll_rad=math.radians(c.roll_deg) + self._roll(t_s),
            pitch_rad=math.radians(c.pitch_deg) + self._pitch(t_s),
            yaw_rad=math.radians(c.yaw_deg),
        )


def rotation_body_to_ned(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """R_nb = Rz(ψ) Ry(θ) Rx(φ) (thesis §4.2.3): body FRD vectors to NED."""
    cf, sf = math.cos(roll_rad), math.sin(roll_rad)
    ct, st = math.cos(pitch_rad), math.sin(pitch_rad)
    cp, sp = math.cos(yaw_rad), math.sin(yaw_rad)
    rz = np.array([[cp, -sp, 0.0], [sp, cp, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[ct, 0.0, st], [0.0, 1.0, 0.0], [-st, 0.0, ct]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cf, -sf], [0.0, sf, cf]])
    return rz @ ry @ rx
