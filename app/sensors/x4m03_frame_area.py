"""How the X4 firmware quantises the frame area in baseband mode, and the range axis that results. Pure.

``x4driver_set_frame_area`` (reference §6)::

    dR = 8·c/(2·fs) = 0.0514403 m          frame step = 96·c/(2·fs) = 0.617284 m,   fs = 23.328 GS/s
    d    = max(floor((start − offset)/step), −1);   fs_q = d·step + offset
    s    = max(start, fs_q);                        e    = min(end, dR·(192 − 4 − 1) + fs_q)
    i_s  = floor((s − fs_q)/dR) + 4  (ceil within 1e-4);   i_e = ceil((e − fs_q)/dR) + 4  (floor within 1e-4)
    start_q = (i_s − 4)·dR + fs_q;   end_q = (i_e − 4)·dR + fs_q;   bins = i_e − i_s + 1;   r[k] = start_q + k·dR

The thesis's ``range[k] = k·8·c/(2·fs) + 0.4`` puts bin 0 1.4 cm too far: use ``start_q`` (what
``get_frame_area`` returns).
"""

from __future__ import annotations

import math

from app.messages import RangeAxis

C_MPS = 3.0e8  # the firmware's c (it uses 1.5e8 for c/2)
SAMPLE_RATE_HZ = 23.328e9
BASEBAND_BIN_M = 8 * (C_MPS / 2) / SAMPLE_RATE_HZ  # 0.0514403 m
FRAME_STEP_M = 96 * (C_MPS / 2) / SAMPLE_RATE_HZ  # 0.617284 m
MAX_BINS = 192
DISCARDED_BINS = 4
_TOL = 1e-4


def quantise_frame_area(start_m: float, end_m: float, offset_m: float) -> RangeAxis:
    """The range axis the firmware makes of a requested area (downconversion 1); ValueError if start > end."""
    if start_m > end_m:
        raise ValueError(f"frame area start {start_m} m is after its end {end_m} m")
    d = max(math.floor((start_m - offset_m) / FRAME_STEP_M), -1)
    fs_q = d * FRAME_STEP_M + offset_m
    s = max(start_m, fs_q)
    e = min(end_m, BASEBAND_BIN_M * (MAX_BINS - DISCARDED_BINS - 1) + fs_q)
    x = (s - fs_q) / BASEBAND_BIN_M
    i_s = math.ceil(x) if math.ceil(x) - x < _TOL else math.floor(x)
    y = (e - fs_q) / BASEBAND_BIN_M
    i_e = math.floor(y) if y - math.floor(y) < _TOL else math.ceil(y)
    return RangeAxis(start_m=i_s * BASEBAND_BIN_M + fs_q, bin_m=BASEBAND_BIN_M, bins=i_e - i_s + 1)


def axis_from_frame_area(start_q_m: float, end_q_m: float, bins: int) -> RangeAxis:
    """The axis from what the device reports (``get_frame_area``, bin count): bins spaced evenly start..end."""
    if bins < 2:
        raise ValueError(f"a frame needs at least 2 bins, got {bins}")
    return RangeAxis(start_m=start_q_m, bin_m=(end_q_m - start_q_m) / (bins - 1), bins=bins)
