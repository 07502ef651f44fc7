"""Which way the vehicle leans on average, and the heading that puts that lean along the camera's wide axis. Pure.

A multirotor holding station in wind (or following a drifting object) leans into it: its thrust tilts upwind and
a downward camera fixed to the body looks downwind, so an object right under the vehicle sits ``lean`` degrees
off the optical axis, in the direction the vehicle leans. A 4:3 image is wider one way than the other (1280×960
at fx 1000: ±32.6° across, ±25.6° along), and in 8 m/s of wind the mean lean is 14–15°. ``MeanLean`` low-passes
the horizontal direction of the camera's axis (body z in NED) from attitude samples; ``across_yaw_rad`` is the
heading (of the two, 180° apart, the nearer to the vehicle's) that lines the image's wide axis up with it — the
idea of PX4's and ArduPilot's weathervane, turned so that the lean lies across the picture's long side rather
than along the nose. Measured at sea state 3 (``sim.evaluate --compare seapick,seapick-lean``, 200 runs each of
seeds 1 and 2): touchdown p95 0.151/0.148 m against 0.187/0.169 m with the heading held, but not fewer
off-target touchdowns (10 and 5 against 4 and 7), and the object is lost low down about as often (40 windy runs,
a 3° threshold: within 0.1 m of it, 0.30–0.45 m over the water, a marker was seen in 72 % of frames against
75 %): the swing of the lean on the waves and the vehicle's offset from the object matter more there than the
mean. So it is the mission's option (``lean_yaw_min_tilt_deg``), off by default.
"""

from __future__ import annotations

import math

from app.messages import AttitudeEuler


def camera_axis_ne(a: AttitudeEuler) -> tuple[float, float]:
    """The horizontal (north, east) part of the body's z axis in NED (ZYX Euler): where a downward camera looks;
    its length is the sine of the tilt."""
    cr, sr = math.cos(a.roll_rad), math.sin(a.roll_rad)
    sp = math.sin(a.pitch_rad)
    cy, sy = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return cy * sp * cr + sy * sr, sy * sp * cr - cy * sr


def wrap_pi(a_rad: float) -> float:
    return (a_rad + math.pi) % (2.0 * math.pi) - math.pi


class MeanLean:
    """The camera axis's horizontal direction, low-passed with time constant ``tau_s`` (the waves' orbits and the
    gusts swing the lean to and fro around the mean that the wind and the drift set)."""

    def __init__(self, tau_s: float = 5.0) -> None:
        self.tau_s = tau_s
        self.ne: tuple[float, float] | None = None
        self._t_s: float | None = None
        self._since_s: float | None = None  # the first sample of this average

    def add(self, a: AttitudeEuler) -> None:
        n, e = camera_axis_ne(a)
        if not (math.isfinite(n) and math.isfinite(e)):
            return
        if self._t_s is not None and a.t_s <= self._t_s:
            return  # an old or repeated sample
        if self.ne is None or self._t_s is None or a.t_s - self._t_s > self.tau_s:
            # the first sample, or after a gap longer than the time constant: start from this one
            self.ne, self._t_s, self._since_s = (n, e), a.t_s, a.t_s
            return
        k = 1.0 - math.exp(-(a.t_s - self._t_s) / self.tau_s)
        self.ne = (self.ne[0] + k * (n - self.ne[0]), self.ne[1] + k * (e - self.ne[1]))
        self._t_s = a.t_s

    def tilt_rad(self) -> float:
        return 0.0 if self.ne is None else math.asin(min(1.0, math.hypot(*self.ne)))

    def across_yaw_rad(self, wide_axis_body_rad: float, yaw_rad: float, min_tilt_rad: float) -> float | None:
        """The heading that puts the mean lean along the image axis at ``wide_axis_body_rad`` (from the nose,
        clockwise), the one of the two nearer to ``yaw_rad``; None before the average spans ``tau_s`` and while the
        mean lean is under ``min_tilt_rad`` (calm air: no reason to turn)."""
        if self.ne is None or self._since_s is None or self._t_s is None or self._t_s - self._since_s < self.tau_s:
            return None
        if self.tilt_rad() < min_tilt_rad:
            return None
        lean_rad = math.atan2(self.ne[1], self.ne[0])
        yaw = wrap_pi(lean_rad - wide_axis_body_rad)
        return yaw if abs(wrap_pi(yaw - yaw_rad)) <= math.pi / 2.0 else wrap_pi(yaw + math.pi)
