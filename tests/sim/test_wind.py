"""Wind: mean direction (meteorological "from"), gust statistics, determinism."""

from __future__ import annotations

import math

import numpy as np

from sim.wind import Wind, WindConfig


def test_mean_wind_blows_away_from_the_from_direction() -> None:
    wind = Wind(WindConfig(mean_mps=5.0, from_deg=240.0, gust_sigma_mps=0.0, vertical_sigma_mps=0.0))
    n, e, d = wind.step(0.1)
    # From 240° (south-west) → the air moves towards 060°: north and (more) east.
    assert math.isclose(n, 5.0 * math.cos(math.radians(60.0)), abs_tol=1e-9)
    assert math.isclose(e, 5.0 * math.sin(math.radians(60.0)), abs_tol=1e-9)
    assert d == 0.0


def test_gusts_have_the_configured_std_and_correlation_time() -> None:
    config = WindConfig(mean_mps=0.0, gust_sigma_mps=1.0, gust_tau_s=3.0)
    wind = Wind(config, seed=7)
    dt_s = 0.1
    samples = np.array([wind.step(dt_s) for _ in range(60_000)])
    assert abs(samples[:, 0].std() - 1.0) < 0.1
    assert abs(samples[:, 1].std() - 1.0) < 0.1
    assert samples[:, 2].std() < 0.3  # small vertical gusts
    # Lag-τ autocorrelation of a Gauss–Markov process is e^{-1}.
    x = samples[:, 0] - samples[:, 0].mean()
    lag = int(config.gust_tau_s / dt_s)
    rho = float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))
    assert abs(rho - math.exp(-1.0)) < 0.1


def test_same_seed_same_wind_other_seed_other_wind() -> None:
    a, b, c = Wind(seed=3), Wind(seed=3), Wind(seed=4)
    sa = [a.step(0.005) for _ in range(200)]
    assert sa == [b.step(0.005) for _ in range(200)]
    assert sa != [c.step(0.005) for _ in range(200)]


def test_off_is_still_air() -> None:
    wind = Wind.off()
    assert all(wind.step(0.01) == (0.0, 0.0, 0.0) for _ in range(100))
