"""The vehicle over the sea, for the pickup's estimates: its state history and its height above the water.

Inputs, each stamped with the time it was *measured* (loop clock): the vehicle's position and attitude samples
(``on_vehicle_sample`` → the state history) and the radar's height above the sea (``on_height``), or its loss
(``on_radar_lost``). Radar heights become samples of the mean sea surface (``app.estimators.sea_level``) once the
vehicle's altitude at their time is known. Asked: the vehicle at a frame's capture time (``state_at``, a little
past the newest sample at its speed), the height above the sea then (``height_at``: the radar's, else the
altitude over the sea reference), the radar's live height (``height_above_sea_m``) and the altitude over the
tracked mean sea (``height_over_mean_sea_m``). The limits are ``FixChecks``'. Pure: no asyncio, no clock reads.

Each sea-surface sample also gives the sea's elevation under the vehicle, up from the mean of the samples over
the last ``ELEVATION_WINDOW_S`` (two wave periods and more up to sea state 3; the tracked mean sea itself follows
a third of a sea-state-3 swell), handed to ``on_elevation`` once that window is nearly full.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

from app.estimators.lean import MeanLean
from app.estimators.sea_level import MeanSeaLevel
from app.estimators.state_history import OutsideHistoryError, StateHistory
from app.messages import AttitudeEuler, PositionVelocityNed, VehicleStateNed

if TYPE_CHECKING:
    from app.missions.fix_checks import FixChecks

ELEVATION_WINDOW_S = 12.0  # the elevation is measured from the mean sea surface over this long …
ELEVATION_MIN_SPAN_S = 10.0  # … once samples span this much of it without a gap longer than …
ELEVATION_MAX_GAP_S = 1.0  # … this


class VehicleOverSea:
    """See the module docstring; ``PickupEstimates`` owns one."""

    def __init__(self, checks: FixChecks, history: StateHistory, sea_level: MeanSeaLevel) -> None:
        self.checks = checks
        self.history = history
        self.sea_level = sea_level
        self.lean = MeanLean()  # which way the vehicle leans on average (wind, drift)
        self.radar_lost = False
        self.newest_height: tuple[float, float] | None = None  # (t_s, m)
        self._heights: deque[tuple[float, float]] = deque(maxlen=64)  # recent ones, for the height at capture time
        self._heights_to_level: deque[tuple[float, float]] = deque(maxlen=64)  # waiting for the vehicle's altitude
        self._surface: deque[tuple[float, float]] = deque()  # (t_s, sea surface down) over ELEVATION_WINDOW_S
        self._surface_sum_m = 0.0
        self.on_elevation: Callable[[float, float], None] | None = None  # (t_s, elevation m, up)

    def on_vehicle_sample(self, sample: PositionVelocityNed | AttitudeEuler, received_s: float = 0.0) -> None:
        if isinstance(sample, PositionVelocityNed):
            self.history.add_pos_vel(sample)
        else:
            self.history.add_attitude(sample)
            self.lean.add(sample)

    def on_height(self, t_s: float, height_m: float) -> None:
        if math.isfinite(t_s) and math.isfinite(height_m) and height_m > 0.0:
            if self.newest_height is None or t_s > self.newest_height[0]:
                self.newest_height = (t_s, height_m)
                self._heights.append((t_s, height_m))
                self._heights_to_level.append((t_s, height_m))
            self.radar_lost = False
        self._update_sea_level()

    def _update_sea_level(self) -> None:
        """Heights become samples of the sea surface once the vehicle's altitude at their time is known."""
        while self._heights_to_level:
            t_s, h = self._heights_to_level[0]
            try:
                state = self.history.at(t_s)
            except OutsideHistoryError as e:
                if e.newest_s is None or t_s > e.newest_s:  # the vehicle's sample after it has not arrived yet
                    return
                self._heights_to_level.popleft()
                continue
            self._heights_to_level.popleft()
            surface_down_m = state.pos_ned_m[2] + h
            self.sea_level.update(t_s, surface_down_m)
            if self.on_elevation is not None:
                self._note_surface(t_s, surface_down_m, self.on_elevation)

    def _note_surface(self, t_s: float, down_m: float, hand_on: Callable[[float, float], None]) -> None:
        """One sea-surface sample into the window; its elevation over the window's mean to ``hand_on``."""
        surface = self._surface
        if surface and (t_s <= surface[-1][0] or t_s - surface[-1][0] > ELEVATION_MAX_GAP_S):
            if t_s <= surface[-1][0]:
                return
            surface.clear()  # a gap: the mean starts over
            self._surface_sum_m = 0.0
        surface.append((t_s, down_m))
        self._surface_sum_m += down_m
        while t_s - surface[0][0] > ELEVATION_WINDOW_S:
            self._surface_sum_m -= surface.popleft()[1]
        if t_s - surface[0][0] >= ELEVATION_MIN_SPAN_S:
            hand_on(t_s, self._surface_sum_m / len(surface) - down_m)

    def height_at(self, t_s: float) -> tuple[float, float] | None:
        """The height above the sea at ``t_s`` and how uncertain it is, m: the radar's when it has one, else the
        vehicle's altitude over the sea reference (``sea_reference``: above the radar's range, e.g. searching at
        10 m with a 5 m radar), with ``altitude_uncertainty_m`` more uncertainty. None without either."""
        radar_m = self.radar_height_at(t_s)
        if radar_m is not None:
            return radar_m, self.checks.height_uncertainty_m
        state = self.state_at(t_s)
        if state is None:
            return None
        down_m = state.pos_ned_m[2]
        c = self.checks
        return self.sea_reference(t_s)[0] - down_m, c.height_uncertainty_m + c.altitude_uncertainty_m

    def state_at(self, t_s: float) -> VehicleStateNed | None:
        """The vehicle at ``t_s`` from the history; a little past its newest sample (a camera frame whose capture
        came after the last telemetry sample arrived) carried at that sample's velocity, attitude held."""
        try:
            return self.history.at(t_s)
        except OutsideHistoryError as e:
            newest_s = e.newest_s
            if newest_s is None or not 0.0 < t_s - newest_s <= self.checks.max_extrapolation_s:
                return None
        try:
            s = self.history.at(newest_s)
        except OutsideHistoryError:
            return None
        dt_s = t_s - newest_s
        p, v = s.pos_ned_m, s.vel_ned_mps
        return VehicleStateNed(t_s, (p[0] + v[0] * dt_s, p[1] + v[1] * dt_s, p[2] + v[2] * dt_s), v, s.q_ned_frd)

    def height_over_mean_sea_m(self, t_s: float) -> float | None:
        """The vehicle's altitude over the tracked mean sea, while that is fresh (``sea_level_fresh_s``)."""
        last = self.sea_level.last()
        if last is None or t_s - last.t_s > self.checks.sea_level_fresh_s:
            return None  # (before the vehicle's state: high up, out of the radar's range, it is asked at 50 Hz)
        state = self.state_at(t_s)
        if state is None:
            return None
        return last.down_m + last.rate_mps * (t_s - last.t_s) - state.pos_ned_m[2]

    def water_falling_mps(self, t_s: float) -> float | None:
        """How fast the water under the vehicle fell when the radar last saw it (m/s, down positive): its rise
        rate over the last heights, for ``FixChecks.water_fall_live_s`` after the newest; None before or after
        that."""
        last = self.sea_level.last()
        if last is None or self.radar_lost or not 0.0 <= t_s - last.t_s <= self.checks.water_fall_live_s:
            return None
        rise = self.sea_level.rise_rate_mps(last.t_s)
        return None if rise is None else -rise

    def sea_reference(self, t_s: float) -> tuple[float, float]:
        """Where the mean sea surface is (down, autopilot frame) and its drift: the tracked mean sea while radar
        heights come, the last level it had when they stop, and before any: ``home_above_sea_m`` below home."""
        est = self.sea_level.estimate(t_s)
        if est is not None:
            return est.down_m, est.rate_mps
        last = self.sea_level.last()
        return (last.down_m, 0.0) if last is not None else (self.checks.home_above_sea_m, 0.0)

    def radar_height_at(self, t_s: float) -> float | None:
        """The radar height at ``t_s`` (interpolated between the two around it; the newest if ``t_s`` is later),
        None when no height lies within ``height_max_age_s``."""
        hs = self._heights
        if not hs or self.radar_lost:
            return None
        max_age_s = self.checks.height_max_age_s
        if t_s >= hs[-1][0]:
            return hs[-1][1] if t_s - hs[-1][0] <= max_age_s else None
        for (t0, h0), (t1, h1) in zip(reversed(hs), list(reversed(hs))[1:], strict=False):
            # walking back: (t0, h0) is the later one
            if t1 <= t_s <= t0:
                if t0 - t1 > max_age_s:
                    return None
                f = (t_s - t1) / (t0 - t1) if t0 > t1 else 1.0
                return h1 + f * (h0 - h1)
        return hs[0][1] if hs[0][0] - t_s <= max_age_s else None

    def descended_since_radar_m(self, t_s: float) -> float | None:
        """How far the vehicle has come down (its altitude, from the autopilot) between the radar's newest height
        and ``t_s``, m (negative: it climbed); None without both states."""
        newest = self.newest_height
        if newest is None:
            return None
        then, now = self.state_at(newest[0]), self.state_at(t_s)
        return None if then is None or now is None else now.pos_ned_m[2] - then.pos_ned_m[2]

    def on_radar_lost(self) -> None:
        self.radar_lost = True

    def height_above_sea_m(self, t_s: float) -> float | None:
        """The radar's height while it measures the sea now: its newest, no older than ``radar_live_s`` (a frame
        and a half at 10 Hz). Below its first range, low over the water, it measures nothing, and its last height,
        held for ``height_max_age_s`` while the vehicle came down at 0.5 m/s, was up to 0.25 m high: DESCEND then
        judged the water out of reach and turned back over it, and the touchdown went unseen (README,
        *Evaluating*). The altitude over the tracked mean sea (``height_over_mean_sea_m``) stands in then."""
        h = self.newest_height
        if h is None or self.radar_lost or t_s - h[0] > self.checks.radar_live_s:
            return None
        return h[1]
