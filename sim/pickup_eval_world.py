"""The pickup world of the Monte Carlo evaluation: ``PickupWorld`` plus clutter and the thesis's detector.

Clutter, in the geometric camera (what ``tests/app/missions/test_pickup_clutter.py`` shows on rendered frames):

- ``glyph``: debris carrying the object's own marker ID, printed ``GLYPH_EDGE_M`` across (the object's marker is
  0.30 m), floating ``GLYPH_DISTANCE_M`` from the object and drifting with the same sea. When it is wholly in the
  image and big enough to decode, and the real marker is not, the detector reports the glyph as the marker;
  when both are, the ID is seen twice (or outer and nested disagree on the centre) and there is no detection;
- ``glints``: sun glints the size of the buoy, in ``GLINT_FRAME_ODDS`` of the frames at a random place on the
  sea in view; the buoy detector reports the glint (brighter than the buoy) instead of the buoy.

Both as the detectors search (``app.sensors.detect``): while they track (something was reported the frame
before), they look only in a window around it, ``roi_margin`` × its size each way (at least
``MIN_WINDOW_PX`` across); clutter outside that window is not seen, and a miss there falls back to the whole
frame. So a glyph metres off the tracked marker does not hide it, and a glint takes the buoy's place only when
it falls inside the window (or nothing is tracked).

Full-frame detection (the thesis: ``cv2.undistort`` of the whole frame, then the default ArUco detector on it)
is modelled by what ``python -m app.bench perception`` measured on this machine for that pipeline against
seapick's tracking detector (issue 4: median 16.77 ms / p95 22.22 ms against 0.90 ms; recall on markers ≥ 30 px
97.9 % against 100 %): every frame reaches the mission later by the extra detector time (log-normal, median
``FULL_FRAME_EXTRA_MEDIAN_S``, p95 ``FULL_FRAME_EXTRA_P95_S``), and ``FULL_FRAME_MISS_ODDS`` of the marker
detections are lost. Its lower accuracy at the corners is not modelled (the bench's centre errors were 0.25 px
against 0.12 px: below the scenarios' pixel noise).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from app.missions.pickup_feeds import CameraObservation
from app.sensors.detect import MIN_WINDOW_PX
from app.settings import Settings
from sim.camera_geometry import mean_edge_px
from sim.inproc import InProcessVehicle
from sim.pickup_world import BUOY_NOISE_PX, MIN_BUOY_PX, MIN_EDGE_PX, PickupScenario, PickupWorld
from sim.sea import FloatingObject

CLUTTER_KINDS = ("none", "glyph", "glints")
GLYPH_EDGE_M = 0.20
GLYPH_DISTANCE_M = (3.0, 6.0)
GLINT_FRAME_ODDS = 0.1
FULL_FRAME_EXTRA_MEDIAN_S = 0.01677 - 0.00090
FULL_FRAME_EXTRA_P95_S = 0.02222 - 0.00090
FULL_FRAME_MISS_ODDS = 1.0 - 0.979
_Z95 = 1.6449


class EvalPickupWorld(PickupWorld):
    def __init__(
        self,
        vehicle: InProcessVehicle,
        scenario: PickupScenario,
        settings: Settings,
        clutter: str = "none",
        full_frame_detection: bool = False,
    ) -> None:
        if clutter not in CLUTTER_KINDS:
            raise ValueError(f"clutter {clutter!r} is not one of {', '.join(CLUTTER_KINDS)}")
        super().__init__(vehicle, scenario, settings)
        self.clutter = clutter
        self.full_frame_detection = full_frame_detection
        # their own random streams: the scenario's draws do not shift with the configuration's
        self.clutter_rng = np.random.default_rng(scenario.seed + 2000)
        self.detector_rng = np.random.default_rng(scenario.seed + 3000)
        cam = settings.camera
        self.footprint_per_m = min(cam.width_px / cam.fx_px, cam.height_px / cam.fy_px)
        self.glyph: FloatingObject | None = None
        if clutter == "glyph":
            d_m = float(self.clutter_rng.uniform(*GLYPH_DISTANCE_M))
            b_rad = float(self.clutter_rng.uniform(0.0, 2.0 * math.pi))
            n0, e0 = scenario.object_start_ne_m
            self.glyph = FloatingObject(self.sea, start_ne_m=(n0 + d_m * math.cos(b_rad), e0 + d_m * math.sin(b_rad)))
        self.roi_margin = settings.detector.roi_margin
        self.fx_px = cam.fx_px
        self._tracked_ne_m: tuple[float, float] | None = None  # what the detector reported last frame, on the sea
        self.glyph_frames = 0  # frames the glyph was reported as the marker
        self.glint_frames = 0  # frames a glint was reported as the buoy
        self.missed_frames = 0  # detections the full-frame detector lost

    def frame_latency_s(self) -> float:
        extra_s = 0.0
        if self.full_frame_detection:
            sigma = math.log(FULL_FRAME_EXTRA_P95_S / FULL_FRAME_EXTRA_MEDIAN_S) / _Z95
            extra_s = FULL_FRAME_EXTRA_MEDIAN_S * math.exp(sigma * float(self.detector_rng.normal()))
        return self.scenario.latency_s + extra_s

    def _in_window(self, truth: Any, size_m: float, ne_m: tuple[float, float]) -> bool:
        """Is ``ne_m`` inside the tracking window around what was reported last frame (False: not tracking)?"""
        if self._tracked_ne_m is None:
            return False
        height_m = max(-truth.pos_ned_m[2], 0.5)  # over the mean sea: the window's floor, roughly
        half_m = max(self.roi_margin * size_m, 0.5 * MIN_WINDOW_PX * height_m / self.fx_px)
        dn, de = ne_m[0] - self._tracked_ne_m[0], ne_m[1] - self._tracked_ne_m[1]
        return abs(dn) <= half_m and abs(de) <= half_m

    def _report(self, seen: CameraObservation, ne_m: tuple[float, float] | None) -> CameraObservation:
        self._tracked_ne_m = ne_m if seen.corners_px is not None or seen.center_px is not None else None
        return seen

    def _largest_seen(self, t_s: float, truth: Any, centre_ned_m: Any) -> CameraObservation:
        seen = super()._largest_seen(t_s, truth, centre_ned_m)
        where: tuple[float, float] | None = (float(centre_ned_m[0]), float(centre_ned_m[1]))
        if self.glyph is not None:
            glyph = self._glyph_seen(t_s, truth, self.glyph)
            if glyph is not None:
                g = self.glyph.state(t_s).pos_ned_m
                glyph_ne = (float(g[0]), float(g[1]))
                size_m = self.marker_sizes_m[0]
                if seen.corners_px is not None:
                    marker_in = self._in_window(truth, size_m, where)  # type: ignore[arg-type]
                    glyph_in = self._in_window(truth, size_m, glyph_ne)
                    if marker_in and not glyph_in:
                        pass  # tracking the marker: the glyph is outside the window
                    elif glyph_in and not marker_in:
                        self.glyph_frames += 1
                        seen, where = glyph, glyph_ne  # tracking the glyph
                    else:
                        seen = CameraObservation(t_s)  # the ID twice in what was searched: no detection
                else:
                    self.glyph_frames += 1
                    seen, where = glyph, glyph_ne
        if self.full_frame_detection and seen.corners_px is not None:
            if self.detector_rng.random() < FULL_FRAME_MISS_ODDS:
                self.missed_frames += 1
                return self._report(CameraObservation(t_s), None)
        return self._report(seen, where)

    def _buoy_seen(self, t_s: float, truth: Any, centre_ned_m: Any) -> CameraObservation:
        seen = super()._buoy_seen(t_s, truth, centre_ned_m)
        buoy_ne = (float(centre_ned_m[0]), float(centre_ned_m[1]))
        if self.clutter == "glints" and self.clutter_rng.random() < GLINT_FRAME_ODDS:
            glint = self._glint_seen(t_s, truth)
            if glint is not None:
                obs, glint_ne = glint
                tracking_buoy = seen.center_px is not None and self._in_window(truth, self.buoy_diameter_m, buoy_ne)
                if not tracking_buoy or self._in_window(truth, self.buoy_diameter_m, glint_ne):
                    self.glint_frames += 1  # brighter than the buoy, in what was searched
                    return self._report(obs, glint_ne)
        return self._report(seen, buoy_ne)

    def _glyph_seen(self, t_s: float, truth: Any, glyph: FloatingObject) -> CameraObservation | None:
        """The glyph as the detector would report it (as the outer marker: no size), when it can be decoded."""
        p = truth.pos_ned_m
        f = self.camera.frame(
            t_s,
            p,
            truth.roll_rad,
            truth.pitch_rad,
            truth.yaw_rad,
            glyph.state(t_s).pos_ned_m,
            marker_size_m=GLYPH_EDGE_M,
        )
        c = f.corners_true_px
        edge_px = mean_edge_px(c)
        if not f.visible or edge_px < MIN_EDGE_PX:
            return None
        return CameraObservation(t_s, tuple((float(u), float(v)) for u, v in f.corners_px))

    def _glint_seen(self, t_s: float, truth: Any) -> tuple[CameraObservation, tuple[float, float]] | None:
        """A buoy-sized glint somewhere on the sea in view, and where (None when it falls outside the image)."""
        p = truth.pos_ned_m
        sea_down_m = -float(self.sea.surface_elevation_m(t_s, p[0], p[1]))
        radius_m = 0.5 * max(sea_down_m - p[2], 0.5) * self.footprint_per_m
        r_m, b_rad = (
            radius_m * math.sqrt(float(self.clutter_rng.random())),
            float(self.clutter_rng.uniform(0, 2 * math.pi)),
        )
        n_m, e_m = p[0] + r_m * math.cos(b_rad), p[1] + r_m * math.sin(b_rad)
        at = (n_m, e_m, -float(self.sea.surface_elevation_m(t_s, n_m, e_m)))
        f = self.camera.frame(
            t_s, p, truth.roll_rad, truth.pitch_rad, truth.yaw_rad, at, marker_size_m=self.buoy_diameter_m
        )
        c = f.corners_true_px
        diameter_px = mean_edge_px(c)
        if not f.visible or diameter_px < MIN_BUOY_PX:
            return None
        u, v = f.centre_true_px + self.clutter_rng.normal(0.0, BUOY_NOISE_PX, 2)
        return CameraObservation(t_s, center_px=(float(u), float(v)), diameter_px=diameter_px), (n_m, e_m)

    def clutter_summary(self) -> dict[str, int]:
        return {
            "glyph_frames": self.glyph_frames,
            "glint_frames": self.glint_frames,
            "missed_frames": self.missed_frames,
        }
