"""Precomputed textures for the camera renderer: sea, marker plate, buoy, glare, sensor noise.

Everything here is made once per renderer (cached per seed/marker) so that a frame costs only a few cv2 ops.
Radiance is stored as ``uint8`` in *scene units*: 255 is the brightest thing in the scene (a sun glint); the
renderer's exposure model multiplies it by a gain (so white paper, at 200, saturates at normal exposure —
like a white marker over a dark sea with the camera exposing for the sea).

Sea: a periodic, band-limited random field with the spectrum of short wind waves and ripples (power ∝ k⁻³,
stretched along the wave direction), one texture per *level* of detail: level ``L`` has texels of
``SEA_TEXEL0_M · 2^L`` metres, so the renderer can pick the level whose texel matches a pixel's footprint.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]

SEA_TEXTURE_PX = 1024  # side of one periodic sea texture
SEA_TEXEL0_M = 0.002  # texel of level 0, m (0.75 m above the sea a pixel covers ≈ 0.75 mm)
SEA_LEVELS = 7  # levels 0..6: 2 mm .. 128 mm texels
SEA_MEAN = 42.0  # mean sea radiance, scene units (sky reflection + upwelling: dark)
SEA_STD = 9.0  # its spatial standard deviation
PAPER_WHITE = 200.0  # the marker plate's white, scene units
INK_BLACK = 8.0  # the marker's black
BUOY_YELLOW = 170.0  # a yellow buoy as a mono sensor sees it
NOISE_TILE_PX = (1024, 1280)  # rows, cols of the precomputed noise tile (cropped at random offsets)
MARKER_TOP_CELL_PX = 96  # cell size of the largest marker mip
MARKER_QUIET_CELLS = 1  # white margin around the marker on its plate, in cells


@functools.lru_cache(maxsize=4)
def sea_levels(seed: int, wave_dir_rad: float = 0.0) -> tuple[U8, ...]:
    """The sea texture at each level of detail: ``SEA_LEVELS`` periodic fields of ``SEA_TEXTURE_PX``², tiled 2×2."""
    rng = np.random.default_rng(seed)
    n = SEA_TEXTURE_PX
    levels = []
    for level in range(SEA_LEVELS):
        texel_m = SEA_TEXEL0_M * 2**level
        k = np.fft.fftfreq(n, d=texel_m)  # cycles per metre
        kn, ke = np.meshgrid(k, k, indexing="ij")
        # stretch across the wave direction: long crests
        along = kn * math.cos(wave_dir_rad) + ke * math.sin(wave_dir_rad)
        across = -kn * math.sin(wave_dir_rad) + ke * math.cos(wave_dir_rad)
        kk = np.hypot(along, 2.0 * across)
        kk[0, 0] = np.inf
        # amplitude ∝ k^-1.5 (power ∝ k^-3), band 0.5 .. 200 cycles/m
        amplitude = np.where((kk > 0.5) & (kk < 200.0), kk**-1.5, 0.0)
        spectrum = amplitude * np.exp(2j * np.pi * rng.random((n, n)))
        field = np.real(np.fft.ifft2(spectrum))
        field /= max(float(np.std(field)), 1e-12)
        # crests facing the sky reflect more: a skewed brightness
        radiance = SEA_MEAN + SEA_STD * (field + 0.25 * np.maximum(field, 0.0) ** 2 - 0.125)
        # tiled 2×2 so that a frame's footprint fits without a (slow) wrapping border
        levels.append(np.tile(np.clip(radiance, 0, 255).astype(np.uint8), (2, 2)))
    return tuple(levels)


@dataclass(frozen=True, slots=True)
class MarkerPlate:
    """Mip levels of a marker on its white plate; ``marker_frac`` = marker edge / plate edge."""

    mips: tuple[U8, ...]  # largest first; mips[i] has side ``plate_px >> i``
    marker_frac: float

    @property
    def plate_px(self) -> int:
        return int(self.mips[0].shape[0])


def _marker_image(dictionary: cv2.aruco.Dictionary, marker_id: int, side_px: int) -> U8:
    img = cv2.aruco.generateImageMarker(dictionary, marker_id, side_px, borderBits=1)
    return np.where(img > 127, PAPER_WHITE, INK_BLACK).astype(np.uint8)


@functools.lru_cache(maxsize=8)
def marker_plate(dictionary_name: str, marker_id: int, nested_ids: tuple[int, ...] = ()) -> MarkerPlate:
    """The marker (and its nested markers, concentric) on a plate with a one-cell white margin.

    Nesting convention (the detector uses the same, ``app.sensors.detect_marker.nested_size_ratio``): each
    nested marker's edge is half a cell of the marker it sits in, centred, with a one-cell quiet zone of its own.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary_name))
    cells = int(dictionary.markerSize) + 2
    cell = MARKER_TOP_CELL_PX
    marker_px = cells * cell
    plate_px = marker_px + 2 * MARKER_QUIET_CELLS * cell
    plate = np.full((plate_px, plate_px), PAPER_WHITE, np.uint8)
    m0 = MARKER_QUIET_CELLS * cell
    plate[m0 : m0 + marker_px, m0 : m0 + marker_px] = _marker_image(dictionary, marker_id, marker_px)
    edge = marker_px
    for nested_id in nested_ids:
        edge = edge // (2 * cells)
        if edge < cells:
            break
        quiet = edge // cells
        block = edge + 2 * quiet
        start = (plate_px - block) // 2
        plate[start : start + block, start : start + block] = PAPER_WHITE
        plate[start + quiet : start + quiet + edge, start + quiet : start + quiet + edge] = _marker_image(
            dictionary, nested_id, edge
        )
    mips = [plate]
    while mips[-1].shape[0] > 16:
        mips.append(np.asarray(cv2.resize(mips[-1], None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)))
    return MarkerPlate(tuple(mips), marker_px / plate_px)


