"""ArUco/AprilTag marker detection (thesis §4.2.3), fast enough to run on every frame on one core.

The thesis undistorted each whole frame and ran the default detector over it. Here the raw frame is searched
as it is (only the corners found are undistorted later), and the work is cut three ways:

- **tracking**: around the expected position only, in a window reaching ``roi_margin`` × the marker size from
  it each way, scaled down so the marker spans ~``TRACK_TARGET_PX`` pixels there;
- **search** (no track, or the window missed): first the whole frame at ``SEARCH_SCALE`` (markers from
  ~``SEARCH_REDUCED_MIN_PX`` px up), then, only if that found none of the set whole, at full resolution for the
  small ones;
- one adaptive-threshold window (``THRESHOLD_WINDOW_PX``) per pass instead of the default three (3, 13, 23 px),
  and candidates outside the size range a pass is for are dropped before they are decoded (OpenCV measures a
  perimeter in contour points, √2 fewer along a diagonal: the bound allows for a marker turned 45°, and the
  marker's edge itself is checked after).

Corners found at a reduced scale are refined at full resolution (``cv2.cornerSubPix`` in a window no wider than
a fraction of a cell); a marker small there is found again at full resolution around it instead. A match needs
the expected ID exactly once — zero or several matches of it give no detection (thesis) — and the centre is the
mean of the four corners (eq. 4.3).

Nested markers (``nested_marker_ids``): each sits concentric in the centre of the one before, with an edge of
half a cell of it — ``edge_k = marker_size_m / (2 (n + 2))^k`` for an n×n-bit dictionary — so the lock holds
when the outer marker outgrows the image near touchdown. When several of the set are seen, the largest wins;
outer and nested must agree on the centre. A marker cut by the image border is not used, but a whole nested one
inside it is (a tracking window leaves that to the search). In a tracking window, duplicates are only seen
inside the window.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from app.messages import PixelDetection
from app.sensors.detect import MIN_WINDOW_PX, DetectionHint, Image, TrackingDetector, Window
from app.settings import CameraSettings, DetectorSettings

SEARCH_SCALE = 0.5  # the first full-frame pass runs at this scale
SEARCH_REDUCED_MIN_PX = 28  # smallest marker (edge, full-res px) the reduced pass looks for
SEARCH_FULL_MAX_PX = 90  # the full-resolution pass decodes markers up to this edge only (larger: the reduced pass)
SEARCH_FULL_MIN_PX = 14
TRACK_TARGET_PX = 64  # in the tracking window the marker is scaled down to about this edge
THRESHOLD_WINDOW_PX = 7  # adaptive-threshold window of every pass, px (at the pass's scale)
PIXELS_PER_CELL = 8  # bit sampling resolution; the default 4 misreads blurred, rotated markers
CORNER_WINDOW_CELL_FRACTION = 0.35  # sub-pixel refinement looks no further than this part of a cell
MIN_EDGE_SLACK = 0.9  # a pass's smallest edge, measured: a small marker's corners come out a pixel or so inside


def nested_size_ratio(bits: int) -> float:
    """Edge of a nested marker over the edge of the marker it sits in: half a cell of an n×n-bit marker."""
    return 1.0 / (2.0 * (bits + 2))


def marker_sizes_m(settings: DetectorSettings) -> tuple[float, ...]:
    """The edges of the marker and its nested ones, largest first, m."""
    bits = int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, settings.dictionary)).markerSize)
    ratio = nested_size_ratio(bits)
    return tuple(settings.marker_size_m * ratio**k for k in range(len(settings.nested_marker_ids) + 1))


def _parameters(min_perimeter_rate: float, max_perimeter_rate: float) -> cv2.aruco.DetectorParameters:
    """Parameters of one pass; the perimeter rates are 4 × the edge it is for over the image's long side."""
    p = cv2.aruco.DetectorParameters()
    p.adaptiveThreshWinSizeMin = THRESHOLD_WINDOW_PX
    p.adaptiveThreshWinSizeMax = THRESHOLD_WINDOW_PX
    p.adaptiveThreshWinSizeStep = 10
    # OpenCV counts a candidate's perimeter in contour points, and an edge at 45° has only 1/√2 point per pixel
    # of length: the lower bound is lowered by as much, so that a marker turned 45° counts at its full size
    p.minMarkerPerimeterRate = min_perimeter_rate / math.sqrt(2.0)
    p.maxMarkerPerimeterRate = max_perimeter_rate
    p.perspectiveRemovePixelPerCell = PIXELS_PER_CELL
    p.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE  # refined at full resolution below
    # A marker's white plate cut by the image (or window) border is grouped with the marker and, as the group's
    # largest candidate, rejected for touching the border — taking the marker with it. Keep such candidates;
    # a quad that really touches the border is dropped in _pick instead.
    p.minDistanceToBorder = 0
    return p


