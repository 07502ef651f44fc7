"""Small-distance geodesy (flat earth around a reference point). Pure."""

from __future__ import annotations

import math

from app.messages import Vec3

EARTH_RADIUS_M = 6_371_000.0


def ned_offset_m(from_lat_deg: float, from_lon_deg: float, from_alt_m: float,
                 to_lat_deg: float, to_lon_deg: float, to_alt_m: float) -> Vec3:  # fmt: skip
    """NED vector (m) from one global point to another, flat-earth (good to ~1e-4 relative within a few km)."""
    lat0 = math.radians(from_lat_deg)
    d_north = math.radians(to_lat_deg - from_lat_deg) * EARTH_RADIUS_M
    d_east = math.radians(to_lon_deg - from_lon_deg) * EARTH_RADIUS_M * math.cos(lat0)
    return (d_north, d_east, -(to_alt_m - from_alt_m))
