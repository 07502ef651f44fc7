"""How big an object should look in the image at a fix's range, against how big it does: the size check that
refuses a detection of the wrong physical size (``app.missions.pickup``'s defence against printed glyphs and
round bright spots), and the range that the size then measures (``height_from_size``: below the radar's first
range, the only height over the object there is). Pure geometry on the undistorted image plane."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from app.estimators.triangulation import SeaPlaneFix
from app.messages import CameraModel


def polygon_area(corners: ArrayLike) -> float:
    """Shoelace area of a quadrilateral (4×2)."""
    c = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    x, y = c[:, 0], c[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def sphere_size_ratio(
    center_px: tuple[float, float], diameter_px: float, fix: SeaPlaneFix, camera: CameraModel, diameter_m: float
) -> float:
    """Measured over expected apparent diameter of a sphere (a buoy) seen along ``fix``'s ray (1.0 = right size).

    On the undistorted image plane a small sphere of diameter D at range r, its centre β from the optical axis,
    is an ellipse D/(r cos β) across the radial direction's normal and D/(r cos² β) along it; the measured
    diameter is taken through the undistortion along both image axes, the two compared as geometric means.
    """
    u, v = center_px
    half = diameter_px / 2.0
    xy = camera.undistort_to_normalized(np.array([[u - half, v], [u + half, v], [u, v - half], [u, v + half]]))
    measured = math.sqrt(abs(float(xy[1, 0] - xy[0, 0])) * abs(float(xy[3, 1] - xy[2, 1])))
    cx, cy = camera.undistort_to_normalized(np.array([[u, v]], dtype=np.float64))[0]
    cos_beta = 1.0 / math.sqrt(1.0 + cx * cx + cy * cy)
    range_m = fix.camera_height_m / max(math.cos(fix.off_vertical_rad), 1e-6)
    expected = diameter_m / (range_m * cos_beta**1.5)
    return measured / expected if expected > 0.0 else math.inf


def apparent_size_ratio(corners_px: ArrayLike, fix: SeaPlaneFix, camera: CameraModel, size_m: float) -> float:
    """√(measured area / expected area) of a flat, level marker seen along ``fix``'s ray (1.0 = the right size).

    On the undistorted image plane (f = 1) a small patch of area A at range r, its normal at θ from the ray,
    covers A·cos θ / r² of solid angle, and the image plane holds that as A·cos θ / (r² cos³ β), β the ray's
    angle from the optical axis (with the axis vertical: (s/h)², whatever the off-nadir angle).
    """
    xy = camera.undistort_to_normalized(np.asarray(corners_px, dtype=np.float64).reshape(-1, 2))
    cx, cy = xy.mean(axis=0)
    cos_beta = 1.0 / math.sqrt(1.0 + cx * cx + cy * cy)
    cos_theta = math.cos(fix.off_vertical_rad)
    range_m = fix.camera_height_m / max(cos_theta, 1e-6)
    expected = size_m**2 * cos_theta / (range_m**2 * cos_beta**3)
    return math.sqrt(polygon_area(xy) / expected) if expected > 0.0 else math.inf


def height_from_size(camera_height_m: float, ratio: float, rel_std: float) -> tuple[float, float]:
    """The camera's height above the object and its σ, m, from a size ``ratio`` (measured over expected apparent
    size, as above) found with the ray triangulated at ``camera_height_m``: the expected size goes as 1/range and
    the range along a ray as the height, so the object is ``camera_height_m / ratio`` below the camera;
    ``rel_std`` is the size's relative σ (pixels, and how well the object's size is known)."""
    h_m = camera_height_m / ratio
    return h_m, h_m * rel_std


def marker_size_rel_std(pixel_std_px: float, edge_px: float) -> float:
    """Relative σ of a square's √area from independent corner noise σ: σ_A = σ·d (d the diagonal) for each of four
    corners moved across the other diagonal, so σ_√A/√A = σ_A/(2A) = σ/(√2·edge)."""
    return pixel_std_px / (math.sqrt(2.0) * edge_px) if edge_px > 0.0 else math.inf