class MarkerDetector(TrackingDetector):
    """The marker detector behind :class:`app.sensors.detect.Detector`."""

    def __init__(self, settings: DetectorSettings, camera: CameraSettings | None = None) -> None:
        super().__init__()
        self.settings = settings
        self.width_px = camera.width_px if camera else 1280
        self.height_px = camera.height_px if camera else 960
        self._dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, settings.dictionary))
        bits = int(self._dictionary.markerSize)
        self._cells = bits + 2
        ids = (settings.marker_id, *settings.nested_marker_ids)
        self._sizes_m = dict(zip(ids, marker_sizes_m(settings), strict=True))
        long_side = max(self.width_px, self.height_px)
        reduced_long = long_side * SEARCH_SCALE
        self._reduced = cv2.aruco.ArucoDetector(
            self._dictionary, _parameters(4 * SEARCH_REDUCED_MIN_PX * SEARCH_SCALE / reduced_long, 4.0)
        )
        self._full = cv2.aruco.ArucoDetector(
            self._dictionary, _parameters(4 * SEARCH_FULL_MIN_PX / long_side, 4 * SEARCH_FULL_MAX_PX / long_side)
        )
        self._window = cv2.aruco.ArucoDetector(self._dictionary, _parameters(0.03, 4.0))

    def detect(
        self, image: Image, t_s: float, hint: DetectionHint | None = None, height_m: float | None = None
    ) -> PixelDetection | None:
        hint = hint or self._track.hint(t_s)
        found = None
        if hint is not None:
            found = self._in_window(image, t_s, hint)
        if found is None:
            found = self._search(image, t_s)
        if found is None:
            self._last_pass = "none"
        self._track.update(found)
        return found

    # -- passes ------------------------------------------------------------------------------------------------

    def _in_window(
        self, image: Image, t_s: float, hint: DetectionHint, *, tracked: bool = True
    ) -> PixelDetection | None:
        size = max(hint.size_px, 1.0)
        # the window reaches roi_margin × the size from the expected centre each way (so a turned marker and its
        # white margin fit with room to move), plus the hint's own uncertainty
        side = max(2 * (self.settings.roi_margin * size + hint.radius_px), MIN_WINDOW_PX)
        win = Window.around(hint.center_px, side, image.shape[1], image.shape[0])
        if win.empty:
            return None
        scale = min(1.0, TRACK_TARGET_PX / size)
        crop: Any = image[win.y0 : win.y1, win.x0 : win.x1]
        if scale < 1.0:
            crop = cv2.resize(crop, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        # accept markers from a third of the expected size up, in this crop
        long_side = max(crop.shape)
        params = _parameters(min(4 * size * scale / 3 / long_side, 4.0), 4.0)
        self._window.setDetectorParameters(params)
        corners, ids, _ = self._window.detectMarkers(crop)
        # one of the set cut by the window's edge: the search decides (the window may hide a larger one)
        quads = self._whole(corners, ids, crop.shape, scale, (win.x0, win.y0), size / 3, cut_vetoes=True)
        found = self._pick(image, t_s, quads, scale, tracked=tracked) if quads else None
        if found is not None and tracked:
            self._last_pass = "track"
        return found

    def _search(self, image: Image, t_s: float) -> PixelDetection | None:
        small = cv2.resize(image, None, fx=SEARCH_SCALE, fy=SEARCH_SCALE, interpolation=cv2.INTER_AREA)
        corners, ids, _ = self._reduced.detectMarkers(small)
        quads = self._whole(corners, ids, small.shape, SEARCH_SCALE, (0, 0), SEARCH_REDUCED_MIN_PX, cut_vetoes=False)
        if quads is None:
            return None  # an ID seen twice: no detection, and no second look at full resolution
        if quads:
            found = self._pick(image, t_s, quads, SEARCH_SCALE, tracked=False)
            if found is not None:
                self._last_pass = "search_reduced"
                return self._sharpened(image, t_s, found)
            return None  # seen whole and refused (not concentric)
        # none of the set, or only cut by the image border (a nested one may be whole, too small for this pass)
        corners, ids, _ = self._full.detectMarkers(image)
        quads = self._whole(corners, ids, image.shape, 1.0, (0, 0), SEARCH_FULL_MIN_PX, cut_vetoes=False)
        found = self._pick(image, t_s, quads, 1.0, tracked=False) if quads else None
        if found is not None:
            self._last_pass = "search_full"
        return found

    def _sharpened(self, image: Image, t_s: float, found: PixelDetection) -> PixelDetection:
        """A marker the reduced pass found small, found again at full resolution around it (better corners).

        Its corners are off by about a reduced pixel; refinement mends that only where a cell's fraction is wider.
        """
        if found.size_px >= TRACK_TARGET_PX:
            return found
        again = self._in_window(image, t_s, DetectionHint(found.center_px, found.size_px), tracked=False)
        return again if again is not None and again.marker_id == found.marker_id else found

    # -- choosing and refining -----------------------------------------------------------------------------------

    def _whole(
        self,
        corners: Sequence[Any],
        ids: Any,
        crop_shape: tuple[int, ...],
        scale: float,
        offset: tuple[int, int],
        min_edge_px: float,
        *,
        cut_vetoes: bool,
    ) -> dict[int, NDArray[np.float64]] | None:
        """The pass's markers of the set, full-resolution corners by ID; None: the pass must give no detection.

        An ID of the set seen twice gives None. A marker cut by the border (of the image or the window) is left
        out — its corners, and even its ID, are not to be trusted — and a whole nested marker inside it kept; with
        ``cut_vetoes`` it gives None instead.
        """
        if ids is None:
            return {}
        flat = [int(i) for i in ids.ravel()]
        if any(flat.count(i) > 1 for i in set(flat) if i in self._sizes_m):
            return None  # several matches of an ID: no detection
        ours = [k for k, i in enumerate(flat) if i in self._sizes_m]
        cut = [k for k in ours if _touches_border(corners[k].reshape(4, 2), crop_shape)]
        if cut and cut_vetoes:
            return None
        # pixel centres: (x + 0.5) / scale − 0.5 maps a scaled pixel back to full resolution
        quads = {
            flat[k]: (corners[k].reshape(4, 2).astype(np.float64) + 0.5) / scale - 0.5 + offset
            for k in ours
            if k not in cut
        }
        # a pass is for markers from min_edge_px up (its lower perimeter bound lets smaller ones through)
        if quads and max(_edge_px(q) for q in quads.values()) < MIN_EDGE_SLACK * min_edge_px:
            return {}
        return quads

    def _pick(
        self, image: Image, t_s: float, quads: dict[int, NDArray[np.float64]], scale: float, *, tracked: bool
    ) -> PixelDetection | None:
        """The largest marker of the set, refined at full resolution; None if the set disagrees on the centre."""
        best_id = max(quads, key=lambda i: _edge_px(quads[i]))
        if not self._concentric(quads, best_id):
            return None
        quad = self._refine(image, quads[best_id], scale)
        centre = quad.mean(axis=0)  # eq. 4.3
        return PixelDetection(
            t_s=t_s,
            center_px=(float(centre[0]), float(centre[1])),
            corners_px=tuple((float(x), float(y)) for x, y in quad),
            size_px=_edge_px(quad),
            size_m=self._sizes_m[best_id],
            marker_id=best_id,
            tracked=tracked,
        )

    def _concentric(self, quads: dict[int, NDArray[np.float64]], best_id: int) -> bool:
        """Markers of a nested set seen together must share their centre (within half the smallest one)."""
        if len(quads) < 2:
            return True
        centres = np.array([q.mean(axis=0) for q in quads.values()])
        smallest = min(_edge_px(q) for q in quads.values())
        return bool(np.all(np.linalg.norm(centres - quads[best_id].mean(axis=0), axis=1) <= 0.5 * smallest))

    def _refine(self, image: Image, quad: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
        """Sub-pixel corners at full resolution, searched no further than the scaled pixel's error."""
        cell_px = _edge_px(quad) / self._cells
        half_win = int(min(max(2.0, math.ceil(1.5 / scale)), max(2.0, CORNER_WINDOW_CELL_FRACTION * cell_px)))
        pts = quad.astype(np.float32).reshape(-1, 1, 2)
        h, w = image.shape
        margin = half_win + 2
        inside = (pts[:, 0, 0] >= margin) & (pts[:, 0, 1] >= margin)
        inside &= (pts[:, 0, 0] < w - margin) & (pts[:, 0, 1] < h - margin)
        if not np.all(inside):
            return quad
        criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.01)
        refined = cv2.cornerSubPix(image, pts, (half_win, half_win), (-1, -1), criteria).reshape(4, 2)
        # a corner that wandered off by more than the search window is not trusted
        moved = np.linalg.norm(refined - quad, axis=1)
        return np.where((moved <= half_win * 1.5)[:, None], refined.astype(np.float64), quad)


def _touches_border(quad: NDArray[np.float32], shape: tuple[int, ...], margin_px: float = 2.0) -> bool:
    h, w = shape[:2]
    return bool(
        np.any(quad < margin_px) or np.any(quad[:, 0] > w - 1 - margin_px) or np.any(quad[:, 1] > h - 1 - margin_px)
    )


def _edge_px(quad: NDArray[np.float64]) -> float:
    return float(np.mean(np.linalg.norm(quad - np.roll(quad, -1, axis=0), axis=1)))
