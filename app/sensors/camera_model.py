"""The pinhole camera with OpenCV lens distortion (thesis §2.3.2, eqs. 2.6–2.9).

Camera frame ``_cam``: OpenCV convention — x right in the image, y down in the image, z along the
optical axis (out of the lens). Pixels ``(u, v)``: u to the right, v down, origin at the top-left
pixel's corner as OpenCV counts it.

Only *points* are undistorted (``cv2.undistortPoints``), never whole images: a detector finds corners
in the raw image, and this model turns those pixels into rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.settings import CameraSettings

FloatArray = NDArray[np.float64]

# Points closer to the image plane than this (along z_cam) cannot be projected, m.
MIN_DEPTH_M = 1e-9


@dataclass(frozen=True, slots=True)
class CameraModel:
    """Intrinsics ``K`` (px) and OpenCV distortion ``k1 k2 p1 p2 [k3 …]`` of one camera."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    width_px: int = 1280
    height_px: int = 960

    @classmethod
    def from_settings(cls, cam: CameraSettings) -> CameraModel:
        return cls(
            fx_px=cam.fx_px,
            fy_px=cam.fy_px,
            cx_px=cam.cx_px,
            cy_px=cam.cy_px,
            distortion=tuple(float(d) for d in cam.distortion),
            width_px=cam.width_px,
            height_px=cam.height_px,
        )

    @property
    def K(self) -> FloatArray:
        """The 3×3 projection matrix of eq. 2.6."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]], dtype=np.float64
        )

    @property
    def dist_coeffs(self) -> FloatArray:
        return np.asarray(self.distortion, dtype=np.float64)

    def undistort_to_normalized(self, pixels: ArrayLike) -> FloatArray:
        """Raw (distorted) pixels N×2 → ideal normalized image coordinates ``(x/z, y/z)`` N×2."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 1, 2)
        if px.shape[0] == 0:
            return np.zeros((0, 2))
        # Iterative inverse of eq. 2.9 (OpenCV default: 5 iterations is too coarse for strong distortion).
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        xy = cv2.undistortPointsIter(px, self.K, self.dist_coeffs, np.eye(3), np.eye(3), criteria)
        return np.asarray(xy, dtype=np.float64).reshape(-1, 2)

    def undistort_to_rays(self, pixels: ArrayLike) -> FloatArray:
        """Raw pixels N×2 → unit rays in the camera frame N×3 (z > 0)."""
        xy = self.undistort_to_normalized(pixels)
        rays = np.column_stack([xy, np.ones(len(xy))])
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    def project(self, points_cam: ArrayLike) -> FloatArray:
        """Points in the camera frame N×3 (m, z > 0) → raw (distorted) pixels N×2 (eqs. 2.6 + 2.9).

        Points behind the camera (z ≤ 0) give NaN pixels.
        """
        p = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
        out = np.full((len(p), 2), np.nan)
        front = p[:, 2] > MIN_DEPTH_M
        if np.any(front):
            img, _ = cv2.projectPoints(p[front].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), self.K, self.dist_coeffs)
            out[front] = img.reshape(-1, 2)
        return out

    def in_image(self, pixels: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Which pixels N×2 fall inside the image (with ``margin_px`` kept clear of the border)."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        u, v = px[:, 0], px[:, 1]
        return (
            np.isfinite(u)
            & np.isfinite(v)
            & (u >= margin_px)
            & (v >= margin_px)
            & (u <= self.width_px - 1 - margin_px)
            & (v <= self.height_px - 1 - margin_px)
        )
