"""The X4M03 emulator driven live by the simulated vehicle: echoes from its true pose over the simulator's sea.

``live_sea_emulator(sea, truth_at)`` serves the radar on a pty (``sim.radar.RadarEmulator``) with frames from
``SeaRadarScene`` over the *same* ``SeaWorld`` the rest of the simulator uses (camera, floating object,
evaluation), and a track (``LiveTrack``) whose pose is whatever ``truth_at(t_s)`` returns, e.g. a function
reading the flight stack's truth (``truth_at_from_snapshots``).

Time base — one clock, "simulation time": ``t_sim = time.monotonic() − epoch_monotonic_s``. The emulator
runs on the wall clock from its own start (``RadarEmulator.now_s``); each frame it produces at emulator time
``t_emu`` is computed at ``t_sim = t_emu + (emulator start − epoch)``, and both the sea (η(t_sim, …)) and
``truth_at(t_sim)`` are asked at that time. Pass the simulator's epoch — ``SimAutopilot.boot_monotonic_s``,
whose ``Truth.t_s`` counts from it — so the waves under the vehicle are the waves the camera renders and the
evaluation scores. ``epoch_monotonic_s=None`` makes the emulator's own start the epoch.

A frame is measured over its sweep and sent when the sweep ends, so the scene is evaluated at the sweep's
middle, ``t_sim − sweep/2`` (sweep = iterations·pps·(dac_max − dac_min + 1)/PRF from the firmware's current
settings, 24 ms to the middle with the thesis settings): the app's driver stamps a frame "received − half the
sweep" and then looks at the same instant.

Edge cases (the emulator thread must never die): before the vehicle exists ``truth_at`` may return ``None``
(the last pose, or ``parked``, is held); a call that raises or gives a non-finite pose is counted
(``LiveTrack.failures``, ``last_error``) and the last good pose held. A vehicle on the ground or lower than
the radar's first range gets the pulse's tail in the first bins or no sea echo at all (antenna at or under
the surface): frames of direct path, body echoes and noise. A sea beyond the last range is simply absent.
The sea's frame is NED with the mean surface at down = 0: ``truth_at`` returns positions in it (an autopilot
whose local origin is elsewhere is shifted by ``origin_ned_m``).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Protocol, cast

import numpy as np

from app.messages import RangeAxis
from sim.radar import RadarEmulator
from sim.radar_firmware import FirmwareConfig, FirmwareFaults, X4M03Firmware
from sim.radar_signal import RadarSignalConfig, SeaRadarScene
from sim.radar_track import Pose, VehicleTrack
from sim.sea import SeaWorld

Vec3 = tuple[float, float, float]
PoseTuple = tuple[Vec3, float, float, float]  # (pos_ned_m, roll_rad, pitch_rad, yaw_rad)
TruthAt = Callable[[float], PoseTuple | None]  # simulation time → pose in the sea's frame, or None (no vehicle yet)
PRF_HZ = 243e6  # pulse repetition frequency before the divider (reference §10.1)
MAX_EXTRAPOLATION_S = 0.1  # a truth snapshot is carried forward (or back) by at most this much


class LiveTrack:
    """A vehicle track whose ``pose(t_s)`` comes from ``truth_at(t_s)`` (the interface ``SeaRadarScene`` uses).

    Thread-safe: the emulator's thread calls ``pose``; a bad answer never propagates, it holds the last pose.
    """

    def __init__(self, truth_at: TruthAt, parked: PoseTuple = ((0.0, 0.0, 0.0), 0.0, 0.0, 0.0)) -> None:
        """``parked``: the pose before ``truth_at`` has ever answered (default: at the origin, on the mean sea)."""
        self.truth_at = truth_at
        self.failures = 0  # calls that raised or returned a non-finite pose
        self.last_error: str | None = None
        self._last: PoseTuple = parked
        self._lock = threading.Lock()

    def pose(self, t_s: float) -> Pose:
        try:
            got = self.truth_at(t_s)
            if got is not None:
                got = _checked(got)
        except Exception as e:  # the emulator thread must survive whatever the simulator's truth does
            with self._lock:
                self.failures += 1
                self.last_error = f"{type(e).__name__}: {e}"
            got = None
        with self._lock:
            if got is not None:
                self._last = got
            (n, e_, d), roll, pitch, yaw = self._last
        return Pose(t_s, (n, e_, d), roll, pitch, yaw)


def _checked(p: PoseTuple) -> PoseTuple:
    (n, e, d), roll, pitch, yaw = p
    values = (float(n), float(e), float(d), float(roll), float(pitch), float(yaw))
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"non-finite pose {values}")
    return (values[0], values[1], values[2]), values[3], values[4], values[5]


def live_scene(
    sea: SeaWorld, truth_at: TruthAt | LiveTrack, seed: int = 0, signal: RadarSignalConfig | None = None
) -> SeaRadarScene:
    """The radar scene over ``sea`` with the vehicle at ``truth_at`` (its ``truth(t_s)`` is the height truth)."""
    track = truth_at if isinstance(truth_at, LiveTrack) else LiveTrack(truth_at)
    # SeaRadarScene only calls ``track.pose(t_s)``; it is typed with the scripted VehicleTrack.
    return SeaRadarScene(sea, cast(VehicleTrack, track), signal, seed)


def live_sea_emulator(
    sea: SeaWorld,
    truth_at: TruthAt,
    link_path: str | None = None,
    seed: int = 0,
    *,
    epoch_monotonic_s: float | None = None,
    firmware_config: FirmwareConfig | None = None,
    faults: FirmwareFaults | None = None,
    signal: RadarSignalConfig | None = None,
) -> RadarEmulator:
    """An emulator (not started: call ``start()``) whose echoes come from ``sea`` under the pose ``truth_at``.

    ``epoch_monotonic_s``: ``time.monotonic()`` at simulation time 0 (see the module docstring); ``None``: the
    emulator's own start. The scene is ``emulator.firmware.frames.scene`` (its ``truth(t_sim)``, its track).
    """
    scene = live_scene(sea, truth_at, seed, signal)
    source = _LiveFrames(scene)
    emulator = RadarEmulator(X4M03Firmware(source, firmware_config, faults, seed), link_path, seed)
    epoch = time.monotonic() if epoch_monotonic_s is None else epoch_monotonic_s
    # emulator start − epoch, from one pair of clock reads (now_s() = monotonic − emulator start)
    source.offset_s = (time.monotonic() - epoch) - emulator.now_s()
    source.firmware = emulator.firmware
    return emulator


class _LiveFrames:
    """The firmware's frame source: emulator time → simulation time at the sweep's middle → the scene's frame."""

    def __init__(self, scene: SeaRadarScene) -> None:
        self.scene = scene
        self.offset_s = 0.0
        self.firmware: X4M03Firmware | None = None

    def sim_time_s(self, t_emu_s: float) -> float:
        return t_emu_s + self.offset_s - self.half_sweep_s()

    def half_sweep_s(self) -> float:
        if self.firmware is None:
            return 0.0
        x4 = self.firmware.x4
        steps = max(1, x4.dac_max - x4.dac_min + 1)
        return 0.5 * x4.iterations * x4.pulses_per_step * steps * max(1, x4.prf_div) / PRF_HZ

    def __call__(self, t_emu_s: float, axis: RangeAxis) -> np.ndarray:
        return self.scene.baseband(self.sim_time_s(t_emu_s), axis)[0]


