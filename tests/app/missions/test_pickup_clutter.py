"""Rendered clutter never becomes a fix: real pixels through the real ArUco detector into ``PickupEstimates``.

The simulator's renderer draws the sea (and, in one scene, the object's marker at its true pose) from a vehicle
hovering 10 m up; into each raw frame the test composites a printed glyph — the object's own ArUco ID, ~20 px,
on debris floating 3-4 m from the object — and round bright spots (glints, buoys). Every frame goes through
the app's detector (raw image, capture time) and, like the camera task does, into ``on_marker``/``on_frame``;
vehicle samples (50 Hz) and radar heights (10 Hz) arrive as the sensor tasks would hand them over.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from app.estimators.apparent_size import apparent_size_ratio
from app.estimators.factory import make_target_filter
from app.estimators.triangulation import SeaPlaneTriangulator
from app.messages import AttitudeEuler, PositionVelocityNed
from app.missions.params import MissionParams
from app.missions.pickup import PickupEstimates
from app.sensors.camera import ExposureControls
from app.sensors.detect import make_detector
from app.settings import Settings
from sim.camera_render import CameraRenderer, Conditions
from sim.camera_render_poses import Pose, camera_pose, object_pose
from sim.sea import FloatingObject, SeaConfig, SeaWorld

SETTINGS = Settings()
CAMERA, DETECTOR = SETTINGS.camera, SETTINGS.detector
HOVER_DOWN_M = -10.0  # the vehicle's down position; the mean sea is at down = 0
FRAME_HZ, SAMPLE_HZ, RADAR_HZ = 15.0, 50.0, 10.0
LATENCY_S = 0.06  # capture → detection handed to the estimates (exposure, readout, detector)
FRAMES = 60  # 4 s of frames per scene
GLYPH_EDGE_M = 0.20  # the printed glyph's black square: ~20 px from 10 m
GLYPH_START_NE_M = (-1.0, -3.2)  # where the debris floats at t = 0
GLYPH_DRIFT_NE_MPS = (0.12, 0.08)  # it drifts slowly (and turns), a pixel or two a frame
GLYPH_TURN_RADPS = 0.3
SPOTS = ((2.5, 3.5, 3.0), (-3.0, 2.0, 6.0), (3.0, -1.5, 10.0), (-2.0, 4.5, 16.0), (1.0, 5.0, 24.0))  # n, e, r_px
OBJECT_START_NE_M = (0.3, -0.4)  # the real marker, near nadir
ON_TARGET_PX = 12.0  # a detection this close to a drawn thing's centre is that thing
F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@dataclass
class Run:
    """What one scene produced: the estimates, and per frame what the detector found and where things were."""

    model: PickupEstimates
    glyph_detections: int = 0
    marker_detections: int = 0
    other_detections: list[tuple[float, float]] = field(default_factory=list)  # centres on neither: spots or noise
    glyph_sizes_px: list[float] = field(default_factory=list)
    glyph_size_ratios: list[float] = field(default_factory=list)  # what the size check computed for each
    first_marker_frame: int | None = None
    fused_glyphs: int = 0
    errors_m: list[float] = field(default_factory=list)  # |estimate − true marker| (horizontal) after each frame
    glyph_gaps_m: list[float] = field(default_factory=list)  # |estimate − glyph| after each frame


def model() -> PickupEstimates:
    """As ``tests/app/missions/test_pickup_estimates.py`` builds it: default ``FixChecks``."""
    return PickupEstimates(
        SeaPlaneTriangulator.from_settings(CAMERA), make_target_filter(MissionParams(target_filter="wave", sea_state=2))
    )


def hover(t_s: float) -> tuple[F64, F64, tuple[float, float, float]]:
    """The hovering vehicle's position, velocity and attitude: a few centimetres and a degree of sway."""
    pos = np.array([0.05 * math.sin(0.7 * t_s), 0.04 * math.sin(0.5 * t_s + 1.0), HOVER_DOWN_M])
    vel = np.array([0.035 * math.cos(0.7 * t_s), 0.02 * math.cos(0.5 * t_s + 1.0), 0.0])
    att = (0.015 * math.sin(1.3 * t_s), 0.012 * math.sin(0.9 * t_s + 0.5), 0.4)
    return pos, vel, att


