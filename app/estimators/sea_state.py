"""WMO sea-state codes 0–5 with the significant wave height and peak period the filters and simulator use.

Hs is the upper bound of each WMO band (conservative); Tp follows a fully developed Pierson–Moskowitz sea:
ω_p = 0.877 g/U and Hs = 0.21 U²/g give Tp = 2π/ω_p ≈ 4.99·√Hs s (code 1: at least 1.6 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class SeaState:
    code: int
    hs_m: float
    tp_s: float
    name: str


def _pm_tp_s(hs_m: float) -> float:
    return 2.0 * math.pi / (0.877 * math.sqrt(0.21 * 9.81 / hs_m)) if hs_m > 0 else 0.0


SEA_STATES: dict[int, SeaState] = {
    code: SeaState(code, hs, max(_pm_tp_s(hs), 1.6) if hs > 0 else 0.0, name)
    for code, hs, name in (
        (0, 0.0, "calm (glassy)"),
        (1, 0.1, "calm (rippled)"),
        (2, 0.5, "smooth"),
        (3, 1.25, "slight"),
        (4, 2.5, "moderate"),
        (5, 4.0, "rough"),
    )
}
