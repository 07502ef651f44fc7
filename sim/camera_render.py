"""What the downward camera sees: the sea, its glints, and the marker or buoy at the object's true pose.

The frame is built in a few cv2 operations on precomputed textures (:mod:`sim.camera_render_textures`):

1. the sea texture (level of detail matched to the pixel footprint), warped by the homography of the plane
   down = 0 into an *undistorted* canvas at half resolution, then upsampled;
2. sun glints (small saturating specks) and, optionally, a glare blob;
3. the marker plate (or the buoy sprite) warped into its bounding box at full resolution through the
   homography of the object's tilted plane (pose from the wave slope at the object), alpha-composited;
4. lens distortion: the canvas is remapped to raw pixels (maps precomputed from the camera model);
5. motion blur (a line kernel), the exposure model — grey = radiance · exposure · k + (brightness − 32)·k_b,
   saturating at 255 — and Gaussian sensor noise.

Ground truth comes with every frame: the marker's corners projected *with* distortion (``CameraModel.project``),
their mean (thesis eq. 4.3, what a detector reports) and the projection of the object centre.

Frames: NED metres, camera frame OpenCV (x right, y down, z out of the lens). Only the sea plane is flat here:
waves move and tilt the object, the sea texture scrolls with the waves; tilts must keep the horizon out of
view. Deterministic for a seed and frame index.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from app.messages import CameraModel
from app.sensors.camera import ExposureControls
from app.settings import CameraSettings, DetectorSettings
from sim.camera_render_poses import Pose
from sim.camera_render_textures import (
    SEA_LEVELS,
    SEA_MEAN,
    SEA_TEXEL0_M,
    SEA_TEXTURE_PX,
    U8,
    buoy_sprite,
    glare_sprite,
    marker_plate,
    noise_tile,
    sea_levels,
)

F64 = NDArray[np.float64]

# Exposure model: at the thesis defaults (exposure 48, brightness 32) the mean sea is mid-band (120 grey).
EXPOSURE_GAIN = 120.0 / (SEA_MEAN * 48.0)  # grey per (radiance unit · exposure unit)
BRIGHTNESS_REF = 32.0  # brightness that adds no offset
BRIGHTNESS_GAIN = 1.0  # grey per brightness unit
SEA_SCROLL_MPS = 0.6  # how fast the texture drifts with the waves


@dataclass(frozen=True, slots=True)
class Glare:
    """A smooth bright blob (sun reflection) centred at ``center_px`` (raw pixels)."""

    center_px: tuple[float, float]
    radius_px: float
    strength: float = 1.0  # 1: its centre reaches full-scale radiance


@dataclass(frozen=True, slots=True)
class Conditions:
    """Per-frame nuisances: light level, blur, glints, glare."""

    illumination: float = 1.0  # scene radiance multiplier (sun/overcast)
    blur_px: float = 0.0  # motion blur length, px
    blur_angle_rad: float = 0.0
    glints: int = 40  # sun glints in the glitter zone
    glint_center_px: tuple[float, float] | None = None  # None: the image centre
    glint_spread_px: float = 300.0
    glare: Glare | None = None
    noise_std_dn: float = 2.0  # sensor noise, grey levels


@dataclass(frozen=True, slots=True)
class FrameTruth:
    """Ground truth of one frame. ``corners_px`` is ``None`` when the marker is not fully in the image."""

    corners_px: F64 | None  # 4×2 raw pixels, ArUco order (TL, TR, BR, BL of the marker image)
    center_px: tuple[float, float] | None  # mean of the corners (thesis eq. 4.3) / buoy centre projection
    center_projected_px: tuple[float, float] | None  # projection of the object's centre point
    size_px: float  # mean marker edge / buoy diameter on the image, px (0 when not in view)
    in_view: bool  # the whole marker (or buoy) is inside the image


@dataclass(frozen=True, slots=True, eq=False)
class RenderedFrame:
    image: U8
    truth: FrameTruth


@dataclass
class CameraRenderer:
    """Renders frames for one camera and one object (marker from ``detector`` settings, or a buoy)."""

    camera: CameraSettings
    detector: DetectorSettings
    seed: int = 0
    wave_dir_rad: float = math.radians(60.0)  # direction the sea texture drifts to
    model: CameraModel = field(init=False)
    _lens: _LensMaps | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        self.model = CameraModel.from_settings(self.camera)
        self._sea = sea_levels(self.seed, self.wave_dir_rad)
        if self.detector.kind == "aruco":
            self._plate = marker_plate(
                self.detector.dictionary, self.detector.marker_id, tuple(self.detector.nested_marker_ids)
            )
        if any(self.camera.distortion):
            self._lens = _lens_maps(self.model)

    # -- public ------------------------------------------------------------------------------------------------

    def render(
        self,
        t_s: float,
        cam: Pose,
        obj: Pose | None,
        controls: ExposureControls,
        conditions: Conditions | None = None,
        frame_index: int = 0,
    ) -> RenderedFrame:
        """The raw image at ``t_s`` from camera pose ``cam`` with the object at ``obj`` (None: no object)."""
        cond = conditions or Conditions()
        rng = np.random.default_rng((self.seed, frame_index))
        w, h = self.camera.width_px, self.camera.height_px
        origin, size = self._canvas()
        canvas = self._sea_canvas(t_s, cam, origin, size)
        self._glints(canvas, origin, cond, rng)
        truth = FrameTruth(None, None, None, 0.0, False)
        if obj is not None:
            truth = self._object(canvas, origin, cam, obj)
        if cond.glare is not None:
            self._glare(canvas, origin, cond.glare)
        lens = self._lens
        image = canvas if lens is None else cv2.remap(canvas, lens.map1, lens.map2, cv2.INTER_LINEAR)
        if cond.blur_px >= 1.0:
            image = cv2.filter2D(image, -1, _line_kernel(cond.blur_px, cond.blur_angle_rad))
        gain = controls.exposure * EXPOSURE_GAIN * cond.illumination
        offset = (controls.brightness - BRIGHTNESS_REF) * BRIGHTNESS_GAIN
        lut = np.clip(np.arange(256) * gain + offset, 0, 255).astype(np.uint8)
        image = cv2.LUT(image, lut)
        if cond.noise_std_dn > 0.0:
            tile = noise_tile(self.seed, round(cond.noise_std_dn, 2))
            r0 = int(rng.integers(0, tile.shape[0] - h + 1))
            c0 = int(rng.integers(0, tile.shape[1] - w + 1))
            image = cv2.add(image, tile[r0 : r0 + h, c0 : c0 + w], dtype=cv2.CV_8U)
        return RenderedFrame(np.asarray(image, dtype=np.uint8), truth)

    def truth(self, cam: Pose, obj: Pose) -> FrameTruth:
        """Where the marker's corners (or the buoy) fall in the raw image, without rendering."""
        r_cam_ned = cam.R_ned_from_body.T
        centre_cam = r_cam_ned @ (obj.pos_ned_m - cam.pos_ned_m)
        centre_px = self.model.project(centre_cam[None, :])[0]
        if self.detector.kind == "buoy":
            diameter_px = 2.0 * self.camera.fx_px * (self.detector.buoy_diameter_m / 2) / max(centre_cam[2], 1e-6)
            in_view = bool(self.model.in_image(centre_px[None, :], diameter_px / 2)[0])
            c = (float(centre_px[0]), float(centre_px[1]))
            return FrameTruth(None, c, c, diameter_px, in_view)
        half = self.detector.marker_size_m / 2
        corners_obj = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
        corners_ned = obj.pos_ned_m + corners_obj @ obj.R_ned_from_body.T
        corners_px = self.model.project((corners_ned - cam.pos_ned_m) @ r_cam_ned.T)
        edges = np.linalg.norm(corners_px - np.roll(corners_px, -1, axis=0), axis=1)
        in_view = bool(np.all(self.model.in_image(corners_px, 1.0)))
        mean = corners_px.mean(axis=0)
        return FrameTruth(
            corners_px if in_view else None,
            (float(mean[0]), float(mean[1])),
            (float(centre_px[0]), float(centre_px[1])),
            float(np.nanmean(edges)) if np.isfinite(edges).any() else math.nan,  # nothing projects: out of view
            in_view,
        )

    # -- the steps -----------------------------------------------------------------------------------------------

    def _canvas(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """Origin (x, y) and size (w, h) of the undistorted canvas; the image itself without distortion."""
        if self._lens is None:
            return (0, 0), (self.camera.width_px, self.camera.height_px)
        return self._lens.origin, self._lens.size

    def _homography_ned_plane(self, cam: Pose, origin: tuple[int, int]) -> F64:
        """3×3 from plane coordinates [north, east, 1] at down = 0 to canvas pixels."""
        r_cam_ned = cam.R_ned_from_body.T
        plane = np.array([[1.0, 0.0, -cam.pos_ned_m[0]], [0.0, 1.0, -cam.pos_ned_m[1]], [0.0, 0.0, -cam.pos_ned_m[2]]])
        shift = np.array([[1.0, 0.0, -origin[0]], [0.0, 1.0, -origin[1]], [0.0, 0.0, 1.0]])
        return shift @ self.model.K @ r_cam_ned @ plane

    def _sea_canvas(self, t_s: float, cam: Pose, origin: tuple[int, int], size: tuple[int, int]) -> U8:
        height_m = max(-float(cam.pos_ned_m[2]), 0.05)
        footprint_m = 2.0 * height_m / self.camera.fx_px  # per half-resolution pixel
        level = int(np.clip(math.floor(math.log2(max(footprint_m / SEA_TEXEL0_M, 1.0))), 0, SEA_LEVELS - 1))
        texel_m = SEA_TEXEL0_M * 2**level
        n_px = SEA_TEXTURE_PX
        # the texture drifts with the waves; its origin is chosen (mod one period) so that the sea under the
        # camera falls in the middle of the 2×2-tiled texture
        drift_m = SEA_SCROLL_MPS * t_s
        drift_n, drift_e = drift_m * math.cos(self.wave_dir_rad), drift_m * math.sin(self.wave_dir_rad)
        u_c = ((cam.pos_ned_m[1] - drift_e) / texel_m) % n_px + n_px / 2  # texture coords under the camera
        v_c = ((drift_n - cam.pos_ned_m[0]) / texel_m) % n_px + n_px / 2
        n0, e0 = cam.pos_ned_m[0] + v_c * texel_m, cam.pos_ned_m[1] - u_c * texel_m
        # texture (u → east, v → south) to plane [n, e, 1]
        tex_to_plane = np.array([[0.0, -texel_m, n0], [texel_m, 0.0, e0], [0.0, 0.0, 1.0]])
        half = np.array([[0.5, 0.0, -0.25], [0.0, 0.5, -0.25], [0.0, 0.0, 1.0]])
        hom = half @ self._homography_ned_plane(cam, origin) @ tex_to_plane
        half_size = ((size[0] + 1) // 2, (size[1] + 1) // 2)
        sea = cv2.warpPerspective(
            self._sea[level], hom, half_size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT101
        )
        full = cv2.resize(sea, (half_size[0] * 2, half_size[1] * 2), interpolation=cv2.INTER_LINEAR)
        return np.ascontiguousarray(full[: size[1], : size[0]], dtype=np.uint8)

    def _glints(self, canvas: U8, origin: tuple[int, int], cond: Conditions, rng: np.random.Generator) -> None:
        if cond.glints <= 0:
            return
        cx, cy = cond.glint_center_px or (self.camera.width_px / 2, self.camera.height_px / 2)
        pts = rng.normal((cx - origin[0], cy - origin[1]), cond.glint_spread_px, (cond.glints, 2))
        radii = rng.integers(1, 4, cond.glints)
        for (x, y), r in zip(pts, radii, strict=True):
            cv2.circle(canvas, (int(x * 4), int(y * 4)), int(r) * 4, 255, -1, cv2.LINE_AA, shift=2)

    def _object(self, canvas: U8, origin: tuple[int, int], cam: Pose, obj: Pose) -> FrameTruth:
        truth = self.truth(cam, obj)
        r_cam_ned = cam.R_ned_from_body.T
        if self.detector.kind == "buoy":
            radiance, alpha = buoy_sprite()
            half = self.detector.buoy_diameter_m / 2
            quad_obj = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
            # a sphere looks like a disc facing the camera: build the quad in the camera's image axes
            centre_cam = r_cam_ned @ (obj.pos_ned_m - cam.pos_ned_m)
            quad_cam = centre_cam + quad_obj
        else:
            plate = self._plate
            half = self.detector.marker_size_m / plate.marker_frac / 2
            quad_obj = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
            quad_cam = (obj.pos_ned_m + quad_obj @ obj.R_ned_from_body.T - cam.pos_ned_m) @ r_cam_ned.T
        if np.any(quad_cam[:, 2] <= 0.01):
            return truth
        quad_px = (quad_cam[:, :2] / quad_cam[:, 2:]) * [self.camera.fx_px, self.camera.fy_px]
        quad_px += [self.camera.cx_px - origin[0], self.camera.cy_px - origin[1]]
        on_screen_px = float(np.max(np.linalg.norm(quad_px - np.roll(quad_px, -1, axis=0), axis=1)))
        alpha_tex: U8 | None = None
        if self.detector.kind == "buoy":
            alpha_tex = alpha
        else:
            mip = 0
            while mip + 1 < len(plate.mips) and plate.mips[mip + 1].shape[0] >= on_screen_px:
                mip += 1
            radiance = plate.mips[mip]
        _composite(canvas, radiance, alpha_tex, quad_px)
        return truth

    def _glare(self, canvas: U8, origin: tuple[int, int], glare: Glare) -> None:
        sprite = glare_sprite()
        if glare.strength != 1.0:
            sprite = np.clip(sprite * glare.strength, 0, 255).astype(np.uint8)
        x, y, r = glare.center_px[0] - origin[0], glare.center_px[1] - origin[1], glare.radius_px
        quad = np.array([[x - r, y - r], [x + r, y - r], [x + r, y + r], [x - r, y + r]])
        _composite(canvas, sprite, None, quad, add=True)


@dataclass(frozen=True, slots=True, eq=False)
class _LensMaps:
    """cv2.remap maps from raw pixels to the undistorted canvas, and where that canvas lies (undistorted px)."""

    map1: NDArray[np.int16]
    map2: NDArray[np.uint16]
    origin: tuple[int, int]
    size: tuple[int, int]


@functools.lru_cache(maxsize=4)
def _lens_maps(model: CameraModel) -> _LensMaps:
    w, h = model.width_px, model.height_px
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    xy = model.undistort_to_normalized(np.column_stack([u.ravel(), v.ravel()]))
    map_x = (xy[:, 0] * model.fx_px + model.cx_px).reshape(h, w)
    map_y = (xy[:, 1] * model.fy_px + model.cy_px).reshape(h, w)
    x0, y0 = math.floor(map_x.min()) - 2, math.floor(map_y.min()) - 2
    size = (math.ceil(map_x.max()) + 3 - x0, math.ceil(map_y.max()) + 3 - y0)
    m1, m2 = cv2.convertMaps((map_x - x0).astype(np.float32), (map_y - y0).astype(np.float32), cv2.CV_16SC2)
    return _LensMaps(m1, m2, (x0, y0), size)


def _composite(canvas: U8, tex: U8, alpha: U8 | None, quad_px: F64, *, add: bool = False) -> None:
    """Warp ``tex`` (corners → ``quad_px``, TL TR BR BL) into ``canvas``.

    Blend with ``alpha`` warped alike, or (``alpha`` None) with the anti-aliased quad itself; ``add`` adds instead.
    """
    h, w = canvas.shape
    x0, y0 = np.floor(quad_px.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(quad_px.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return
    s = tex.shape[0]
    src = np.array([[-0.5, -0.5], [s - 0.5, -0.5], [s - 0.5, s - 0.5], [-0.5, s - 0.5]], np.float32)
    local = (quad_px - [x0, y0]).astype(np.float32)
    hom = cv2.getPerspectiveTransform(src, local)
    size = (int(x1 - x0), int(y1 - y0))
    warped = cv2.warpPerspective(tex, hom, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    roi = canvas[y0:y1, x0:x1]
    if add:
        cv2.add(roi, warped, dst=roi)
        return
    if alpha is not None:
        a = cv2.warpPerspective(alpha, hom, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    else:
        a = np.zeros((size[1], size[0]), np.uint8)
        cv2.fillConvexPoly(a, np.round(local * 16).astype(np.int32), 255, cv2.LINE_AA, shift=4)
    # roi ← roi·(1 − a) + warped·a, in saturating uint8 arithmetic
    cv2.add(
        cv2.multiply(roi, cv2.bitwise_not(a), scale=1.0 / 255.0), cv2.multiply(warped, a, scale=1.0 / 255.0), dst=roi
    )


def _line_kernel(length_px: float, angle_rad: float) -> NDArray[np.float32]:
    """A centred, normalized motion-blur line of ``length_px`` at ``angle_rad``."""
    n = math.ceil(length_px) | 1
    k = np.zeros((n, n), np.float32)
    c = (n - 1) / 2
    dx, dy = math.cos(angle_rad) * (length_px - 1) / 2, math.sin(angle_rad) * (length_px - 1) / 2
    cv2.line(
        k,
        (round((c - dx) * 16), round((c - dy) * 16)),
        (round((c + dx) * 16), round((c + dy) * 16)),
        1.0,
        1,
        cv2.LINE_AA,
        shift=4,
    )
    return k / max(float(k.sum()), 1e-6)
