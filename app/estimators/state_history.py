"""Vehicle-state history: a bounded ring of telemetry, interpolated at a measurement's time. Pure.

STYLE 10 (AC_PrecLand's inertial history): a camera frame is fused against the vehicle state at its
*capture* time, not against the newest telemetry. Position and attitude arrive as separate streams at
their own rates and phases; each is kept in its own ring:

- position / velocity (NED, m, m/s): linear interpolation between the two bracketing samples;
- attitude (quaternion body FRD → NED): slerp between the two bracketing samples (no Euler wrap at ±180°).

``at(t_s)`` raises ``OutsideHistoryError`` — saying which stream and its span — when ``t_s`` is outside
the span of either stream, or falls in a telemetry gap longer than ``max_gap_s``. Samples not newer than
the newest one of their stream are dropped and counted (``dropped_out_of_order``). Oldest samples fall out
once ``capacity`` is reached.
"""

from __future__ import annotations

import bisect
import math

from app.errors import AppError
from app.estimators.rotations import quat_from_euler_zyx, quat_slerp
from app.messages import AttitudeEuler, PositionVelocityNed, VehicleStateNed

DEFAULT_CAPACITY = 256  # 5 s of 50 Hz telemetry
DEFAULT_MAX_GAP_S = 0.5  # two samples further apart than this do not bracket anything


class OutsideHistoryError(AppError):
    """Raised by ``StateHistory.at`` when ``t_s`` is outside a stream's span or inside a telemetry gap."""

    def __init__(self, stream: str, t_s: float, oldest_s: float | None, newest_s: float | None, reason: str) -> None:
        self.stream = stream
        self.t_s = t_s
        self.oldest_s = oldest_s
        self.newest_s = newest_s
        self.reason = reason
        span = "empty" if oldest_s is None else f"[{oldest_s:.3f}, {newest_s:.3f}] s"
        super().__init__(f"{stream} history cannot give t={t_s:.3f} s: {reason} (span {span})")


class _Ring:
    """Time-ordered samples (t, k values) in Python lists, the live window from ``_start`` (amortised O(1)
    append: the fallen-out front is cut off once it is as long as the window). Floats, not numpy: a bracket is
    read a few hundred times per second of flight, a handful of numbers each time."""

    def __init__(self, capacity: int) -> None:
        if capacity < 2:
            raise ValueError("capacity must be at least 2")
        self.capacity = capacity
        self._t: list[float] = []
        self._v: list[tuple[float, ...]] = []
        self._start = 0
        self.appended = 0  # samples appended so far

    def __len__(self) -> int:
        return len(self._t) - self._start

    def newest_t(self) -> float | None:
        return self._t[-1] if len(self) else None

    def oldest_t(self) -> float | None:
        return self._t[self._start] if len(self) else None

    def append(self, t_s: float, values: tuple[float, ...]) -> None:
        self._t.append(float(t_s))
        self._v.append(tuple(float(v) for v in values))
        self.appended += 1
        if len(self) > self.capacity:
            self._start += 1
            if self._start >= self.capacity:
                del self._t[: self._start], self._v[: self._start]
                self._start = 0

    def bracket(self, stream: str, t_s: float, max_gap_s: float) -> tuple[int, int, float]:
        """Indices of the samples around ``t_s`` and the fraction between them (0 at the older one)."""
        t = self._t
        if len(self) == 0 or t_s < t[self._start] or t_s > t[-1]:
            raise OutsideHistoryError(stream, t_s, self.oldest_t(), self.newest_t(), "outside the span")
        i = bisect.bisect_right(t, t_s, self._start) - 1
        if i == len(t) - 1:  # exactly the newest sample
            return i, i, 0.0
        dt = t[i + 1] - t[i]
        if dt > max_gap_s:
            raise OutsideHistoryError(
                stream, t_s, self.oldest_t(), self.newest_t(), f"in a {dt:.3f} s gap between samples"
            )
        return i, i + 1, (t_s - t[i]) / dt

    def values(self, index: int) -> tuple[float, ...]:
        return self._v[index]

    def newest_values(self) -> tuple[float, ...] | None:
        return self._v[-1] if len(self) else None


