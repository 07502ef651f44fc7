"""WMO sea-state codes 0–5 with the significant wave height and peak period the filters and simulator use.

Hs is the upper bound of each WMO band (conservative); Tp follows a fully developed Pierson–Moskowitz sea:
ω_p = 0.877 g/U and Hs = 0.21 U²/g give Tp = 2π/ω_p ≈ 4.99·√Hs s (code 1: at least 1.6 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

GRAVITY_MPS2 = 9.80665
MIN_PEAK_PERIOD_S = 1.6


@dataclass(frozen=True, slots=True)
class SeaState:
    """One WMO sea-state code: significant wave height (top of the band) and peak period."""

    code: int
    hs_m: float
    tp_s: float
    name: str


def pm_peak_period_s(hs_m: float) -> float:
    """Peak period of a fully developed Pierson–Moskowitz sea of significant height ``hs_m`` (≈ 4.99 √Hs)."""
    if hs_m <= 0.0:
        return 0.0
    # Hs = 0.21 U²/g  ⇒  U = √(Hs g / 0.21);   ωp = 0.877 g / U
    wind_19_5_mps = math.sqrt(hs_m * GRAVITY_MPS2 / 0.21)
    return max(MIN_PEAK_PERIOD_S, 2.0 * math.pi * wind_19_5_mps / (0.877 * GRAVITY_MPS2))


def pierson_moskowitz(omega_radps: ArrayLike, hs_m: float, tp_s: float) -> NDArray[np.float64]:
    """One-sided Pierson–Moskowitz spectrum S(ω), m²·s/rad (zero for ω ≤ 0 or a flat sea)."""
    omega = np.asarray(omega_radps, dtype=np.float64)
    if hs_m <= 0.0 or tp_s <= 0.0:
        return np.zeros_like(omega)
    omega_p = 2.0 * math.pi / tp_s
    w = np.where(omega > 0.0, omega, 1.0)
    # S = 5/16 Hs² ωp⁴ ω⁻⁵ exp(−5/4 (ωp/ω)⁴)
    s = 5.0 / 16.0 * hs_m**2 * omega_p**4 * w**-5 * np.exp(-1.25 * (omega_p / w) ** 4)
    return np.where(omega > 0.0, s, 0.0)


def peak_wave_slope(hs_m: float, tp_s: float) -> float:
    """The steepest slope of a wave of height ``hs_m`` at the peak period (deep water, L = g Tp² / 2π): π Hs / L.
    Two points ``d`` apart on such a sea differ in height by at most about this times ``d`` (for d ≪ L)."""
    if hs_m <= 0.0 or tp_s <= 0.0:
        return 0.0
    return math.pi * hs_m / (GRAVITY_MPS2 * tp_s**2 / (2.0 * math.pi))


SEA_STATES: dict[int, SeaState] = {
    code: SeaState(code, hs, pm_peak_period_s(hs), name)
    for code, hs, name in (
        (0, 0.0, "calm (glassy)"),
        (1, 0.1, "calm (rippled)"),
        (2, 0.5, "smooth (wavelets)"),
        (3, 1.25, "slight"),
        (4, 2.5, "moderate"),
        (5, 4.0, "rough"),
    )
}
