"""The pickup mission's estimates: detections → triangulation → target filter, with false-fix defences.

Inputs arrive from the sensor tasks, each stamped with the time it was *measured* (loop clock):
- vehicle samples (position and attitude) → the state history (``on_vehicle_sample``);
- the radar's height above the sea (``on_height``), or its loss (``on_radar_lost``) — these two kept, with the
  mean sea they give, by ``app.missions.vehicle_over_sea.VehicleOverSea``;
- detections at the frame's capture time: a marker's four raw corner pixels (``on_marker``), or a buoy's
  centre and diameter in raw pixels (``on_buoy``).

A detection becomes a fix only if it passes, in order (each rejection counted by reason):
1. the vehicle state at the capture time is in the history, and a fresh radar height exists;
2. the ray meets the sea (``SeaPlaneTriangulator``; 2 and 3: ``fix_checks.checked_fix``);
3. **size**: the marker's (buoy's) apparent size matches its known physical size at that range: √(measured area /
   expected area) within ``1 ± (size_tolerance + height_uncertainty_m / h)``, the expected area that of a
   level square of its edge at the fix, on the undistorted image plane (``apparent_size_ratio``: lens
   distortion and off-axis views do not bias it), h the camera's height. The range comes from the radar's
   height over the sea *under the vehicle*, which differs from the sea under the object by up to the waves'
   height — a relative error that grows as the vehicle comes down. From 10 m in sea state 2 (±0.25 m) a
   detection must be within ±17.5 % of the marker's size: a same-ID print of 0.2 m (20 px, ratio 0.67–0.73
   on rendered frames) is refused, the marker itself (0.93–1.0) is not. Where the radar measures the sea now, the
   height's bound is the local one instead (twice the fix's height σ: the sea's slope over the distance from
   under the vehicle, at least ``radar_height_std_m``; ``fix_checks.checked_fix``): with the whole wave height
   the same print passed below 3.4 m at sea state 3. A buoy is a sphere of the detector's
   ``buoy_diameter_m`` (``sphere_size_ratio``): a round bright spot of the wrong size is no buoy. With
   ``height_from_size`` (the pickup's default), a detection where the radar measures no sea now (below its first
   range, low over the object: its last height, held while the vehicle comes down, was 0.26 m high at 0.31 m and
   put fixes 6–7 cm off) is triangulated again at the height its apparent size gives, when that is the surer and
   plausible (``fix_checks.sized_height``) — and is then not held to the size check against the held height. Low
   over a trough the vehicle may be under the mean sea and yet over the water: no ray meets a sea above the
   camera, and such a detection is a fix only if its size gives the range;
4. **confirmation**: before the filter holds a lock, ``confirm_frames`` fixes within ``confirm_window_s``
   must agree within ``confirm_radius_m``, and they must be at least ``confirm_fraction`` of the frames of that
   window (M of N, as a radar tracker confirms a track); only then is the filter started (with the newest).
   Once locked, the filter's own innovation gate judges every fix; when the lock times out, confirmation
   starts over.

``snapshot`` freezes the estimate for the guards: the object predicted to now, its covariance, the fix age,
how long the filter has counted as converged (position σ ≤ ``converged_sigma_m`` without a break, on the lock that
holds now), how old that lock is (``progress['lock_age_s']``) and the
height above the sea. Pure: no asyncio, no clock reads.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from numpy.typing import ArrayLike

from app.estimators.apparent_size import (
    apparent_size_ratio,
    marker_size_rel_std,
    polygon_area,
    sphere_size_ratio,
)
from app.estimators.sea_level import MeanSeaLevel
from app.estimators.state_history import StateHistory
from app.estimators.target_filter import LinearTargetFilter
from app.estimators.triangulation import SeaPlaneFix, SeaPlaneTriangulator
from app.messages import (
    AttitudeEuler,
    PositionVelocityNed,
    TargetEstimate,
    VehicleStateNed,
)
from app.missions.estimates import Estimates, SensorHealth
from app.missions.fix_checks import FixChecks, LockConfirmation, checked_fix
from app.missions.vehicle_over_sea import VehicleOverSea

if TYPE_CHECKING:
    from app.missions.pickup_targets import SearchPattern


@dataclass(frozen=True, slots=True)
class RadarCalibrator:
    """How the mission calibrates the radar (the radar task's ``capture_background``, or the simulator's):
    ``capture(n)`` takes the background from the next ``n`` frames and raises (with the reason) when the sea is
    still in range or the frames do not come; ``max_range_m`` is the radar's last range."""

    max_range_m: float
    capture: Callable[[int], Awaitable[object]]