class StateHistory:
    """The last ``capacity`` position/velocity and attitude samples, interpolated on demand."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY, max_gap_s: float = DEFAULT_MAX_GAP_S) -> None:
        self.max_gap_s = max_gap_s
        self._pos_vel = _Ring(capacity)
        self._att = _Ring(capacity)
        self.dropped_out_of_order = 0
        self.dropped_non_finite = 0
        # the last answer of ``at`` and what it was read from (the time, and each stream's newest sample): asked
        # for the same instant by the guards, the guidance and the trace within one tick
        self._at_key: tuple[float, int, int] | None = None
        self._at_state: VehicleStateNed | None = None

    # -- feeding ---------------------------------------------------------------------------------

    def add_pos_vel(self, s: PositionVelocityNed) -> bool:
        """Store a position/velocity sample; False (and counted) when it is not newer than the newest or not finite."""
        if not all(map(math.isfinite, (s.t_s, *s.pos_ned_m, *s.vel_ned_mps))):
            self.dropped_non_finite += 1
            return False
        newest = self._pos_vel.newest_t()
        if newest is not None and s.t_s <= newest:
            self.dropped_out_of_order += 1
            return False
        self._pos_vel.append(s.t_s, (*s.pos_ned_m, *s.vel_ned_mps))
        return True

    def add_attitude(self, a: AttitudeEuler) -> bool:
        """Store an attitude sample; False (and counted) when it is not newer than the newest or not finite."""
        if not all(map(math.isfinite, (a.t_s, a.roll_rad, a.pitch_rad, a.yaw_rad))):
            self.dropped_non_finite += 1
            return False
        newest = self._att.newest_t()
        if newest is not None and a.t_s <= newest:
            self.dropped_out_of_order += 1
            return False
        q = quat_from_euler_zyx(a.roll_rad, a.pitch_rad, a.yaw_rad)
        prev = self._att.newest_values()
        if prev is not None and sum(x * y for x, y in zip(prev, q, strict=True)) < 0.0:  # keep the sign continuous
            q = (-q[0], -q[1], -q[2], -q[3])
        self._att.append(a.t_s, q)
        return True

    # -- reading ---------------------------------------------------------------------------------

    def span_s(self) -> tuple[float, float] | None:
        """The time span both streams cover, or None when either is empty or they do not overlap."""
        lo_p, hi_p = self._pos_vel.oldest_t(), self._pos_vel.newest_t()
        lo_a, hi_a = self._att.oldest_t(), self._att.newest_t()
        if lo_p is None or lo_a is None or hi_p is None or hi_a is None:
            return None
        lo, hi = max(lo_p, lo_a), min(hi_p, hi_a)
        return (lo, hi) if lo <= hi else None

    def at(self, t_s: float) -> VehicleStateNed:
        """The vehicle state interpolated at ``t_s``; raises ``OutsideHistoryError`` when it cannot."""
        key = (t_s, self._pos_vel.appended, self._att.appended)
        if key == self._at_key and self._at_state is not None:
            return self._at_state
        i0, i1, f = self._pos_vel.bracket("position", t_s, self.max_gap_s)
        a, b = self._pos_vel.values(i0), self._pos_vel.values(i1)
        pv = [(1.0 - f) * x + f * y for x, y in zip(a, b, strict=True)]
        j0, j1, g = self._att.bracket("attitude", t_s, self.max_gap_s)
        q = quat_slerp(self._att.values(j0), self._att.values(j1), g)
        self._at_key, self._at_state = key, VehicleStateNed(t_s, (pv[0], pv[1], pv[2]), (pv[3], pv[4], pv[5]), q)
        return self._at_state

    def latest(self) -> VehicleStateNed:
        """The newest sample of each stream as they are (no interpolation), stamped with the newer time."""
        pv = self._pos_vel.newest_values()
        q = self._att.newest_values()
        if pv is None or q is None:
            raise OutsideHistoryError("state", float("nan"), None, None, "no samples yet")
        t_s = max(self._pos_vel.newest_t() or 0.0, self._att.newest_t() or 0.0)
        return VehicleStateNed(t_s, (pv[0], pv[1], pv[2]), (pv[3], pv[4], pv[5]), (q[0], q[1], q[2], q[3]))

    def __len__(self) -> int:
        return min(len(self._pos_vel), len(self._att))
