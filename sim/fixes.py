"""Synthetic camera fixes of the floating object, with the errors sea-plane triangulation really has.

A vehicle hovers ``height_m`` above the mean sea, loosely above the object (it follows the object's
3-s average with a slowly wandering offset of a couple of metres), and a downward camera sees the object.
Each fix is the ray through the (noisy) pixel scaled to the sea plane at the radar's height:

- pixel noise ``pixel_std_px`` at focal length ``focal_px`` and attitude noise ``attitude_std_rad``
  perturb the ray direction; the horizontal error grows as h/cos²θ along the ray's bearing;
- the radar measures the height to the water *under the vehicle* (±``radar_std_m``), but the object rides
  its own wave: that height error e_v shows up horizontally as e_h = e_v·tan θ (thesis §3.2.1);
- frames come at 10–30 Hz (a new rate every 10 s, ±2 ms jitter), with dropouts (a two-state Markov chain),
  ``false_rate`` false detections anywhere in the footprint, and ``late_rate`` fixes delivered a few
  frames late (their capture time is still right).
The covariance handed to the filter is what triangulation can know: pixel, attitude and radar noise
through the geometry — not the wave-induced height error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.messages import TargetObservation
from sim.sea import FloatingObject, SeaWorld


@dataclass(frozen=True)
class FixConfig:
    height_m: float = 6.0
    focal_px: float = 1000.0
    pixel_std_px: float = 0.7
    attitude_std_rad: float = math.radians(0.3)
    radar_std_m: float = 0.03
    fps_min_hz: float = 10.0
    fps_max_hz: float = 30.0
    mean_on_s: float = 9.0  # dropouts: mean time with fixes …
    mean_off_s: float = 0.6  # … and without
    false_rate: float = 0.02
    late_rate: float = 0.02
    half_fov_rad: float = math.radians(32.0)
    offset_std_m: float = 1.5  # the vehicle's wander around the object's average position
    offset_tau_s: float = 20.0


@dataclass
class FixStream:
    t_s: np.ndarray  # capture times, in delivery order
    z_ne_m: np.ndarray  # (N, 2)
    cov_ne_m2: np.ndarray  # (N, 2, 2)
    down_m: np.ndarray  # (N,)
    is_false: np.ndarray  # (N,) bool
    is_late: np.ndarray  # (N,) bool: delivered after a later capture

    def observations(self) -> list[TargetObservation]:
        return [
            TargetObservation(
                float(t),
                (float(z[0]), float(z[1]), float(d)),
                ((float(c[0, 0]), float(c[0, 1])), (float(c[1, 0]), float(c[1, 1]))),
            )
            for t, z, c, d in zip(self.t_s, self.z_ne_m, self.cov_ne_m2, self.down_m, strict=True)
        ]


def capture_times(cfg: FixConfig, duration_s: float, rng: np.random.Generator) -> np.ndarray:
    times: list[np.ndarray] = []
    t0 = 0.0
    while t0 < duration_s:
        fps = rng.uniform(cfg.fps_min_hz, cfg.fps_max_hz)
        seg = t0 + np.arange(0.0, min(10.0, duration_s - t0), 1.0 / fps)
        times.append(seg + rng.uniform(-0.002, 0.002, seg.size))
        t0 += 10.0
    t = np.sort(np.concatenate(times))
    # dropouts: alternate on/off periods with exponential durations
    keep = np.ones(t.size, dtype=bool)
    s, on = 0.0, True
    while s < duration_s:
        d = rng.exponential(cfg.mean_on_s if on else cfg.mean_off_s)
        if not on:
            keep &= ~((t >= s) & (t < s + d))
        s, on = s + d, not on
    return t[keep & (t > 0.0)]


def ou(t: np.ndarray, std: float, tau_s: float, rng: np.random.Generator) -> np.ndarray:
    """An Ornstein–Uhlenbeck path sampled at times ``t`` (stationary, exact discretisation)."""
    out = np.empty(t.size)
    x = rng.normal(0.0, std)
    prev = t[0] if t.size else 0.0
    for i, ti in enumerate(t):
        a = math.exp(-(ti - prev) / tau_s)
        x = a * x + std * math.sqrt(1.0 - a * a) * rng.normal()
        out[i], prev = x, ti
    return out


def make_fixes(
    sea: SeaWorld, obj: FloatingObject, duration_s: float, seed: int, cfg: FixConfig = FixConfig()
) -> FixStream:
    rng = np.random.default_rng(seed)
    t = capture_times(cfg, duration_s, rng)
    n = t.size
    pos, _, _ = obj.states(t)
    # the vehicle: above the object's 3-s average position plus a wandering offset, at a wandering height
    k = max(1, round(3.0 * n / max(duration_s, 1e-9)))
    kernel = np.ones(k) / k
    avg = np.stack([np.convolve(np.pad(pos[:, i], (k - 1, 0), mode="edge"), kernel, mode="valid") for i in (0, 1)], 1)
    cam_ne = avg + np.stack([ou(t, cfg.offset_std_m, cfg.offset_tau_s, rng) for _ in (0, 1)], 1)
    cam_h = cfg.height_m + ou(t, 0.3, 10.0, rng)
    eta_under = np.asarray(sea.surface_elevation_m(t, cam_ne[:, 0], cam_ne[:, 1]), dtype=float)
    h_radar = cam_h - eta_under + rng.normal(0.0, cfg.radar_std_m, n)
    # true ray camera → object (NED, down positive)
    ray = np.column_stack((pos[:, 0] - cam_ne[:, 0], pos[:, 1] - cam_ne[:, 1], cam_h + pos[:, 2]))
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    # perturb its direction by pixel + attitude noise, in two directions orthogonal to it
    sigma = math.hypot(cfg.pixel_std_px / cfg.focal_px, cfg.attitude_std_rad)
    e1 = np.cross(ray, np.array([0.0, 0.0, 1.0]))
    e1[np.linalg.norm(e1, axis=1) < 1e-9] = (1.0, 0.0, 0.0)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(ray, e1)
    noisy = ray + sigma * (rng.normal(size=(n, 1)) * e1 + rng.normal(size=(n, 1)) * e2)
    # scale to the sea plane at the radar height
    z = cam_ne + noisy[:, :2] * (h_radar / noisy[:, 2])[:, None]
    # false detections anywhere in the footprint
    is_false = rng.random(n) < cfg.false_rate
    r_fp = cam_h * math.tan(cfg.half_fov_rad)
    z[is_false] = cam_ne[is_false] + rng.uniform(-1.0, 1.0, (int(is_false.sum()), 2)) * r_fp[is_false, None]
    cov = triangulation_cov(z - cam_ne, h_radar, sigma, math.hypot(cfg.radar_std_m, 0.02))
    # a few fixes arrive late: delivered after the next 2–6 captures
    order = np.arange(n, dtype=float)
    is_late = rng.random(n) < cfg.late_rate
    order[is_late] += rng.integers(2, 7, int(is_late.sum())) + 0.5
    idx = np.argsort(order, kind="stable")
    return FixStream(t[idx], z[idx], cov[idx], pos[idx, 2], is_false[idx], is_late[idx])


def triangulation_cov(d_ne_m: np.ndarray, h_m: np.ndarray, sigma_ang_rad: float, sigma_h_m: float) -> np.ndarray:
    """Horizontal covariance of a sea-plane fix at offset ``d`` from below the camera, height ``h``.

    Along the bearing: (h/cos²θ)²σ_ang² + (tanθ·σ_h)²; across it: (h/cosθ)²σ_ang².
    """
    r = np.linalg.norm(d_ne_m, axis=1)
    tan_t = r / h_m
    cos_t = 1.0 / np.sqrt(1.0 + tan_t**2)
    along = (h_m / cos_t**2 * sigma_ang_rad) ** 2 + (tan_t * sigma_h_m) ** 2
    across = (h_m / cos_t * sigma_ang_rad) ** 2
    u = np.where(r[:, None] > 1e-9, d_ne_m / np.maximum(r, 1e-9)[:, None], np.array([1.0, 0.0]))
    v = np.column_stack((-u[:, 1], u[:, 0]))
    return along[:, None, None] * u[:, :, None] * u[:, None, :] + across[:, None, None] * v[:, :, None] * v[:, None, :]
