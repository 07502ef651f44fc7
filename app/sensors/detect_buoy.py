"""Detection of a plain bright (yellow) buoy, after the thesis's post-processing (§5.1.4).

Per frame, in the tracking window or the whole frame:

1. binarize at ``BINARIZE_LEVEL`` of the range *above the frame's median*, 0.5 (the thesis's absolute level,
   0.3 · 255, assumed a dark sea; with auto-exposure holding the mean at 100–140 it lies below the whole sea,
   and 0.3 of the range above the median still joins the buoy to bright wave faces);
2. erode with a disc of radius 5 px (drops glints and noise), dilate with a disc of radius 10 px (fills dark
   spots on the buoy) — both shrunk when the expected buoy is so small (high up) that r = 5 would erase it;
3. drop blobs larger than 40 000 px (the thesis's pier and snow patches; here big glare and bright water) —
   unless the buoy itself is expected that large — and blobs smaller than half the expected disc;
4. a circular Hough transform on the *grey* image around each remaining blob, the radii scaled by the current
   height: r = f · (D/2) / h, searched in [0.6 r, 1.6 r] (no height: ``DEFAULT_RADII_PX``).

The strongest circle wins; its centre and radius are refined from the moments of the bright disc (the Hough
accumulator is quantized to whole pixels). The full-frame search runs steps 1–3 at half resolution (radii
halved) to keep it cheap; a tracking window runs at full resolution. No undistortion: the centre is in raw pixels.
"""

from __future__ import annotations

import cv2
import numpy as np

from app.messages import PixelDetection
from app.sensors.detect import MIN_WINDOW_PX, DetectionHint, Image, TrackingDetector, Window
from app.settings import CameraSettings, DetectorSettings

BINARIZE_LEVEL = 0.5  # of the range above the frame's median (thesis: 0.3 of full scale, on a dark sea)
ERODE_RADIUS_PX = 5
DILATE_RADIUS_PX = 10
MAX_BLOB_AREA_PX = 40_000
RADIUS_RANGE = (0.7, 1.4)  # search radii around the one the height predicts (tilt, height error)
DEFAULT_RADII_PX = (6, 120)
SEARCH_SCALE = 0.5
MAX_CANDIDATES = 8  # blobs handed to the Hough transform per frame


def _disc(radius_px: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1, 2 * radius_px + 1))


