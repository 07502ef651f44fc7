"""The autopilot's state estimate: the truth plus a seeded, slowly varying error (what EKF2/EKF3 would report).

A real autopilot controls and reports an *estimate*. Its velocity error is correlated over seconds, its
vertical velocity may carry a bias, and its position drifts (GNSS wander, baro drift), and the estimate is
not even consistent with itself: d(position)/dt differs from the reported velocity. Per axis::

    e_v   ← Gauss–Markov(σ_v, τ_v)                       velocity error, m/s
    v̂     = v + e_v + b_v                                b_v: constant velocity bias (NED, m/s)
    ṙ     = Gauss–Markov(σ_r, τ_r)                       drift rate, m/s
    ė_p   = ṙ − e_p / τ_leak                             position drift (bounded by the leak), m
    p̂     = p + e_p
    φ̂, θ̂  = φ + Gauss–Markov(σ_tilt, τ_tilt), θ + Gauss–Markov(σ_tilt, τ_tilt)      roll and pitch, rad

Gauss–Markov: x ← x·e^{−dt/τ} + σ·√(1 − e^{−2dt/τ})·N(0, 1), stationary at σ (it starts drawn from
that distribution). ``sim.dynamics`` runs its velocity controller on v̂ (and ArduCopter's position target on
p̂), so the bias becomes a real drift of the vehicle that only the reported position reveals. The tilt error is
only reported (the camera images with the true attitude; the app triangulates with the reported one); it has its
own random stream, so the position and velocity errors of a seed are those they were before it existed.

Presets (``ESTIMATORS``):
- ``perfect``: no error (unit tests of the dynamics and the old behaviour).
- ``gnss`` (the default): a GNSS-aided EKF on a real airframe with a good receiver (u-blox M8/M9 class:
  speed accuracy ~0.05 m/s, horizontal position wander of a few decimetres over minutes, baro drift of
  a few decimetres): σ_v 0.05 / 0.03 m/s (h / v) with τ_v 3 s, a 0.02 m/s downward bias, position drift
  rate σ_r 0.01 m/s with τ_r 10 s and a 60 s leak (σ_p = σ_r·τ_leak·√(τ_r/(τ_r + τ_leak)) ≈ 0.23 m); a roll
  and pitch error of σ 0.3° with τ 10 s (EKF2/EKF3 tilt accuracy with a good IMU, a few tenths of a degree,
  slowly varying: the figure is this project's choice, not a measurement).
- ``px4-sih``: what PX4 SIH's EKF2 reported against SIH's truth in the recording
  (``shared/reference/autopilot-response``): velocity error 0.22 / 0.27 m/s RMS north / east with a
  correlation time of 3.6–3.9 s, vertical 0.135 m/s with 2.9 s and a +0.09 m/s (down) bias (README:
  +0.08…+0.11; 0.11 over the whole step flight), position error within ±0.65 m of its start; the recordings do
  not give the attitude's error: the same tilt error as ``gnss``.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from sim.noise import NormalBatches
from sim.wind import Vec3


@dataclass(frozen=True, slots=True)
class EstimatorErrorParams:
    vel_sigma_mps: tuple[float, float] = (0.0, 0.0)  # horizontal (each axis), vertical
    vel_tau_s: tuple[float, float] = (3.0, 3.0)
    vel_bias_ned_mps: Vec3 = (0.0, 0.0, 0.0)
    drift_rate_sigma_mps: tuple[float, float] = (0.0, 0.0)
    drift_rate_tau_s: float = 10.0
    drift_leak_tau_s: float = 60.0
    tilt_sigma_rad: float = 0.0  # roll and pitch error (each), rad
    tilt_tau_s: float = 10.0

    def is_perfect(self) -> bool:
        return (
            self.vel_sigma_mps == (0.0, 0.0)
            and self.vel_bias_ned_mps == (0.0, 0.0, 0.0)
            and self.drift_rate_sigma_mps == (0.0, 0.0)
            and self.tilt_sigma_rad == 0.0
        )


PERFECT = EstimatorErrorParams()
GNSS = EstimatorErrorParams(
    vel_sigma_mps=(0.05, 0.03),
    vel_tau_s=(3.0, 3.0),
    vel_bias_ned_mps=(0.0, 0.0, 0.02),
    drift_rate_sigma_mps=(0.01, 0.01),
    tilt_sigma_rad=math.radians(0.3),
)
PX4_SIH = EstimatorErrorParams(
    vel_sigma_mps=(0.24, 0.135),
    vel_tau_s=(3.7, 2.9),
    vel_bias_ned_mps=(0.0, 0.0, 0.09),
    drift_rate_sigma_mps=(0.03, 0.03),
    tilt_sigma_rad=math.radians(0.3),
)
ESTIMATORS: dict[str, EstimatorErrorParams] = {"perfect": PERFECT, "gnss": GNSS, "px4-sih": PX4_SIH}


_BATCH = 1024  # normal draws made at a time (one per process per step)


class _GaussMarkovBank:
    """Gauss–Markov processes stepped together, their N(0, 1) draws taken from ``rng`` a batch at a time (a step
    costs one list lookup per process, not a call into the generator): ``x ← x·a + σ·√(1 − a²)·w``."""

    def __init__(self, sigmas: tuple[float, ...], taus_s: tuple[float, ...], rng: np.random.Generator) -> None:
        self.sigmas, self.taus_s = sigmas, taus_s
        # stationary from the start: x drawn from N(0, σ²)
        self.x = [s * w for s, w in zip(sigmas, rng.standard_normal(len(sigmas)).tolist(), strict=True)]
        self._draws = NormalBatches(rng, len(sigmas), _BATCH)
        self._dt_s = math.nan
        self._coefficients: list[tuple[int, float, float]] = []  # (process, a = e^{−dt/τ}, σ·√(1 − a²)), σ > 0

    def step(self, dt_s: float) -> list[float]:
        if dt_s != self._dt_s:
            self._dt_s = dt_s
            self._coefficients = []
            for i, (sigma, tau_s) in enumerate(zip(self.sigmas, self.taus_s, strict=True)):
                if sigma > 0.0:
                    a = math.exp(-dt_s / tau_s)
                    self._coefficients.append((i, a, sigma * math.sqrt(1.0 - a * a)))
        if not self._coefficients:
            return self.x
        w = self._draws.next()
        x = self.x
        for i, a, b in self._coefficients:
            x[i] = x[i] * a + b * w[i]
        return x


def _rng(name: str) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(name.encode()))


class EstimatorError:
    """The error state; ``step`` advances it, ``apply`` turns the truth into the estimate."""

    def __init__(self, params: EstimatorErrorParams, seed: int = 0) -> None:
        self.params = params
        (sh, sv), (th, tv) = params.vel_sigma_mps, params.vel_tau_s
        rh, rv = params.drift_rate_sigma_mps
        tr = params.drift_rate_tau_s
        # velocity error north/east/down, then the drift rates north/east/down
        self._vel_rate = _GaussMarkovBank((sh, sh, sv, rh, rh, rv), (th, th, tv, tr, tr, tr), _rng(f"estimator-{seed}"))
        self.pos_err_m = [0.0, 0.0, 0.0]
        # its own stream: the others' draws stay as they are with or without it
        ts, tt = params.tilt_sigma_rad, params.tilt_tau_s
        self._tilt = _GaussMarkovBank((ts, ts), (tt, tt), _rng(f"estimator-tilt-{seed}"))

    @property
    def vel_err_mps(self) -> Vec3:
        b, x = self.params.vel_bias_ned_mps, self._vel_rate.x
        return (x[0] + b[0], x[1] + b[1], x[2] + b[2])

    @property
    def tilt_err_rad(self) -> tuple[float, float]:
        """The reported roll and pitch minus the true ones, rad."""
        x = self._tilt.x
        return x[0], x[1]

    def step(self, dt_s: float) -> None:
        leak = self.params.drift_leak_tau_s
        e_p = self.pos_err_m
        x = self._vel_rate.step(dt_s)
        # ė_p = ṙ − e_p / τ_leak
        e_p[0] += (x[3] - e_p[0] / leak) * dt_s
        e_p[1] += (x[4] - e_p[1] / leak) * dt_s
        e_p[2] += (x[5] - e_p[2] / leak) * dt_s
        self._tilt.step(dt_s)

    def apply(self, pos_ned_m: Vec3, vel_ned_mps: Vec3) -> tuple[Vec3, Vec3]:
        e_p, e_v = self.pos_err_m, self.vel_err_mps
        return (
            (pos_ned_m[0] + e_p[0], pos_ned_m[1] + e_p[1], pos_ned_m[2] + e_p[2]),
            (vel_ned_mps[0] + e_v[0], vel_ned_mps[1] + e_v[1], vel_ned_mps[2] + e_v[2]),
        )