def glyph_texture() -> U8:
    """The object's own marker ID, printed with a one-cell white quiet zone; 10 texels per cell."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DETECTOR.dictionary))
    cells = int(dictionary.markerSize) + 2
    marker = cv2.aruco.generateImageMarker(dictionary, DETECTOR.marker_id, 10 * cells, borderBits=1)
    return np.asarray(cv2.copyMakeBorder(marker, 10, 10, 10, 10, cv2.BORDER_CONSTANT, value=255), np.uint8)


GLYPH = glyph_texture()
GLYPH_QUIET_FRACTION = GLYPH.shape[0] / (GLYPH.shape[0] - 20)  # printed square (with quiet zone) over the marker


def glyph_quad_ned(t_s: float) -> F64:
    """The printed sheet's corners (TL, TR, BR, BL of the texture) on the sea at ``t_s``, NED."""
    n = GLYPH_START_NE_M[0] + GLYPH_DRIFT_NE_MPS[0] * t_s
    e = GLYPH_START_NE_M[1] + GLYPH_DRIFT_NE_MPS[1] * t_s
    a = 0.7 + GLYPH_TURN_RADPS * t_s
    half = GLYPH_EDGE_M * GLYPH_QUIET_FRACTION / 2
    # the texture's x (right) and y (down) axes on the sea, north-east: at a = 0 east and south (not mirrored)
    x, y = np.array([-math.sin(a), math.cos(a)]), np.array([-math.cos(a), -math.sin(a)])
    corners = [(-half, -half), (half, -half), (half, half), (-half, half)]
    return np.array([[n + cx * x[0] + cy * y[0], e + cx * x[1] + cy * y[1], 0.0] for cx, cy in corners])


def to_pixels(renderer: CameraRenderer, cam: Pose, points_ned: F64) -> F64:
    return renderer.model.project((points_ned - cam.pos_ned_m) @ cam.R_ned_from_body)


def composite_glyph(image: U8, quad_px: F64, rng: np.random.Generator) -> None:
    """The print, lit like the sea (white ~200, black ~30 grey), slightly soft, with sensor noise, in place."""
    tex = np.where(GLYPH > 127, 200, 30).astype(np.uint8)
    s = tex.shape[0]
    src = np.array([[-0.5, -0.5], [s - 0.5, -0.5], [s - 0.5, s - 0.5], [-0.5, s - 0.5]], np.float32)
    x0, y0 = np.floor(quad_px.min(axis=0)).astype(int) - 3
    x1, y1 = np.ceil(quad_px.max(axis=0)).astype(int) + 4
    hom = cv2.getPerspectiveTransform(src, (quad_px - [x0, y0]).astype(np.float32))
    size = (int(x1 - x0), int(y1 - y0))
    sharp = np.asarray(cv2.warpPerspective(tex, hom, size, flags=cv2.INTER_AREA), np.float64)
    alpha = np.asarray(cv2.warpPerspective(np.full_like(tex, 255), hom, size, flags=cv2.INTER_LINEAR)) / 255.0
    print_grey = cv2.GaussianBlur(sharp, (0, 0), 0.6) + rng.normal(0.0, 2.0, sharp.shape)
    roi = image[y0:y1, x0:x1].astype(np.float64)
    image[y0:y1, x0:x1] = np.clip(roi * (1.0 - alpha) + print_grey * alpha, 0, 255).round().astype(np.uint8)


def spot_centres_px(renderer: CameraRenderer, cam: Pose) -> list[tuple[F64, float]]:
    ned = np.array([[n, e, 0.0] for n, e, _ in SPOTS])
    return list(zip(to_pixels(renderer, cam, ned), (r for _, _, r in SPOTS), strict=True))


