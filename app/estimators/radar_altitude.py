"""Radar altitude: height above the sea from X4M03 baseband frames (thesis §4.2.2 and §5.1.4). Pure.

Per frame z (complex baseband per bin k, on the frame's range axis r[k] — the quantised one the device
reports, not the thesis's approximate formula):

    background map (thesis §4.2.2):   e[k] = z[k] − B[k],   B = mean of N frames taken with the sea out of range
    clutter map    (thesis eq. 5.1):  e[k] = z[k] − C[k],   then C[k] ← α z[k] + (1 − α) C[k]   (C₀ = first frame)
    amplitude:                        a[k] = |e[k]|
    threshold:                        T[k] = max(T_abs, κ σ[k])   σ: noise per bin (calibration), or for the
                                      clutter map the frame's robust noise level median(a)/√(ln 4)
    candidate:                        k* = argmax a[k] inside the gate |r[k] − r_last| ≤ g + v_max·Δt when
                                      tracking (Δt since the last accepted one), over every bin ≥ r_min
                                      when not; accepted if a[k*] ≥ T[k*]
    sub-bin peak (Gaussian pulse):    δ = (ln a₋ − ln a₊) / (2 (ln a₋ − 2 ln a₀ + ln a₊)),   R = r[k*] + δ·Δr
    or leading edge (``peak``):       the first return rather than the strongest: bins j, j+1 where the
                                      echo rises through half its peak, R = r̄ + σ_p² ln(a_j+1/a_j)/Δr
                                      (exact for one Gaussian pulse of known σ_p; a rough sea's off-nadir
                                      glints come later and pull the peak long, not the leading edge)
    tilt (specular sea):              h_a = R          (a mirror returns from the nadir whatever the tilt)
         (boresight, diffuse ground): h_a = R cos φ cos θ
    lever arm o (antenna from the reference point, body FRD):
                                      h = h_a + (R_nb o)_down = h_a − sin θ o_x + sin φ cos θ o_y + cos φ cos θ o_z
    timeout:                          no accepted candidate for ``timeout_s`` → "lost" (search all bins again)
    edges:                            a maximum in the first or last bin of the axis is not a peak (the echo
                                      may lie beyond it): never accepted
    non-finite frames:                a frame with a NaN or inf in any bin is rejected and counted
                                      (``rejected_non_finite``) and changes nothing — not the clutter map, not
                                      the track (one bad frame would otherwise poison the map for good)

Both maps work on the complex baseband, not on amplitudes as the thesis did: the static direct path and
body echoes cancel exactly, while the sea echo, whose phase turns every 2 cm of range, does not. The
thesis's amplitude forms are kept as ``domain="amplitude"`` (e = |z| − B_amp; the map on |z|). The
clutter map absorbs an echo that stops moving (the thesis's own caveat): a vehicle hovering over a glassy
sea loses it; a real vehicle's few centimetres of wobble rotate the phase enough to keep it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from app.messages import RadarFrame, RangeAxis
from app.settings import RadarAltitudeSettings

RAYLEIGH_MEDIAN = math.sqrt(math.log(4.0))  # median of |CN(0, 1)|
Status = Literal["tracking", "holding", "lost", "uncalibrated"]


@dataclass(frozen=True, slots=True, eq=False)
class BackgroundCalibration:
    """The background map, or why there is none (``ok`` False and ``reason`` says what to do)."""

    ok: bool
    reason: str
    frames: int
    axis: RangeAxis | None = None
    background: np.ndarray | None = None  # complex mean per bin
    background_amplitude: np.ndarray | None = None  # mean |z| per bin (amplitude domain)
    noise: np.ndarray | None = None  # rms change per bin (complex)


@dataclass(frozen=True, slots=True)
class AltitudeEstimate:
    t_s: float
    status: Status
    altitude_m: float | None  # reference point above the sea; the last accepted one while "holding"
    range_m: float | None  # the strongest echo of this frame after background removal (sub-bin)
    amplitude: float  # its amplitude
    accepted: bool  # this frame gave a new altitude
    age_s: float | None  # since the last accepted candidate


def calibrate_background(frames: Sequence[RadarFrame], config: RadarAltitudeSettings) -> BackgroundCalibration:
    """Average ``frames`` (captured with the sea out of range) into a background map, after checking them."""
    finite = [f for f in frames if np.isfinite(f.baseband).all()]  # a NaN/inf frame would poison the mean
    skipped = len(frames) - len(finite)
    frames, n = finite, len(finite)
    if n < config.calibration_min_frames:
        why = f"need at least {config.calibration_min_frames} frames, got {n}"
        return BackgroundCalibration(False, why + (f" ({skipped} with NaN/inf skipped)" if skipped else ""), n)
    axis = frames[0].axis
    if any(f.axis != axis for f in frames):
        return BackgroundCalibration(False, "the range axis changed during calibration: configure, then calibrate", n)
    z = np.stack([f.baseband for f in frames]).astype(np.complex128)
    mean = z.mean(axis=0)
    change = np.sqrt(np.mean(np.abs(z - mean) ** 2, axis=0))
    # the noise floor from the quietest bins: an echo sweeping through (a descent) must not raise it
    floor = float(np.percentile(change, 10))
    limit = max(config.calibration_max_change, config.calibration_change_factor * floor)
    worst = int(np.argmax(change))
    if change[worst] > limit:
        range_m = axis.start_m + worst * axis.bin_m
        return BackgroundCalibration(
            False,
            f"strong echo at {range_m:.2f} m (rms change {change[worst]:.1e} > {limit:.1e}): the sea is too close "
            f"— climb above {axis.end_m + 0.3:.1f} m and calibrate again",
            n,
        )
    return BackgroundCalibration(True, "ok", n, axis, mean, np.abs(z).mean(axis=0), change)


class RadarAltitudeEstimator:
    """Frames (and the attitude at their time) in, altitude estimates out; deterministic, no clock."""

    def __init__(
        self,
        config: RadarAltitudeSettings | None = None,
        calibration: BackgroundCalibration | None = None,
        antenna_offset_frd_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ):
        """``antenna_offset_frd_m``: the radar's lever arm (``RadarSettings.lever_arm_frd_m``)."""
        self.config = config if config is not None else RadarAltitudeSettings()
        self.antenna_offset_frd_m = antenna_offset_frd_m
        self.calibration: BackgroundCalibration | None = None
        self._clutter: np.ndarray | None = None
        self._last_range_m: float | None = None
        self._last_altitude_m: float | None = None
        self._last_accept_s: float | None = None
        self.rejected_non_finite = 0  # frames with a NaN/inf bin, skipped
        if calibration is not None:
            self.calibrate(calibration)

    def calibrate(self, calibration: BackgroundCalibration) -> None:
        """Use a background map; a failed calibration is refused (ValueError with its reason)."""
        if not calibration.ok:
            raise ValueError(f"calibration failed: {calibration.reason}")
        self.calibration = calibration

    @property
    def tracking(self) -> bool:
        return self._last_range_m is not None

    def update(self, frame: RadarFrame, roll_rad: float = 0.0, pitch_rad: float = 0.0) -> AltitudeEstimate:
        c = self.config
        if not (np.isfinite(frame.baseband).all() and math.isfinite(roll_rad) and math.isfinite(pitch_rad)):
            self.rejected_non_finite += 1
            age_s = None if self._last_accept_s is None else frame.t_s - self._last_accept_s
            status: Status = "holding" if self._last_range_m is not None else "lost"
            return AltitudeEstimate(frame.t_s, status, self._last_altitude_m, None, 0.0, False, age_s)
        residual = self._residual(frame)
        if residual is None:
            return AltitudeEstimate(frame.t_s, "uncalibrated", None, None, 0.0, False, None)
        amplitude, noise = residual
        axis = frame.axis
        strongest = int(np.argmax(amplitude))
        strongest_m = axis.start_m + (strongest + _peak_offset(amplitude, strongest)) * axis.bin_m
        # the gate: around the last accepted range when tracking, all bins beyond r_min when not
        if self._last_accept_s is not None and frame.t_s - self._last_accept_s > c.timeout_s:
            self._last_range_m = self._last_altitude_m = None
        if self._last_range_m is not None and self._last_accept_s is not None:
            half_m = c.gate_m + c.max_range_rate_mps * (frame.t_s - self._last_accept_s)
            lo = math.ceil(axis.bin_of(self._last_range_m - half_m))
            hi = math.floor(axis.bin_of(self._last_range_m + half_m))
        else:
            lo, hi = math.ceil(axis.bin_of(c.min_range_m)), axis.bins - 1
        lo, hi = max(lo, 0), min(hi, axis.bins - 1)
        accepted = False
        if lo <= hi:
            k = lo + int(np.argmax(amplitude[lo : hi + 1]))
            threshold = max(c.threshold_amplitude, c.noise_factor * float(noise[k] if noise.ndim else noise))
            edge = k == 0 or k == axis.bins - 1  # a maximum at the axis's edge: the echo may lie beyond
            if amplitude[k] >= threshold and not edge:
                if c.peak == "leading_edge":
                    range_m = _leading_edge_m(amplitude, k, axis, c.pulse_sigma_m, c.leading_edge_fraction)
                else:
                    range_m = axis.start_m + (k + _peak_offset(amplitude, k)) * axis.bin_m
                self._last_range_m = range_m
                self._last_altitude_m = self._height_m(range_m, roll_rad, pitch_rad)
                self._last_accept_s = frame.t_s
                accepted = True
        age_s = None if self._last_accept_s is None else frame.t_s - self._last_accept_s
        status = "tracking" if accepted else ("holding" if self._last_range_m is not None else "lost")
        return AltitudeEstimate(
            frame.t_s, status, self._last_altitude_m, strongest_m, float(amplitude[strongest]), accepted, age_s
        )

    def _residual(self, frame: RadarFrame) -> tuple[np.ndarray, np.ndarray] | None:
        """|e| per bin and the noise level (per bin, or one number), or None without a usable map."""
        c = self.config
        z = frame.baseband
        if c.method == "background":
            cal = self.calibration
            if cal is None or cal.axis != frame.axis or cal.background is None or cal.noise is None:
                return None
            if c.domain == "complex":
                return np.abs(z - cal.background), cal.noise
            assert cal.background_amplitude is not None
            return np.abs(z) - cal.background_amplitude, cal.noise
        x = z if c.domain == "complex" else np.abs(z).astype(np.complex64)
        if self._clutter is None or self._clutter.shape != x.shape:
            self._clutter = x.astype(np.complex128)  # C₀ = the first frame (thesis)
        e = x - self._clutter
        # C ← α z + (1 − α) C   (eq. 5.1)
        self._clutter = c.clutter_alpha * x + (1.0 - c.clutter_alpha) * self._clutter
        amplitude = np.abs(e) if c.domain == "complex" else e.real
        return amplitude, np.asarray(np.median(np.abs(e)) / RAYLEIGH_MEDIAN)

    def _height_m(self, range_m: float, roll_rad: float, pitch_rad: float) -> float:
        """Range along the return → height of the reference point (tilt geometry + lever arm)."""
        c = self.config
        cos_tilt = math.cos(roll_rad) * math.cos(pitch_rad)
        antenna_m = range_m if c.tilt == "specular" else range_m * cos_tilt
        ox, oy, oz = self.antenna_offset_frd_m
        # (R_nb o)_down = −sin θ o_x + sin φ cos θ o_y + cos φ cos θ o_z
        down_m = -math.sin(pitch_rad) * ox + math.sin(roll_rad) * math.cos(pitch_rad) * oy + cos_tilt * oz
        return antenna_m + down_m