class BuoyDetector(TrackingDetector):
    """The buoy detector behind :class:`app.sensors.detect.Detector`."""

    def __init__(self, settings: DetectorSettings, camera: CameraSettings | None = None) -> None:
        super().__init__()
        self.settings = settings
        self.camera = camera or CameraSettings()

    def expected_radius_px(self, height_m: float) -> float:
        """r = f · (D/2) / h: the buoy's radius on the image from ``height_m`` above it."""
        return self.camera.fx_px * self.settings.buoy_diameter_m / 2 / max(height_m, 1e-3)

    def detect(
        self, image: Image, t_s: float, hint: DetectionHint | None = None, height_m: float | None = None
    ) -> PixelDetection | None:
        if height_m is not None:
            r = self.expected_radius_px(height_m)
            radii = (max(2, round(r * RADIUS_RANGE[0])), max(4, round(r * RADIUS_RANGE[1])))
        else:
            radii = DEFAULT_RADII_PX
        hint = hint or self._track.hint(t_s)
        found = None
        if hint is not None:
            side = max(2 * (self.settings.roi_margin * hint.size_px + hint.radius_px), MIN_WINDOW_PX)
            win = Window.around(hint.center_px, side, image.shape[1], image.shape[0])
            if not win.empty:
                found = self._find(image, win, 1.0, radii, t_s, tracked=True)
                self._last_pass = "track"
        if found is None:
            win = Window(0, 0, image.shape[1], image.shape[0])
            found = self._find(image, win, SEARCH_SCALE, radii, t_s, tracked=False)
            self._last_pass = "search_reduced" if found is not None else "none"
        self._track.update(found)
        return found

    def _find(
        self, image: Image, win: Window, scale: float, radii: tuple[int, int], t_s: float, *, tracked: bool
    ) -> PixelDetection | None:
        crop = image[win.y0 : win.y1, win.x0 : win.x1]
        small = crop if scale == 1.0 else cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        median = float(np.median(small[::4, ::4]))
        level = median + BINARIZE_LEVEL * (255.0 - median)
        _, binary = cv2.threshold(small, level, 255, cv2.THRESH_BINARY)
        # the thesis's 5/10 px discs, shrunk for a buoy so small (high up) that r = 5 would erase it
        erode_px = min(float(ERODE_RADIUS_PX), 0.5 * radii[0] / RADIUS_RANGE[0])
        binary = cv2.erode(binary, _disc(max(1, round(erode_px * scale))))
        binary = cv2.dilate(binary, _disc(max(1, round(2 * erode_px * scale))))
        n, _, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
        # a disc of radius r, eroded and dilated, covers about π (r + e)²; blobs below half the smallest expected
        # disc are not it, and the thesis's 40 000 px cap is raised when the buoy itself is that big (below ~1 m)
        expected_area = np.pi * ((radii[0] + radii[1]) / 2 + erode_px) ** 2
        min_area = 0.5 * np.pi * radii[0] ** 2
        max_area = max(MAX_BLOB_AREA_PX, 3.0 * np.pi * (radii[1] + erode_px) ** 2)
        blobs = [tuple(int(v) for v in stats[i]) for i in range(1, n)]
        blobs = [b for b in blobs if min_area <= b[4] / (scale * scale) <= max_area]
        # the Hough transform is the costly step: try the blobs closest to the expected size first, a few only
        blobs.sort(key=lambda b: abs(np.log(b[4] / (scale * scale) / expected_area)))
        best: tuple[float, float, float, float] | None = None  # contrast, x, y, r (full-res crop pixels)
        for x, y, w, h, _ in blobs[:MAX_CANDIDATES]:
            # back to full resolution, padded by the largest radius
            pad = radii[1]
            x0, y0 = max(int(x / scale) - pad, 0), max(int(y / scale) - pad, 0)
            x1, y1 = min(int((x + w) / scale) + pad, crop.shape[1]), min(int((y + h) / scale) + pad, crop.shape[0])
            # the image's own edges in the patch's pixels: a disc cut by them is fitted on its visible rim
            ox, oy = win.x0 + x0, win.y0 + y0
            edges = (-ox, -oy, image.shape[1] - 1 - ox, image.shape[0] - 1 - oy)
            circle = self._hough(crop[y0:y1, x0:x1], radii, edges)
            if circle is not None and (best is None or circle[0] > best[0]):
                best = (circle[0], circle[1] + x0, circle[2] + y0, circle[3])
        if best is None:
            return None
        _, cx, cy, r = best
        return PixelDetection(
            t_s=t_s,
            center_px=(cx + win.x0, cy + win.y0),
            corners_px=(),
            size_px=2.0 * r,
            size_m=self.settings.buoy_diameter_m,
            marker_id=-1,
            tracked=tracked,
        )

    @staticmethod
    def _hough(
        patch: Image, radii: tuple[int, int], edges: tuple[int, int, int, int]
    ) -> tuple[float, float, float, float] | None:
        """The strongest bright circle in ``patch``: (quality, x, y, r), or None. ``edges``: the image's left,
        top, right and bottom pixel in the patch's coordinates."""
        if min(patch.shape) < 2 * radii[0] + 2:
            return None
        circles = cv2.HoughCircles(
            cv2.GaussianBlur(patch, (3, 3), 0.8),
            cv2.HOUGH_GRADIENT_ALT,
            dp=1.0,
            minDist=float(radii[0]),
            param1=150,
            param2=0.8,
            minRadius=radii[0],
            maxRadius=radii[1],
        )
        if circles is None:
            return None
        # HOUGH_GRADIENT_ALT returns the circles best first; check polarity: brighter inside than around
        for x, y, r in circles.reshape(-1, 3)[:3]:
            inner = _ring_mean(patch, x, y, 0.0, 0.7 * r)
            outer = _ring_mean(patch, x, y, 1.3 * r, 1.8 * r)
            if inner > outer + 20.0:
                cx, cy, radius = _refine(patch, float(x), float(y), float(r), 0.5 * (inner + outer), edges)
                return (float(inner - outer), cx, cy, radius)
        return None


