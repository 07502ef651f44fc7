"""The one safety envelope every offboard setpoint passes through. Pure.

Limits, in this order:
1. horizontal speed ≤ max (direction kept), climb ≤ max, descent ≤ max;
2. geofence: outside the radius around home, the outward horizontal component is removed;
3. height: above max height no climbing; below min height no descending.
The result says which limits acted, so the event log can show why a setpoint differs from guidance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from app.messages import Vec3


@dataclass(frozen=True, slots=True)
class EnvelopeLimits:
    max_horizontal_speed_mps: float
    max_climb_speed_mps: float
    max_descent_speed_mps: float
    geofence_radius_m: float
    max_height_m: float
    min_height_m: float


@dataclass(frozen=True, slots=True)
class Clamped:
    vel_ned_mps: Vec3
    limits: tuple[str, ...]  # names of the limits that acted, empty if none


def apply_envelope(
    vel_ned_mps: Vec3, pos_ned_m: Vec3, home_ned_m: Vec3, limits: EnvelopeLimits, *, allow_below_min: bool = False
) -> Clamped:
    """Clamp a desired NED velocity to the envelope at the vehicle position ``pos_ned_m``.

    ``allow_below_min`` lifts the minimum-height rule (only for a deliberate descent to touchdown).
    """
    vn, ve, vd = vel_ned_mps
    acted: list[str] = []
    if not all(map(math.isfinite, (vn, ve, vd))):
        return Clamped((0.0, 0.0, 0.0), ("non_finite",))

    v_h = math.hypot(vn, ve)
    if v_h > limits.max_horizontal_speed_mps:
        scale = limits.max_horizontal_speed_mps / v_h
        vn, ve = vn * scale, ve * scale
        acted.append("max_horizontal_speed")
    if -vd > limits.max_climb_speed_mps:
        vd = -limits.max_climb_speed_mps
        acted.append("max_climb_speed")
    if vd > limits.max_descent_speed_mps:
        vd = limits.max_descent_speed_mps
        acted.append("max_descent_speed")

    # Geofence: remove the outward radial component outside the radius.
    dn, de = pos_ned_m[0] - home_ned_m[0], pos_ned_m[1] - home_ned_m[1]
    r_m = math.hypot(dn, de)
    if r_m > limits.geofence_radius_m:
        un, ue = dn / r_m, de / r_m
        outward = vn * un + ve * ue
        if outward > 0.0:
            vn, ve = vn - outward * un, ve - outward * ue
            acted.append("geofence")

    height_m = home_ned_m[2] - pos_ned_m[2]
    if height_m >= limits.max_height_m and vd < 0.0:
        vd = 0.0
        acted.append("max_height")
    if height_m <= limits.min_height_m and vd > 0.0 and not allow_below_min:
        vd = 0.0
        acted.append("min_height")
    return Clamped((vn, ve, vd), tuple(acted))