@functools.lru_cache(maxsize=2)
def buoy_sprite(side_px: int = 256) -> tuple[U8, U8]:
    """A floating sphere seen from above: (radiance, alpha) of ``side_px``², the disc filling the square."""
    r = (np.arange(side_px) + 0.5 - side_px / 2) / (side_px / 2)
    x, y = np.meshgrid(r, r)
    rho2 = x * x + y * y
    inside = np.clip((1.0 - np.sqrt(rho2)) * side_px / 2, 0.0, 1.0)  # anti-aliased edge, one texel wide
    mu = np.sqrt(np.clip(1.0 - rho2, 0.0, 1.0))  # cosine of the view angle on the sphere
    highlight = np.exp(-((x + 0.3) ** 2 + (y + 0.3) ** 2) / 0.02)
    radiance = BUOY_YELLOW * (0.55 + 0.45 * mu) + 60.0 * highlight
    return np.clip(radiance, 0, 255).astype(np.uint8), (inside * 255).astype(np.uint8)


@functools.lru_cache(maxsize=1)
def glare_sprite(side_px: int = 128) -> U8:
    """A smooth round glare blob (sun reflection / lens flare), 255 in the centre."""
    r = (np.arange(side_px) + 0.5 - side_px / 2) / (side_px / 2)
    x, y = np.meshgrid(r, r)
    fall = np.exp(-(x * x + y * y) * 4.0)
    return (255.0 * np.clip((fall - math.exp(-4.0)) / (1.0 - math.exp(-4.0)), 0.0, 1.0)).astype(np.uint8)


@functools.lru_cache(maxsize=2)
def noise_tile(seed: int, std_dn: float) -> NDArray[np.int16]:
    """Zero-mean Gaussian sensor noise of ``std_dn`` grey levels (int16), cropped at random offsets per frame."""
    rng = np.random.default_rng(seed + 7919)
    return np.round(rng.standard_normal(NOISE_TILE_PX) * std_dn).astype(np.int16)