def largest_eigenvalue(cov: tuple[tuple[float, float], tuple[float, float]]) -> float:
    """The larger eigenvalue of a symmetric 2×2 matrix, in closed form: (a + c)/2 + √(((a − c)/2)² + b²)."""
    (a, b), (_, c) = cov
    return 0.5 * (a + c) + math.hypot(0.5 * (a - c), b)


class PickupEstimates:
    """The pickup mission's ``MissionModel``: see the module docstring."""

    def __init__(
        self,
        triangulator: SeaPlaneTriangulator,
        target_filter: LinearTargetFilter,
        checks: FixChecks | None = None,
        history: StateHistory | None = None,
        search_centre_ne_m: tuple[float, float] = (0.0, 0.0),
        sea_level: MeanSeaLevel | None = None,
    ) -> None:
        self.tri = triangulator
        self.filter = target_filter
        self.checks = checks if checks is not None else FixChecks()
        self.history = history if history is not None else StateHistory()
        self.rejected: Counter[str] = Counter()
        self.fixes = 0
        self.sized_fixes = 0  # fixes triangulated at the height their apparent size gave (``height_from_size``)
        self.sea_level = sea_level if sea_level is not None else MeanSeaLevel()
        self.over_sea = VehicleOverSea(self.checks, self.history, self.sea_level)
        if target_filter.takes_elevation:  # (the window of sea samples it needs is not kept otherwise)
            self.over_sea.on_elevation = self._on_elevation
        self._last_frame_t_s: float | None = None
        self._last_fix_t_s: float | None = None
        self.confirmation = LockConfirmation(self.checks)
        self._converged_since_s: float | None = None
        self._lock_t_s: float | None = None  # the capture time of the fix the filter's current lock began with
        # where SEARCH searches, at ``datum_t_s`` (moves to the last estimate on a loss), drifting at
        # ``search_drift_ne_mps`` from then on
        self.search_centre_ne_m = search_centre_ne_m
        self.datum_t_s: float | None = None
        self.search_drift_ne_mps: tuple[float, float] = (0.0, 0.0)
        self.last_estimate_t_s: float | None = None
        self.search: SearchPattern | None = None
        # DESCEND's final part given up (drifted off the object, or went blind off it) and not begun again: water
        # met now is no place to grab (``DescendTarget`` keeps it)
        self.final_descent_given_up = False
        self.last_estimate_ne_m: tuple[float, float] | None = None
        self.fix_times_s: deque[float] = deque(maxlen=100_000)  # capture times of the fused fixes
        # every triangulated fix past the size check: (capture t_s, north, east, what became of it), for the
        # run's log (``app.main`` drains it)
        self.fix_log: deque[tuple[float, float, float, str]] = deque(maxlen=1000)
        self._estimate_cache: tuple[tuple[float, int, float], TargetEstimate | None] | None = None
        self.grab_attempts = 0
        self.gripper_closed_t_s: float | None = None  # GRAB closed the gripper then (on the water)
        self.grab_gone_blind = False  # GRAB gave up: blind too long before the water (``grab_blind_max_s``)
        self.grab_gone_off = False  # GRAB gave up: off the estimate before the water (``grab_abort_offset_m``)
        self.searches_after_loss = 0  # SEARCH begun around the last estimate of an object seen and lost
        self.grab_ne_m: tuple[float, float] | None = None  # where the vehicle was at the last grab
        self._grab_sighting_t_s: float | None = None  # the object seen on the sea near there, last at
        self.verify_up_t_s: float | None = None  # after the grab, up at the verify height since
        self.picked_up = False
        self.radar_calibrator: RadarCalibrator | None = None  # registered by the radar task when there is one
        self.radar_calibration: str | None = None  # None while pending; "ok", "skipped: …", "failed: …"

    def footprint_m(self, height_m: float) -> float:
        """The camera footprint's narrower side on the sea from ``height_m`` (nadir view), m."""
        cam = self.tri.camera
        return height_m * min(cam.width_px / cam.fx_px, cam.height_px / cam.fy_px)

    def wide_axis_body_rad(self) -> float:
        """The direction of the image's wider side in the body (from the nose, clockwise; the mount turns it)."""
        cam = self.tri.camera
        axis = self.tri.R_frd_cam[:, 0 if cam.width_px / cam.fx_px >= cam.height_px / cam.fy_px else 1]
        return math.atan2(float(axis[1]), float(axis[0]))

    def yaw_across_lean(self, yaw_rad: float, min_tilt_rad: float) -> float | None:
        """The heading that puts the vehicle's mean lean along the image's wider side (``app.estimators.lean``);
        None in calm air."""
        return self.over_sea.lean.across_yaw_rad(self.wide_axis_body_rad(), yaw_rad, min_tilt_rad)

    def on_grab(self, vehicle_ne_m: tuple[float, float]) -> None:
        """A grab at ``vehicle_ne_m``: sightings of the object on the sea near there from now on mean it missed."""
        self.grab_attempts += 1
        self.grab_ne_m = vehicle_ne_m
        self._grab_sighting_t_s = None
        self.verify_up_t_s = None

    def set_search_datum(self, centre_ne_m: tuple[float, float], t_s: float, drift_ne_mps: tuple[float, float]) -> None:
        """The object was at ``centre_ne_m`` at ``t_s`` and drifts at ``drift_ne_mps`` (an expectation)."""
        self.search_centre_ne_m, self.datum_t_s, self.search_drift_ne_mps = centre_ne_m, t_s, drift_ne_mps

    def search_centre_at(self, t_s: float) -> tuple[float, float]:
        """Where the search centre has drifted to by ``t_s``."""
        (n, e), (vn, ve) = self.search_centre_ne_m, self.search_drift_ne_mps
        dt_s = 0.0 if self.datum_t_s is None else max(0.0, t_s - self.datum_t_s)
        return n + vn * dt_s, e + ve * dt_s

    def restart_search_at_last_estimate(self) -> None:
        """Centre the search on the object's last estimate (when it was seen), and count that search."""
        if self.last_estimate_ne_m is not None:
            self.search_centre_ne_m = self.last_estimate_ne_m
            self.datum_t_s = self.last_estimate_t_s
            self.searches_after_loss += 1

    # ---- inputs -------------------------------------------------------------------------------

    # the vehicle over the sea (``VehicleOverSea``): its samples and radar heights in, its state and heights out
    def on_vehicle_sample(self, sample: PositionVelocityNed | AttitudeEuler, received_s: float = 0.0) -> None:
        self.over_sea.on_vehicle_sample(sample, received_s)

    def on_height(self, t_s: float, height_m: float) -> None:
        self.over_sea.on_height(t_s, height_m)

    def on_radar_lost(self) -> None:
        self.over_sea.on_radar_lost()

    def height_at(self, t_s: float) -> tuple[float, float] | None:
        return self.over_sea.height_at(t_s)

    def state_at(self, t_s: float) -> VehicleStateNed | None:
        return self.over_sea.state_at(t_s)

    def height_over_mean_sea_m(self, t_s: float) -> float | None:
        return self.over_sea.height_over_mean_sea_m(t_s)

    def water_falling_mps(self, t_s: float) -> float | None:
        return self.over_sea.water_falling_mps(t_s)

    def sea_reference(self, t_s: float) -> tuple[float, float]:
        return self.over_sea.sea_reference(t_s)

    def radar_height_at(self, t_s: float) -> float | None:
        return self.over_sea.radar_height_at(t_s)

    def height_above_sea_m(self, t_s: float) -> float | None:
        return self.over_sea.height_above_sea_m(t_s)

    def latest_height_m(self) -> float | None:
        """The height above the sea at the newest camera frame, for a detector that sizes its search by it."""
        t_s = self._last_frame_t_s
        if t_s is None:
            t_s = (self.over_sea.newest_height or (0.0, 0.0))[0]
        h = self.height_at(t_s)
        return None if h is None else h[0]

    def on_frame(self, t_s: float) -> None:
        """A camera frame was processed (with or without a detection): the camera is alive."""
        self._last_frame_t_s = t_s
        self.confirmation.on_frame(t_s)

    def on_marker(self, t_s: float, corners_px: ArrayLike, size_m: float | None = None) -> bool:
        """One marker detection at capture time ``t_s``; True when it was fused into the filter. ``size_m`` is the
        physical edge of the marker the detector found (a nested one near touchdown), by default the outer one."""
        edge_m = size_m if size_m is not None else self.checks.marker_size_m
        return self._on_detection(
            t_s,
            lambda state, h_m, std_m: self.tri.fix_marker(t_s, corners_px, state, h_m, height_std_m=std_m),
            lambda fix: apparent_size_ratio(corners_px, fix, self.tri.camera, edge_m),
            marker_size_rel_std(self.tri.pixel_std_px, math.sqrt(polygon_area(corners_px))),
        )

    def on_buoy(self, t_s: float, center_px: tuple[float, float], diameter_px: float) -> bool:
        """One buoy detection (its centre and diameter in raw pixels) at capture time ``t_s``; as ``on_marker``."""
        return self._on_detection(
            t_s,
            lambda state, h_m, std_m: self.tri.fix_pixel(t_s, center_px, state, h_m, height_std_m=std_m),
            lambda fix: sphere_size_ratio(center_px, diameter_px, fix, self.tri.camera, self.checks.buoy_diameter_m),
            max(
                self.checks.buoy_diameter_rel_std, self.tri.pixel_std_px / diameter_px if diameter_px > 0 else math.inf
            ),
        )

    def _on_detection(
        self,
        t_s: float,
        triangulate: Callable[[VehicleStateNed, float, float], SeaPlaneFix | None],
        size_ratio: Callable[[SeaPlaneFix], float],
        size_rel_std: float,
    ) -> bool:
        self.on_frame(t_s)
        c = self.checks
        height = self.height_at(t_s)
        if height is None:
            return self._reject("no_height")
        height_m, height_uncertainty_m = height
        state = self.state_at(t_s)
        if state is None:
            return self._reject("no_state")
        live = self._radar_live(t_s)
        held = not live and self.radar_height_at(t_s) is not None  # (else the altitude over the mean sea, now)

        def descended_m() -> float:
            return (self.over_sea.descended_since_radar_m(t_s) or 0.0) if held else 0.0

        fix, sized = checked_fix(
            c, triangulate, size_ratio, size_rel_std, state, height_m, height_uncertainty_m, live, descended_m
        )
        if isinstance(fix, str):
            return self._reject(fix)
        self.sized_fixes += sized
        obs = fix.observation
        n_m, e_m = obs.pos_ned_m[0], obs.pos_ned_m[1]
        g, d = self.grab_ne_m, self.drifted(t_s)
        near = [] if g is None else [g] if d is None else [g, d[0]]
        if any(math.hypot(n_m - p[0], e_m - p[1]) <= c.grab_sighting_radius_m for p in near):
            # the right size, on the sea where we grabbed (or where the object would have drifted from there): the
            # grab missed it
            self._grab_sighting_t_s = t_s
        if not self.filter.initialised or self.filter.estimate(t_s) is None:
            if not self.confirmation.confirmed(obs):
                self.fix_log.append((t_s, n_m, e_m, "confirming"))
                return self._reject("confirming")
            self.filter.reset()
        inits = self.filter.counts["init"]
        result = self.filter.update(obs)
        if self.filter.counts["init"] != inits:  # a new lock (confirmed, or the filter escaped onto this fix):
            self._lock_t_s = t_s  # its convergence counts from now, not from the lock it replaced
            self._converged_since_s = None
        if not result.accepted:
            self.fix_log.append((t_s, n_m, e_m, f"filter_{result.reason}"))
            return self._reject(f"filter_{result.reason}")
        self.fix_log.append((t_s, n_m, e_m, "fused"))
        self.fixes += 1
        self._last_fix_t_s = t_s
        self.fix_times_s.append(t_s)
        return True

    def _on_elevation(self, t_s: float, elevation_m: float) -> None:
        """The sea's elevation under the vehicle: the object's too while the vehicle is right over it (within
        ``elevation_radius_m`` of the estimate; a sea-state-3 wave is ~50 m long) — to the filter."""
        est = self.estimate(t_s)
        state = self.state_at(t_s)
        if est is None or state is None:
            return
        p, o = state.pos_ned_m, est.pos_ned_m
        if math.hypot(p[0] - o[0], p[1] - o[1]) <= self.checks.elevation_radius_m:
            self.filter.update_elevation(t_s, elevation_m)

    def _radar_live(self, t_s: float) -> bool:
        """The radar measures the sea now (its newest height no older than ``radar_live_s`` at ``t_s``)."""
        return self.over_sea.height_above_sea_m(t_s) is not None

    def _reject(self, reason: str) -> bool:
        self.rejected[reason] += 1
        return False

    # ---- MissionModel ---------------------------------------------------------------------------

    def estimate(self, t_s: float) -> TargetEstimate | None:
        """The filter's estimate at ``t_s`` (memoised until the next fix: guards, guidance and the summary
        ask for the same instant several times per tick)."""
        if not self.filter.initialised:
            return None
        key = (t_s, self.fixes, self.filter.version)
        if self._estimate_cache is None or self._estimate_cache[0] != key:
            self._estimate_cache = (key, self.filter.estimate(t_s))
        return self._estimate_cache[1]

    def drifted(self, t_s: float) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """Where the object's mean drift at its last fix takes it by ``t_s``, and that drift (after the estimate
        timed out too: a missed object drifts on, with the current and pushed off by the rotors' wash)."""
        return self.filter.drifted(t_s)

    def fix_age_s(self, t_s: float) -> float | None:
        """How old the newest fused fix is at ``t_s``; None without one or once the filter's lock timed out."""
        if self._last_fix_t_s is None or self.estimate(t_s) is None:
            return None
        return t_s - self._last_fix_t_s

    def snapshot(self, t_s: float) -> Estimates:
        est = self.estimate(t_s)
        sigma_m = None
        if est is not None:
            sigma_m = math.sqrt(largest_eigenvalue(est.cov_ne_m2))
        if sigma_m is not None and sigma_m <= self.checks.converged_sigma_m:
            if self._converged_since_s is None:
                self._converged_since_s = t_s
        else:
            self._converged_since_s = None
        if est is not None:
            self.last_estimate_ne_m = (est.pos_ned_m[0], est.pos_ned_m[1])
            self.last_estimate_t_s = t_s
        centre_n_m, centre_e_m = self.search_centre_at(t_s)
        progress = {
            "search_centre_n_m": centre_n_m,
            "search_centre_e_m": centre_e_m,
            "search_done": 1.0 if self.search is not None and self.search.done(t_s) else 0.0,
            "grab_attempts": float(self.grab_attempts),
            "gripper_closed_for_s": -1.0 if self.gripper_closed_t_s is None else t_s - self.gripper_closed_t_s,
            "searches_after_loss": float(self.searches_after_loss),
            "grab_sighting_age_s": math.inf if self._grab_sighting_t_s is None else t_s - self._grab_sighting_t_s,
            "verify_up_for_s": -1.0 if self.verify_up_t_s is None else t_s - self.verify_up_t_s,
            "picked_up": 1.0 if self.picked_up else 0.0,
            "radar_calibration_done": 0.0 if self.radar_calibration is None else 1.0,
            "final_descent_given_up": 1.0 if self.final_descent_given_up else 0.0,
            "grab_gone_blind": 1.0 if self.grab_gone_blind else 0.0,
            "grab_gone_off": 1.0 if self.grab_gone_off else 0.0,
            "lock_age_s": math.inf if self._lock_t_s is None else t_s - self._lock_t_s,
        }
        falling = self.water_falling_mps(t_s)
        if falling is not None:
            progress["water_falling_mps"] = falling
        health = SensorHealth(
            camera_frame_age_s=None if self._last_frame_t_s is None else t_s - self._last_frame_t_s,
            radar_lost=self.over_sea.radar_lost,
        )
        return Estimates(
            t_s,
            target=est.as_target() if est is not None else None,
            target_cov_ne_m2=est.cov_ne_m2 if est is not None else None,
            fix_age_s=self.fix_age_s(t_s),
            converged_for_s=None if self._converged_since_s is None else t_s - self._converged_since_s,
            height_above_sea_m=self.height_above_sea_m(t_s),
            height_over_mean_sea_m=self.height_over_mean_sea_m(t_s),
            sensors=health,
            progress=progress,
        )

    def summary(self) -> dict[str, Any]:
        return {
            "picked_up": self.picked_up,
            "grab_attempts": self.grab_attempts,
            "retries": max(0, self.grab_attempts - 1),
            "searches_after_loss": self.searches_after_loss,
            "fixes": self.fixes,
            "fixes_rejected": dict(self.rejected),
            "radar_calibration": self.radar_calibration,
        }