def _peak_offset(amplitude: np.ndarray, k: int) -> float:
    """Sub-bin offset of the peak at ``k`` from a Gaussian (parabola in ln a) through its neighbours."""
    if k <= 0 or k >= amplitude.size - 1:
        return 0.0
    a_minus, a0, a_plus = float(amplitude[k - 1]), float(amplitude[k]), float(amplitude[k + 1])
    if min(a_minus, a0, a_plus) > 0.0:
        l_minus, l0, l_plus = math.log(a_minus), math.log(a0), math.log(a_plus)
    else:  # amplitude-domain residuals can be ≤ 0: plain parabola
        l_minus, l0, l_plus = a_minus, a0, a_plus
    curvature = l_minus - 2.0 * l0 + l_plus
    if curvature >= 0.0:
        return 0.0
    return max(-0.5, min(0.5, 0.5 * (l_minus - l_plus) / curvature))


def _leading_edge_m(amplitude: np.ndarray, k: int, axis: RangeAxis, sigma_m: float, fraction: float) -> float:
    """Range of the first return: the Gaussian through the two bins where the echo's leading edge crosses
    ``fraction`` of its peak, R = (r_j + r_j+1)/2 + σ² (ln a_j+1 − ln a_j)/Δr (exact for one Gaussian pulse)."""
    level = fraction * float(amplitude[k])
    j = k - 1
    while j >= 0 and amplitude[j] >= level:
        j -= 1
    if j < 0 or amplitude[j] <= 0.0 or amplitude[j + 1] <= 0.0:
        return axis.start_m + (k + _peak_offset(amplitude, k)) * axis.bin_m
    r_mid = axis.start_m + (j + 0.5) * axis.bin_m
    return r_mid + sigma_m**2 * math.log(float(amplitude[j + 1]) / float(amplitude[j])) / axis.bin_m