class TruthSnapshot(Protocol):
    """What ``truth_at_from_snapshots`` reads of ``sim.stack_types.Truth``."""

    @property
    def t_s(self) -> float: ...
    @property
    def pos_ned_m(self) -> Vec3: ...
    @property
    def vel_ned_mps(self) -> Vec3: ...
    @property
    def roll_rad(self) -> float: ...
    @property
    def pitch_rad(self) -> float: ...
    @property
    def yaw_rad(self) -> float: ...


def truth_at_from_snapshots(
    latest: Callable[[], TruthSnapshot | None], origin_ned_m: Vec3 = (0.0, 0.0, 0.0)
) -> TruthAt:
    """``truth_at`` from a live truth source such as ``SimAutopilot.truth`` (a snapshot per physics tick).

    The snapshot is carried to ``t_s`` at its velocity (at most ``MAX_EXTRAPOLATION_S``; the attitude is held)
    and shifted by ``origin_ned_m``, the autopilot's local origin in the sea's frame (e.g. (0, 0, −1.5) for a
    vehicle that boots on a deck 1.5 m above the mean sea). ``None`` until the first snapshot.
    """

    def truth_at(t_s: float) -> PoseTuple | None:
        tr = latest()
        if tr is None:
            return None
        dt_s = min(MAX_EXTRAPOLATION_S, max(-MAX_EXTRAPOLATION_S, t_s - tr.t_s))
        p, v, o = tr.pos_ned_m, tr.vel_ned_mps, origin_ned_m
        pos = (o[0] + p[0] + v[0] * dt_s, o[1] + p[1] + v[1] * dt_s, o[2] + p[2] + v[2] * dt_s)
        return pos, tr.roll_rad, tr.pitch_rad, tr.yaw_rad

    return truth_at