def composite_spots(image: U8, spots: list[tuple[F64, float]]) -> None:
    """Saturating round blobs with soft rims (glints, a white buoy), in place."""
    discs = np.zeros(image.shape, np.uint8)
    for (x, y), r in spots:
        cv2.circle(discs, (round(x * 16), round(y * 16)), round(r * 16), 255, -1, cv2.LINE_AA, shift=4)
    cv2.max(image, cv2.GaussianBlur(discs, (0, 0), 1.0), dst=image)


def run_scene(with_marker: bool, seed: int) -> Run:
    """Frames at 15 Hz from the hovering vehicle, clutter composited in, through detector and estimates."""
    sea = SeaWorld(SeaConfig(sea_state=2, current_mps=0.1), seed=seed)
    obj = FloatingObject(sea, start_ne_m=OBJECT_START_NE_M)
    renderer = CameraRenderer(CAMERA, DETECTOR, seed=seed)
    detector = make_detector(SETTINGS.detector, SETTINGS.camera)
    rng = np.random.default_rng(seed)
    run = Run(model())
    m = run.model
    next_sample_s = next_height_s = 0.0
    for k in range(FRAMES):
        t_capture_s = 1.0 + k / FRAME_HZ
        t_handed_s = t_capture_s + LATENCY_S
        # the sensor tasks' samples up to the moment the detection is handed over
        while next_sample_s <= t_handed_s:
            pos, vel, (roll, pitch, yaw) = hover(next_sample_s)
            m.on_vehicle_sample(PositionVelocityNed(next_sample_s, tuple(pos), tuple(vel)))
            m.on_vehicle_sample(AttitudeEuler(next_sample_s, roll, pitch, yaw))
            next_sample_s += 1.0 / SAMPLE_HZ
        while next_height_s <= t_handed_s:
            pos, _, _ = hover(next_height_s)
            sea_down_m = -float(sea.surface_elevation_m(next_height_s, pos[0], pos[1]))
            m.on_height(next_height_s, sea_down_m - pos[2] + rng.normal(0.0, 0.02))
            next_height_s += 1.0 / RADAR_HZ

        pos, _, (roll, pitch, yaw) = hover(t_capture_s)
        cam = camera_pose(pos, roll, pitch, yaw, CAMERA)
        marker = object_pose(obj, t_capture_s, yaw_rad=0.2) if with_marker else None
        frame = renderer.render(t_capture_s, cam, marker, ExposureControls(), Conditions(), frame_index=k)
        image = frame.image.copy()
        glyph_ned = glyph_quad_ned(t_capture_s)
        glyph_px = to_pixels(renderer, cam, glyph_ned)
        composite_glyph(image, glyph_px, rng)
        spots = spot_centres_px(renderer, cam)
        composite_spots(image, spots)

        det = detector.detect(image, t_capture_s)  # as the camera task calls it
        if det is None:
            m.on_frame(t_capture_s)
        else:
            centre = np.array(det.center_px)
            on_glyph = np.linalg.norm(centre - glyph_px.mean(axis=0)) <= ON_TARGET_PX
            marker_px = frame.truth.center_px
            on_marker = marker_px is not None and np.linalg.norm(centre - marker_px) <= ON_TARGET_PX
            fused = m.on_marker(t_capture_s, det.corners_px, det.size_m)
            if on_glyph:
                run.glyph_detections += 1
                run.glyph_sizes_px.append(det.size_px)
                run.glyph_size_ratios.append(size_ratio(m, t_capture_s, det.corners_px, det.size_m))
                run.fused_glyphs += int(fused)
            elif on_marker:
                run.marker_detections += 1
                if run.first_marker_frame is None:
                    run.first_marker_frame = k
            else:
                run.other_detections.append(det.center_px)
        est = m.estimate(t_handed_s)
        if est is not None:
            en = np.array(est.pos_ned_m[:2])
            run.glyph_gaps_m.append(float(np.linalg.norm(en - glyph_ned.mean(axis=0)[:2])))
            if with_marker:
                run.errors_m.append(float(np.linalg.norm(en - np.array(obj.state(t_handed_s).pos_ned_m[:2]))))
        # every spot is in the frame and away from the glyph, so a detection on one would count as "other"
        assert all(r <= c[0] <= CAMERA.width_px - r and r <= c[1] <= CAMERA.height_px - r for c, r in spots)
        assert all(np.linalg.norm(c - glyph_px.mean(axis=0)) > r + 40.0 for c, r in spots)
    return run


