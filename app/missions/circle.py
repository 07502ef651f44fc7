"""The circle mission: the target generator of thesis §5.2.2 (eqs. 5.3–5.4) and its tracking statistics.

    θ   = (t − t₀) / v_reduction                                 (5.3)
    x   = x₀ + r(−1 + cos θ),   y = y₀ + r sin θ,   z = z₀         (5.4a–c)
    v_x = −sin θ · r / v_reduction,   v_y = cos θ · r / v_reduction,   v_z = 0   (5.4d–f)

The circle starts at the vehicle's position (θ = 0 gives x = x₀, y = y₀). Tracking error is the distance
between each vehicle position sample and the target at that sample's time, counted after ``settle_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from app.messages import PositionVelocityNed, TargetState, Vec3
from app.missions.estimates import Estimates
from app.stats import percentile


@dataclass
class TrackingErrors:
    """Tracking-error samples after convergence (3-D, horizontal and vertical), metres."""

    err_m: list[float] = field(default_factory=list)
    err_horizontal_m: list[float] = field(default_factory=list)
    err_vertical_m: list[float] = field(default_factory=list)  # |down error|

    def summary(self) -> dict[str, float | int | None]:
        err, err_h, err_v = sorted(self.err_m), sorted(self.err_horizontal_m), sorted(self.err_vertical_m)
        return {
            "tracking_error_p50_m": percentile(err, 0.50),
            "tracking_error_p95_m": percentile(err, 0.95),
            "tracking_error_max_m": err[-1] if err else None,
            "tracking_error_horizontal_p50_m": percentile(err_h, 0.50),
            "tracking_error_horizontal_p95_m": percentile(err_h, 0.95),
            "tracking_error_vertical_p50_m": percentile(err_v, 0.50),
            "tracking_error_vertical_p95_m": percentile(err_v, 0.95),
            "tracking_samples": len(self.err_m),
        }


class CircleTarget:
    name = "circle"

    def __init__(
        self,
        origin_ned_m: Vec3,
        t0_s: float,
        radius_m: float,
        v_reduction_s: float,
        settle_s: float,
        errors: TrackingErrors,
    ) -> None:
        self.origin_ned_m = origin_ned_m
        self.t0_s = t0_s
        self.radius_m = radius_m
        self.v_reduction_s = v_reduction_s
        self.settle_s = settle_s
        self.errors = errors

    def theta_rad(self, t_s: float) -> float:
        # θ = t / v_reduction   (5.3)
        return max(0.0, t_s - self.t0_s) / self.v_reduction_s

    def laps(self, t_s: float) -> float:
        return self.theta_rad(t_s) / (2.0 * math.pi)

    def target_at(self, t_s: float) -> TargetState:
        th = self.theta_rad(t_s)
        r, vr = self.radius_m, self.v_reduction_s
        x0, y0, z0 = self.origin_ned_m
        # (5.4a–f)
        pos = (x0 + r * (-1.0 + math.cos(th)), y0 + r * math.sin(th), z0)
        vel = (-math.sin(th) * r / vr, math.cos(th) * r / vr, 0.0)
        # d/dt of (5.4d–e): the centripetal acceleration
        acc = (-math.cos(th) * r / vr**2, -math.sin(th) * r / vr**2, 0.0)
        return TargetState(t_s, pos, vel, acc)

    def observe(self, sample: PositionVelocityNed) -> None:
        if sample.t_s - self.t0_s < self.settle_s:
            return
        t = self.target_at(sample.t_s).pos_ned_m
        p = sample.pos_ned_m
        dn, de, dd = p[0] - t[0], p[1] - t[1], p[2] - t[2]
        self.errors.err_m.append(math.sqrt(dn * dn + de * de + dd * dd))
        self.errors.err_horizontal_m.append(math.hypot(dn, de))
        self.errors.err_vertical_m.append(abs(dd))


class CircleMission:
    """The circle mission's own state: the active target (once ``start``ed) and the tracking errors.

    Guards see ``progress["circle_laps"]`` in the snapshot; the summary carries the tracking figures."""

    def __init__(self) -> None:
        self.errors = TrackingErrors()
        self.target: CircleTarget | None = None

    def start(
        self, origin_ned_m: Vec3, t0_s: float, radius_m: float, v_reduction_s: float, settle_s: float
    ) -> CircleTarget:
        self.target = CircleTarget(origin_ned_m, t0_s, radius_m, v_reduction_s, settle_s, self.errors)
        return self.target

    def snapshot(self, t_s: float) -> Estimates:
        laps = self.target.laps(t_s) if self.target is not None else 0.0
        return Estimates(t_s, progress={"circle_laps": laps})

    def summary(self) -> dict[str, Any]:
        return dict(self.errors.summary())
