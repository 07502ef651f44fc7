"""Seeded wind: a steady mean plus Gauss–Markov gusts.

Frames and units: the output is the air velocity in the local NED frame, metres per second
(``wind_ned_mps`` = where the air moves *to*). The mean is given the meteorological way: a speed and the
direction the wind blows *from*, in degrees clockwise from north (240° = from the south-west, so the air
moves towards 060°).

Gusts are one first-order Gauss–Markov (Ornstein–Uhlenbeck) process per axis, stepped with the exact
discretisation, so the statistics do not depend on the step size::

    g[k+1] = φ g[k] + σ √(1 − φ²) w[k],   φ = exp(−dt/τ),   w ~ N(0, 1)

with stationary standard deviation σ (``gust_sigma_mps`` horizontally, ``vertical_sigma_mps``
vertically) and correlation time τ. Pure: no clock, randomness only from a seeded ``numpy`` Generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.noise import NormalBatches

Vec3 = tuple[float, float, float]
_BATCH = 512


@dataclass(frozen=True, slots=True)
class WindConfig:
    """Wind parameters; ``mean_mps`` from ``from_deg`` (meteorological), gusts as OU processes."""

    mean_mps: float = 5.0
    from_deg: float = 240.0
    gust_sigma_mps: float = 1.0
    gust_tau_s: float = 3.0
    vertical_sigma_mps: float = 0.15
    vertical_tau_s: float = 1.0

    @classmethod
    def off(cls) -> WindConfig:
        """Still air."""
        return cls(mean_mps=0.0, gust_sigma_mps=0.0, vertical_sigma_mps=0.0)

    def mean_ned_mps(self) -> Vec3:
        """The steady part: air moving *towards* ``from_deg + 180°``."""
        from_rad = math.radians(self.from_deg)
        return (-self.mean_mps * math.cos(from_rad), -self.mean_mps * math.sin(from_rad), 0.0)


class Wind:
    """Wind at the vehicle, stepped in time; deterministic for a seed."""

    def __init__(self, config: WindConfig | None = None, seed: int = 0) -> None:
        self.config = config if config is not None else WindConfig()
        self._rng = np.random.default_rng(seed)
        self._draws = NormalBatches(self._rng, 3, _BATCH)  # drawn at the first step, after the start's
        self._mean_ned_mps = self.config.mean_ned_mps()
        sigma = self.config
        # Start the gusts in their stationary distribution, so there is no warm-up transient.
        self._gust_ned_mps = [
            sigma.gust_sigma_mps * float(self._rng.standard_normal()),
            sigma.gust_sigma_mps * float(self._rng.standard_normal()),
            sigma.vertical_sigma_mps * float(self._rng.standard_normal()),
        ]
        self._axes = (
            (sigma.gust_sigma_mps, sigma.gust_tau_s),
            (sigma.gust_sigma_mps, sigma.gust_tau_s),
            (sigma.vertical_sigma_mps, sigma.vertical_tau_s),
        )
        self._dt_s = math.nan  # the step the coefficients below are for
        self._coefficients: list[tuple[float, float | None]] = []  # per axis (φ, σ √(1 − φ²))

    @classmethod
    def off(cls) -> Wind:
        """Still air (no mean, no gusts)."""
        return cls(WindConfig.off(), seed=0)

    @property
    def wind_ned_mps(self) -> Vec3:
        """The current air velocity (mean + gusts), NED, m/s."""
        m, g = self._mean_ned_mps, self._gust_ned_mps
        return (m[0] + g[0], m[1] + g[1], m[2] + g[2])

    def step(self, dt_s: float) -> Vec3:
        """Advance the gusts by ``dt_s`` seconds and return the new air velocity (NED, m/s)."""
        if dt_s <= 0.0:
            return self.wind_ned_mps
        w = self._draws.next()
        if dt_s != self._dt_s:
            # φ = exp(−dt/τ), and σ √(1 − φ²): the same for every step of this length
            self._dt_s, self._coefficients = dt_s, [_ou_coefficients(s, tau, dt_s) for s, tau in self._axes]
        g = self._gust_ned_mps
        for axis, (phi, sigma_w) in enumerate(self._coefficients):
            # g ← φ g + σ √(1 − φ²) w   (no gusts: g = 0)
            g[axis] = phi * g[axis] + sigma_w * w[axis] if sigma_w is not None else 0.0
        m = self._mean_ned_mps
        return (m[0] + g[0], m[1] + g[1], m[2] + g[2])


def _ou_coefficients(sigma_mps: float, tau_s: float, dt_s: float) -> tuple[float, float | None]:
    """φ = exp(−dt/τ) and σ √(1 − φ²) for one axis (None: no gusts on it)."""
    if sigma_mps <= 0.0:
        return 0.0, None
    phi = math.exp(-dt_s / tau_s)
    return phi, sigma_mps * math.sqrt(1.0 - phi * phi)
