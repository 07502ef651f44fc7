"""Where guidance takes the vehicle in the pickup mission: target sources for the setpoint loop.

- ``Transit``: straight to a point at a cruise speed (to the search area, slowing to the search speed; home,
  braking to a stop there).
- ``SearchPattern``: an expanding square around a centre at a fixed height above home; the legs are one
  camera footprint apart (less the overlap), the target point moves along them at the search speed (with its
  velocity as feed-forward), and the pattern ends at ``max_radius_m`` (the state's timeout bounds the time).
- ``ObjectTarget``: above the object's estimate at a height above the *mean* sea surface (radar heights plus
  the vehicle's altitude, ``app.estimators.sea_level``; not home, and not the swell under the vehicle: riding
  it made the vehicle pump ±1.5 m/s vertically); horizontally the object as the wave filter has it now, its
  velocity and acceleration fed forward, so guidance follows the object's wave orbit as it goes down. With no
  estimate the loop holds. ``DescendTarget`` (``app.missions.descend_target``) lowers that height.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable

from app.messages import PositionVelocityNed, TargetState, TelemetrySnapshot
from app.missions.pickup import PickupEstimates

Telemetry = Callable[[], TelemetrySnapshot]


def expanding_square(
    centre_ne_m: tuple[float, float], spacing_m: float, max_radius_m: float
) -> list[tuple[float, float]]:
    """Waypoints (NE) of an expanding square: legs of 1, 1, 2, 2, 3, 3 … spacings, turning clockwise."""
    pts = [centre_ne_m]
    n, e = centre_ne_m
    heading = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)]  # north, east, south, west
    leg, k = 1, 0
    while leg * spacing_m / 2.0 <= max_radius_m:
        for _ in range(2):
            dn, de = heading[k % 4]
            n, e = n + dn * leg * spacing_m, e + de * leg * spacing_m
            if max(abs(n - centre_ne_m[0]), abs(e - centre_ne_m[1])) > max_radius_m:
                return pts
            pts.append((n, e))
            k += 1
        leg += 1
    return pts


class DriftingPoint:
    """A point at ``down_m`` that was at ``ne_m`` at ``t0_s`` and drifts at ``drift_ne_mps`` (the search's start)."""

    def __init__(
        self, name: str, ne_m: tuple[float, float], down_m: float, t0_s: float, drift_ne_mps: tuple[float, float]
    ) -> None:
        self.name, self.ne_m, self.down_m, self.t0_s, self.drift_ne_mps = name, ne_m, down_m, t0_s, drift_ne_mps

    def target_at(self, t_s: float) -> TargetState:
        (n, e), (vn, ve) = self.ne_m, self.drift_ne_mps
        dt_s = max(0.0, t_s - self.t0_s)
        return TargetState(t_s, (n + vn * dt_s, e + ve * dt_s, self.down_m), (vn, ve, 0.0))

    def observe(self, sample: PositionVelocityNed) -> None:
        pass


CRAWL_MPS = 0.5  # a ``Transit``'s point never slower than this before its end


class Transit:
    """From ``start_ne_m`` straight to ``to_ne_m`` at ``down_m``, at up to ``speed_mps`` — as PX4's and ArduPilot's
    own returns fly at cruise speed (PX4 MPC_XY_CRUISE, 5 m/s by default), where guidance alone would close at
    its approach speed U_a,max. The target is a point that moves along the line from ``t0_s`` (its velocity fed
    forward), never more than ``leash_m`` ahead of the vehicle's own progress along it (into a strong wind the
    vehicle is slower than the point). For the end it slows down at ``brake_mps2`` (the deceleration fed forward
    too) to ``end_speed_mps``, early by as much as the vehicle is behind it (the lag of the autopilot's velocity
    loop: braking for the point alone, the vehicle came to the end at 3.6–4 m/s instead of 2), then crawls on at
    no less than ``CRAWL_MPS`` and stops there: ``end_speed_mps`` 0 to stop over home rather than overshoot it,
    the search speed where a search goes on from there (stopped first, PX4 then tilted to its limit to take the
    search up and lost the object it had just seen). The height is ``down_m`` from the start (the climb goes
    with the first metres). With ``drift_ne_mps`` the whole line drifts from ``t0_s`` on (to a search area that
    drifts with the water: ``to_ne_m`` is where it is at ``t0_s``), the drift fed forward too."""

    name = "transit"

    def __init__(
        self,
        name: str,
        start_ne_m: tuple[float, float],
        to_ne_m: tuple[float, float],
        down_m: float,
        speed_mps: float,
        brake_mps2: float,
        t0_s: float,
        leash_m: float = 3.0,
        drift_ne_mps: tuple[float, float] = (0.0, 0.0),
        end_speed_mps: float = 0.0,
    ) -> None:
        self.end_speed_mps = min(end_speed_mps, speed_mps)
        self.name, self.to_ne_m, self.down_m, self.t0_s, self.drift_ne_mps = name, to_ne_m, down_m, t0_s, drift_ne_mps
        self.speed_mps, self.brake_mps2, self.leash_m = speed_mps, brake_mps2, leash_m
        self._start = start_ne_m
        self.length_m = math.hypot(to_ne_m[0] - start_ne_m[0], to_ne_m[1] - start_ne_m[1])
        self._u = (
            (0.0, 0.0)
            if self.length_m < 1e-9
            else ((to_ne_m[0] - start_ne_m[0]) / self.length_m, (to_ne_m[1] - start_ne_m[1]) / self.length_m)
        )
        self._s_m = 0.0  # the point's progress along the line
        self._t_s = t0_s
        self._vehicle_s_m = 0.0  # the vehicle's progress along the line (its newest sample, projected)

    def target_at(self, t_s: float) -> TargetState:
        dt_s = max(0.0, t_s - self._t_s)
        self._t_s = t_s
        # v² = v_end² + 2 a d: down to the end speed at the end — for the vehicle, which is behind the point by
        # the lag of its velocity loop, so the point brakes that much earlier (and crawls on to the end)
        lag_m = min(self.leash_m, max(0.0, self._s_m - self._vehicle_s_m))
        to_go_m = max(0.0, self.length_m - self._s_m - lag_m)
        v_mps = min(self.speed_mps, math.sqrt(self.end_speed_mps**2 + 2.0 * self.brake_mps2 * to_go_m))
        v_mps = max(v_mps, min(self.speed_mps, CRAWL_MPS))
        self._s_m = min(self.length_m, self._s_m + v_mps * dt_s, max(self._s_m, self._vehicle_s_m + self.leash_m))
        if self._s_m >= self.length_m:
            v_mps = 0.0
        braking = 0.0 < v_mps < self.speed_mps
        (un, ue), a_mps2 = self._u, (-self.brake_mps2 if braking else 0.0)
        dn, de = self._drifted_m(t_s)
        n, e = self._start[0] + dn + un * self._s_m, self._start[1] + de + ue * self._s_m
        vn, ve = self.drift_ne_mps
        return TargetState(
            t_s, (n, e, self.down_m), (vn + un * v_mps, ve + ue * v_mps, 0.0), (un * a_mps2, ue * a_mps2, 0.0)
        )

    def observe(self, sample: PositionVelocityNed) -> None:
        (un, ue), p = self._u, sample.pos_ned_m
        dn, de = self._drifted_m(sample.t_s)
        self._vehicle_s_m = (p[0] - dn - self._start[0]) * un + (p[1] - de - self._start[1]) * ue

    def _drifted_m(self, t_s: float) -> tuple[float, float]:
        dt_s = max(0.0, t_s - self.t0_s)
        return self.drift_ne_mps[0] * dt_s, self.drift_ne_mps[1] * dt_s


class SearchPattern:
    """``waypoints`` (around where the centre is at ``t0_s``) flown at ``speed_mps`` from ``t0_s``, the whole
    pattern drifting at ``drift_ne_mps`` from then on with the water the object floats in."""

    name = "search"

    def __init__(
        self,
        waypoints: list[tuple[float, float]],
        altitude_down_m: float,
        speed_mps: float,
        t0_s: float,
        drift_ne_mps: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.waypoints = waypoints
        self.down_m = altitude_down_m
        self.speed_mps = speed_mps
        self.t0_s = t0_s
        self.drift_ne_mps = drift_ne_mps
        self._cum = [0.0]
        for a, b in itertools.pairwise(waypoints):
            self._cum.append(self._cum[-1] + math.hypot(b[0] - a[0], b[1] - a[1]))

    @property
    def length_m(self) -> float:
        return self._cum[-1]

    def done(self, t_s: float) -> bool:
        return (t_s - self.t0_s) * self.speed_mps >= self.length_m

    def target_at(self, t_s: float) -> TargetState:
        still = self._still_target_at(t_s)
        (vn, ve), dt_s = self.drift_ne_mps, max(0.0, t_s - self.t0_s)
        (n, e, d), (wn, we, wd) = still.pos_ned_m, still.vel_ned_mps
        return TargetState(t_s, (n + vn * dt_s, e + ve * dt_s, d), (wn + vn, we + ve, wd))

    def _still_target_at(self, t_s: float) -> TargetState:
        s = min(max(0.0, (t_s - self.t0_s) * self.speed_mps), self.length_m)
        i = max(0, min(len(self._cum) - 2, next((k for k, c in enumerate(self._cum) if c > s), len(self._cum)) - 1))
        if len(self.waypoints) < 2:
            n, e = self.waypoints[0]
            return TargetState(t_s, (n, e, self.down_m), (0.0, 0.0, 0.0))
        (n0, e0), (n1, e1) = self.waypoints[i], self.waypoints[i + 1]
        seg = max(self._cum[i + 1] - self._cum[i], 1e-9)
        f = min(1.0, (s - self._cum[i]) / seg)
        moving = s < self.length_m
        vn, ve = ((n1 - n0) / seg * self.speed_mps, (e1 - e0) / seg * self.speed_mps) if moving else (0.0, 0.0)
        return TargetState(t_s, (n0 + f * (n1 - n0), e0 + f * (e1 - e0), self.down_m), (vn, ve, 0.0))

    def observe(self, sample: PositionVelocityNed) -> None:
        pass


class ObjectTarget:
    """Above the object estimate at ``height_m`` above the sea; ``None`` (hold) without an estimate."""

    name = "object"

    def __init__(
        self, model: PickupEstimates, telemetry: Telemetry, height_m: float, lean_yaw_min_tilt_rad: float | None = None
    ) -> None:
        self.model = model
        self.telemetry = telemetry
        self.height_m = height_m
        self.lean_yaw_min_tilt_rad = lean_yaw_min_tilt_rad  # None: keep the heading

    def _sea(self, t_s: float) -> tuple[float, float]:
        """The mean sea surface (down) and its drift rate (above the radar's range: the last level it had)."""
        return self.model.sea_reference(t_s)

    def _aim(self, t_s: float, height_m: float, precise: bool = False) -> TargetState | None:
        est = self.model.estimate(t_s)  # None: no lock, or the lock timed out
        sea = self._sea(t_s)
        if est is None:
            return None
        # horizontally the object (its wave motion included); vertically a height above the *mean* sea: the
        # vehicle does not ride the swell
        (n, e, _), (vn, ve, _), (an, ae, _) = est.pos_ned_m, est.vel_ned_mps, est.acc_ned_mps2
        return TargetState(t_s, (n, e, sea[0] - height_m), (vn, ve, sea[1]), (an, ae, 0.0), self._yaw(), precise)

    def _yaw(self) -> float | None:
        """The heading that puts the mean lean along the image's wider side (``lean_yaw_min_tilt_rad`` set)."""
        if self.lean_yaw_min_tilt_rad is None:
            return None
        attitude = self.telemetry().attitude
        return None if attitude is None else self.model.yaw_across_lean(attitude.yaw_rad, self.lean_yaw_min_tilt_rad)

    def target_at(self, t_s: float) -> TargetState | None:
        return self._aim(t_s, self.height_m)

    def observe(self, sample: PositionVelocityNed) -> None:
        pass


class SinkTarget(ObjectTarget):
    """GRAB's: over the object, down from ``height_m`` at ``speed_mps`` until the water holds the vehicle up — as
    low as ``floor_m`` (below the mean sea: over a trough the water is lower than the mean; a target at the mean
    stopped the vehicle in the air over one, and the gripper closed there). Followed tightly (``precise``, as
    DESCEND's final part), its sinking speed fed forward: without it the vehicle, handed a target at its own height,
    slowed from 0.46 to 0.29 m/s on entering GRAB, and came down blind for longer."""

    name = "sink"

    def __init__(
        self, model: PickupEstimates, telemetry: Telemetry, height_m: float, speed_mps: float, floor_m: float
    ) -> None:
        super().__init__(model, telemetry, height_m)
        self.speed_mps, self.floor_m = speed_mps, floor_m
        self._t_s: float | None = None

    def target_at(self, t_s: float) -> TargetState | None:
        if self._t_s is not None:
            self.height_m = max(self.floor_m, self.height_m - self.speed_mps * max(0.0, t_s - self._t_s))
        self._t_s = t_s
        aim = self._aim(t_s, self.height_m, precise=True)
        if aim is None or self.height_m <= self.floor_m:
            return aim
        vn, ve, vd = aim.vel_ned_mps
        return dataclasses.replace(aim, vel_ned_mps=(vn, ve, vd + self.speed_mps))


class VerifyTarget(ObjectTarget):
    """After a grab: up to ``height_m`` over the sea, horizontally over the object's estimate while there is one
    (a missed object drifts on, and the camera must still have it in view to see that it missed), else where its
    last drift takes it (``PickupEstimates.drifted``: ArduCopter's takeoff from the water alone outlasts the
    estimate, and a missed object 1 m/s off was 4.5 m away, out of view, when VERIFY looked), else where the
    estimate was last (at first: ``start_ne_m``, where the grab was)."""

    name = "verify"

    def __init__(
        self, model: PickupEstimates, telemetry: Telemetry, height_m: float, start_ne_m: tuple[float, float]
    ) -> None:
        super().__init__(model, telemetry, height_m)
        self.last_ne_m = start_ne_m

    def target_at(self, t_s: float) -> TargetState:
        aim = self._aim(t_s, self.height_m)
        if aim is not None:
            self.last_ne_m = (aim.pos_ned_m[0], aim.pos_ned_m[1])
            return aim
        drifted, down_m = self.model.drifted(t_s), self._sea(t_s)[0] - self.height_m
        if drifted is not None:
            (n, e), (vn, ve) = self.last_ne_m, _ = drifted
            return TargetState(t_s, (n, e, down_m), (vn, ve, 0.0))
        return TargetState(t_s, (*self.last_ne_m, down_m), (0.0, 0.0, 0.0))
