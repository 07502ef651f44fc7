"""The pickup's defences against false fixes: the limits of its checks (``FixChecks``) and the confirmation a new
lock needs (``LockConfirmation``). What each check does and why: ``app.missions.pickup``'s docstring. Pure: no
asyncio, no clock reads.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from app.estimators.apparent_size import height_from_size
from app.estimators.triangulation import SeaPlaneFix
from app.messages import TargetObservation, VehicleStateNed

Triangulate = Callable[[VehicleStateNed, float, float], SeaPlaneFix | None]  # (state, height, its σ) → fix


@dataclass(frozen=True, slots=True)
class FixChecks:
    marker_size_m: float = 0.30  # edge of the printed marker, m
    buoy_diameter_m: float = 0.15  # a buoy's diameter (the buoy detector's), m
    size_tolerance: float = 0.15  # |√(area ratio) − 1| allowed with an exact range …
    height_uncertainty_m: float = 0.25  # … plus this over the camera's height (the waves: Hs/2)
    wave_slope: float = 0.0  # the sea's steepest slope (π Hs / L): caps how much the sea under the object differs
    radar_height_std_m: float = 0.02  # from the sea under the radar d metres away (d · slope, not below this)
    altitude_uncertainty_m: float = 0.5  # a height from the altitude over the sea reference: this much worse
    home_above_sea_m: float = 0.0  # before the radar has seen the sea: home (the deck) this far above it
    sea_level_fresh_s: float = 3.0  # the tracked mean sea counts this long after the radar's last height
    max_extrapolation_s: float = 0.1  # a frame newer than the newest vehicle sample: carried this far at its speed
    confirm_frames: int = 3  # agreeing fixes before a new lock
    confirm_window_s: float = 1.0
    confirm_radius_m: float = 0.5
    confirm_fraction: float = 0.3  # … and they are at least this share of the frames in the window (M of N)
    height_max_age_s: float = 0.5  # a radar height older than this is not used
    height_from_size: bool = False  # a detection that passed the size check measures the range to the object …
    size_model_rel_std: float = 0.02  # … as well as its size is known (print, focal length, tilt on the waves) …
    buoy_diameter_rel_std: float = 0.05  # … and a buoy's diameter is found (a marker's corners: the pixel noise),
    radar_live_s: float = 0.15  # … where the radar measures no sea now: its newest height older than this
    converged_sigma_m: float = 0.10  # filter position σ (√ of the larger eigenvalue) for "converged"
    elevation_radius_m: float = 0.5  # the sea's elevation under the vehicle is the object's this close to it
    grab_sighting_radius_m: float = 1.0  # after a grab, the object seen this close to it on the sea: missed
    water_fall_live_s: float = 0.5  # the water's fall rate the radar last saw stands this long after its newest
    # height (the mission: ``WATER_FALL_LIVE_PERIODS`` of the sea state's peak period)


# water_fall_live_s in the sea's peak periods: water falls for half a period, and the rate the radar saw stands
# while it likely still falls (sea state 3, Tp 5.6 s: 1.0 s; at 0.5 s, seed 1 run 110's touchdown came 0.75 s
# into the radar's silence over a deepening trough, and GRAB's blind sink met the water 0.27-0.33 m off the object)
WATER_FALL_LIVE_PERIODS = 0.18
SIZE_RATIO_RANGE = (1.0 / 3.0, 3.0)  # a size ratio that far off gives no height (a range wrong by 3×: no object)


def sized_height(
    camera_height_m: float,
    ratio: float,
    size_rel_std: float,
    height_std_m: float,
    descended_m: float,
    at_most: bool = False,
) -> tuple[float, float] | None:
    """The camera's height over the object from its apparent size, and its σ (``height_from_size``), for a fix
    triangulated at ``camera_height_m`` (the radar's last height, held) whose size came out ``ratio`` times the
    expected: when that is more precise than ``height_std_m`` and within ``SIZE_RATIO_RANGE`` of the held height
    carried down by the ``descended_m`` the vehicle came down since (the water under it rises and falls
    meanwhile: a reference, no more); else None. ``at_most``: the reference is only a bound from above (a height
    the uncertainty allows where the altitude over the mean sea gave none), and the size may give any lower."""
    sized_m, sized_std_m = height_from_size(camera_height_m, ratio, size_rel_std)
    reference_m = camera_height_m - max(0.0, descended_m)
    times = reference_m / max(sized_m, 1e-6)  # (no more than 3× the reference; and, unless at_most, not under a 3rd)
    plausible = SIZE_RATIO_RANGE[0] <= times and (at_most or times <= SIZE_RATIO_RANGE[1])
    return (sized_m, sized_std_m) if sized_std_m < height_std_m and plausible else None


def checked_fix(
    c: FixChecks,
    triangulate: Triangulate,
    size_ratio: Callable[[SeaPlaneFix], float],
    size_rel_std: float,
    state: VehicleStateNed,
    height_m: float,
    height_uncertainty_m: float,
    radar_live: bool,
    descended_m: Callable[[], float],
) -> tuple[SeaPlaneFix | str, bool]:
    """A detection triangulated at the height over the sea (``height_m``, uncertain by ``height_uncertainty_m``)
    and checked for size (``app.missions.pickup``'s steps 2 and 3): the fix and whether its size gave its height
    (``height_from_size``), or the reason it is refused (``no_ray``, ``size``). ``radar_live``: the radar measures
    the sea now; ``descended_m``: how far the vehicle came down since the radar's last height (when that is held)."""
    # the sea under the object differs from the height used by up to the waves: σ ≈ half that, along the ray
    height_std_m = height_uncertainty_m / 2.0
    sized_only = c.height_from_size and not radar_live and height_m < height_std_m
    if sized_only:
        # low over a trough the vehicle is under the mean sea and yet over the water (a buoy seen 0.33 m under it,
        # 0.05 m "over the mean"): no ray meets a sea at that height — triangulate at one the uncertainty allows
        # and take the fix only if its size gives the range (``sized_height``)
        height_m = height_std_m
    fix = triangulate(state, height_m, height_std_m)
    if fix is None:
        return "no_ray", False
    if c.wave_slope > 0.0 and radar_live:
        # … but by no more than the sea's slope over the distance from the radar's spot to the object: right over
        # the object (descending) the radar measures the sea the object floats on, and a fix whose covariance
        # still carried the whole wave height would be trusted ten times too little (only while it measures the
        # sea now: its last height, carried down below its first range, is as uncertain as the water's rise and
        # fall since — trusted as a live one, such fixes put the estimate 0.23 m off)
        p, o = state.pos_ned_m, fix.observation.pos_ned_m
        local_std_m = max(c.radar_height_std_m, c.wave_slope * math.hypot(o[0] - p[0], o[1] - p[1]))
        if local_std_m < height_std_m:
            fix = triangulate(state, height_m, local_std_m) or fix
            height_std_m = local_std_m
    # the size's tolerance: the range's relative error, the height's bound (2σ) over the camera's height — the
    # local one where the radar measures the sea now. With the whole wave height there, a same-ID print of
    # 0.2 m (ratio 0.67) passed below 3.4 m at sea state 3, and the filter escaped onto it, 3.6 m off the
    # marker, in the middle of a descent (seed 8 run 92 of the evaluation: the water met there)
    tolerance = c.size_tolerance + 2.0 * height_std_m / max(fix.camera_height_m, 0.1)
    ratio = size_ratio(fix)
    if c.height_from_size and not radar_live:
        # where the radar measures no sea now — below its first range (its last height, held while the vehicle
        # comes down, was 0.26 m high at 0.31 m) — the size may tell the range better (``sized_height``) …
        rel_std = math.hypot(size_rel_std, c.size_model_rel_std)
        sized_h = sized_height(fix.camera_height_m, ratio, rel_std, height_std_m, descended_m(), at_most=sized_only)
        sized = None if sized_h is None else triangulate(state, height_m + sized_h[0] - fix.camera_height_m, sized_h[1])
        if sized is not None:
            # … and then the size is what is checked against the ratio range, not against that held height: a
            # nested marker seen whole at 0.2 m was 2.6-5.9 times the area the held height gave, and refused (the
            # MAVLink pickup, seed 1: the last 0.9 s blind, 0.15 m off)
            return sized, True
    if sized_only:
        return "no_ray", False
    return (fix, False) if abs(ratio - 1.0) <= tolerance else ("size", False)


class LockConfirmation:
    """M of N before a new lock: ``confirm_frames`` fixes within ``confirm_window_s`` that agree within
    ``confirm_radius_m`` of the newest, and at least ``confirm_fraction`` of the frames of that window (as a radar
    tracker confirms a track)."""

    def __init__(self, checks: FixChecks) -> None:
        self.checks = checks
        self._candidates: deque[TargetObservation] = deque()
        self._frame_times_s: deque[float] = deque()  # capture times of the frames within the window

    def on_frame(self, t_s: float) -> None:
        """A frame captured at ``t_s`` was processed, with or without a detection."""
        frames = self._frame_times_s
        frames.append(t_s)
        while frames and t_s - frames[0] > self.checks.confirm_window_s:
            frames.popleft()

    def confirmed(self, obs: TargetObservation) -> bool:
        """Add a candidate fix; True (and the candidates cleared) when it confirms a lock."""
        c = self.checks
        self._candidates.append(obs)
        while self._candidates and obs.t_s - self._candidates[0].t_s > c.confirm_window_s:
            self._candidates.popleft()
        near = [
            o
            for o in self._candidates
            if math.hypot(o.pos_ned_m[0] - obs.pos_ned_m[0], o.pos_ned_m[1] - obs.pos_ned_m[1]) <= c.confirm_radius_m
        ]
        # M of N: a floating object in view is detected in most frames; clutter that comes and goes (glints: a
        # tenth of the frames, anywhere in view) can agree with itself by chance when the view is small — low
        # over the deck every glint lies within the confirmation radius — but not in most frames
        frames = sum(1 for t in self._frame_times_s if obs.t_s - t <= c.confirm_window_s)
        if len(near) >= c.confirm_frames and len(near) >= c.confirm_fraction * frames:
            self._candidates.clear()
            return True
        return False