def _refine(
    patch: Image, x: float, y: float, r: float, level: float, edges: tuple[int, int, int, int]
) -> tuple[float, float, float]:
    """Sub-pixel centre and radius: the centroid and area of the bright disc near the Hough circle.

    The Hough accumulator is quantized to whole pixels; the disc's moments are not. A disc cut by the image's
    edge (``edges``: its left, top, right, bottom pixel in the patch), as the buoy is low over it, would pull the
    centroid inwards and shrink the radius (by 0.064 of the diameter with a fifth of it outside): its centre and
    radius come from a circle fitted to the rim that is in the image instead.
    """
    x0, y0 = max(int(x - 1.3 * r), 0), max(int(y - 1.3 * r), 0)
    x1, y1 = min(int(x + 1.3 * r) + 2, patch.shape[1]), min(int(y + 1.3 * r) + 2, patch.shape[0])
    window = patch[y0:y1, x0:x1]
    yy, xx = np.ogrid[y0:y1, x0:x1]
    near = (xx - x) ** 2 + (yy - y) ** 2 <= (1.25 * r) ** 2
    disc = ((window >= level) & near).astype(np.uint8)
    left, top, right, bottom = edges[0] - x0, edges[1] - y0, edges[2] - x0, edges[3] - y0  # in the window
    rows, cols = disc.shape
    cut = (
        (0 <= left < cols and disc[:, left].any())
        or (0 <= right < cols and disc[:, right].any())
        or (0 <= top < rows and disc[top, :].any())
        or (0 <= bottom < rows and disc[bottom, :].any())
    )
    if cut:
        rim = _rim_circle(disc, (left, top, right, bottom), r)
        if rim is not None:
            return x0 + rim[0], y0 + rim[1], rim[2]
    m = cv2.moments(disc, binaryImage=True)
    if m["m00"] < (0.25 if cut else 0.5) * np.pi * r * r:
        return x, y, r  # not a clean disc: keep the Hough circle
    return x0 + m["m10"] / m["m00"], y0 + m["m01"] / m["m00"], float(np.sqrt(m["m00"] / np.pi))


RIM_MIN_FRACTION = 0.3  # of the circumference in the image, for a circle fitted to the rim alone


def _rim_circle(disc: np.ndarray, edges: tuple[int, int, int, int], r: float) -> tuple[float, float, float] | None:
    """A circle fitted (algebraic least squares, Kåsa) to the outline of the disc mask, leaving out the outline
    that runs along the image's edges; None when too little rim is left."""
    contours, _ = cv2.findContours(disc, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    pts = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(np.float64)
    left, top, right, bottom = edges
    x, y = pts[:, 0], pts[:, 1]
    keep = (np.abs(x - left) > 1.5) & (np.abs(x - right) > 1.5) & (np.abs(y - top) > 1.5) & (np.abs(y - bottom) > 1.5)
    x, y = x[keep], y[keep]
    if x.size < RIM_MIN_FRACTION * 2.0 * np.pi * r:
        return None
    A = np.column_stack([x, y, np.ones_like(x)])
    (a, b, c), *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
    cx, cy = a / 2.0, b / 2.0
    radius2 = c + cx * cx + cy * cy
    if not radius2 > 0.0:
        return None
    # the outline runs through the outermost pixels' centres: half a pixel inside the disc's edge
    return float(cx), float(cy), float(np.sqrt(radius2)) + 0.5


def _ring_mean(patch: Image, x: float, y: float, r0: float, r1: float) -> float:
    yy, xx = np.ogrid[: patch.shape[0], : patch.shape[1]]
    d2 = (xx - x) ** 2 + (yy - y) ** 2
    mask = (d2 >= r0 * r0) & (d2 <= r1 * r1)
    return float(patch[mask].mean()) if np.any(mask) else 0.0