def size_ratio(m: PickupEstimates, t_s: float, corners_px: ArrayLike, size_m: float) -> float:
    """The apparent-size ratio the estimates' size check computes for this detection (1.0: the marker's size)."""
    height = m.height_at(t_s)
    fix = None if height is None else m.tri.fix_marker(t_s, corners_px, m.history.at(t_s), height[0])
    return math.nan if fix is None else apparent_size_ratio(corners_px, fix, m.tri.camera, size_m)


@pytest.fixture(scope="module")
def clutter_only() -> Run:
    return run_scene(with_marker=False, seed=11)


@pytest.fixture(scope="module")
def marker_and_clutter() -> Run:
    return run_scene(with_marker=True, seed=12)


def test_the_detector_reports_the_printed_glyph_but_it_never_becomes_a_fix(clutter_only: Run) -> None:
    """Scene (a), no object in view: the same-ID glyph is detected, and every detection is refused on size."""
    run, m = clutter_only, clutter_only.model
    sizes, ratios = run.glyph_sizes_px, run.glyph_size_ratios
    print(f"glyph detected in {run.glyph_detections}/{FRAMES} frames (edge {min(sizes, default=0):.1f}–"
          f"{max(sizes, default=0):.1f} px, size ratio {min(ratios, default=0):.2f}–{max(ratios, default=0):.2f}, "
          f"tolerance ±{m.checks.size_tolerance}); fused {run.fused_glyphs}; fixes {m.fixes}, "
          f"rejected {dict(m.rejected)}")  # fmt: skip
    assert run.glyph_detections >= FRAMES // 4  # otherwise this proves nothing
    assert run.fused_glyphs == 0 and m.fixes == 0 and not m.filter.initialised
    assert m.rejected["size"] == run.glyph_detections
    assert m.estimate(1.0 + FRAMES / FRAME_HZ) is None


def test_with_the_real_marker_in_view_the_estimate_holds_on_it_not_on_the_glyph(marker_and_clutter: Run) -> None:
    """Scene (b): the filter locks on the rendered marker within ~0.3 m and never strays to the glyph."""
    run, m = marker_and_clutter, marker_and_clutter.model
    errors = run.errors_m
    print(f"marker detected in {run.marker_detections}/{FRAMES} frames (first in frame {run.first_marker_frame}), "
          f"glyph in {run.glyph_detections} (fused {run.fused_glyphs}); fixes {m.fixes}, rejected {dict(m.rejected)}; "
          f"error max {max(errors, default=math.nan):.3f} m, last {errors[-1] if errors else math.nan:.3f} m; "
          f"closest to the glyph {min(run.glyph_gaps_m, default=math.nan):.2f} m")  # fmt: skip
    assert m.filter.initialised and m.fixes >= FRAMES // 2
    assert run.fused_glyphs == 0
    assert len(errors) >= FRAMES // 2 and max(errors) <= 0.3
    assert min(run.glyph_gaps_m) >= 2.0  # the glyph floats 3–4 m away: the estimate never went there


@pytest.mark.parametrize("scene", ["clutter_only", "marker_and_clutter"])
def test_bright_round_spots_never_give_a_detection(scene: str, request: pytest.FixtureRequest) -> None:
    """Glints and buoy-like blobs of 3–24 px radius: no detection lies anywhere but on the glyph or the marker."""
    run: Run = request.getfixturevalue(scene)
    print(f"{scene}: detections elsewhere {run.other_detections}")
    assert run.other_detections == []
