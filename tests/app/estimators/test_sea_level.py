"""The mean sea level under the vehicle: follows a drift without lag, leaves the swell out."""

from __future__ import annotations

import math

import numpy as np

from app.estimators.sea_level import MeanSeaLevel


def feed(level: MeanSeaLevel, surface, t_end_s: float, rate_hz: float = 15.0) -> None:
    for t_s in np.arange(0.0, t_end_s, 1.0 / rate_hz):
        level.update(float(t_s), surface(float(t_s)))


def test_a_constant_drift_is_followed_without_steady_state_lag():
    level = MeanSeaLevel(tau_s=5.0)
    feed(level, lambda t: 0.3 + 0.09 * t, 120.0)  # an altitude estimate drifting 0.09 m/s (PX4 SIH's bias)
    est = level.estimate(120.0)
    assert est is not None
    assert abs(est.down_m - (0.3 + 0.09 * 120.0)) < 0.01 and abs(est.rate_mps - 0.09) < 0.002


def test_the_swell_is_attenuated_to_what_the_loop_bandwidth_allows():
    level = MeanSeaLevel(tau_s=5.0, damping=0.8)
    a_m, w = 0.25, 1.8  # a sea-state-2 swell: ±0.25 m at 1.8 rad/s
    seen = []
    for t_s in np.arange(0.0, 200.0, 1.0 / 15.0):
        level.update(float(t_s), 2.0 + a_m * math.sin(w * t_s))
        if t_s > 60.0:
            est = level.estimate(float(t_s))
            assert est is not None
            seen.append(est.down_m - 2.0)
    residual = max(abs(v) for v in seen)
    print(f"residual ±{residual:.3f} m of a ±{a_m} m swell")
    assert residual <= a_m * 2.0 * 0.8 * (1.0 / 5.0) / w * 1.3  # ≈ 2ζω/ω_wave of the swell, with margin
    assert residual > 0.0


def test_bad_samples_change_nothing_and_a_gap_starts_over():
    level = MeanSeaLevel(tau_s=5.0, max_gap_s=2.0)
    assert level.estimate(0.0) is None
    feed(level, lambda t: 1.0, 10.0)
    before = level.estimate(10.0)
    level.update(10.1, math.nan)
    level.update(math.inf, 3.0)
    level.update(5.0, 9.0)  # older than the newest: ignored
    assert level.estimate(10.0) == before
    assert level.estimate(13.0) is None  # nothing for longer than the gap
    level.update(20.0, 4.0)
    est = level.estimate(20.0)
    assert est is not None and est.down_m == 4.0 and est.rate_mps == 0.0


def test_the_crest_is_the_highest_rise_above_the_level_within_the_window():
    level = MeanSeaLevel(tau_s=5.0, crest_window_s=30.0)
    assert level.crest_m() == 0.0
    # a sea-state-3 swell: ±0.6 m at 1.2 rad/s (down positive: a crest is a smaller down)
    feed(level, lambda t: 2.0 - 0.6 * math.sin(1.2 * t), 120.0)
    crest = level.crest_m()
    print(f"crest {crest:.3f} m over the level")
    assert 0.55 <= crest <= 0.75  # the swell's amplitude, plus what the level moves with it
    # the sea calms: the old crests leave the window, and only the new ones count
    for t_s in np.arange(120.0, 200.0, 1.0 / 15.0):
        level.update(float(t_s), 2.0 - 0.1 * math.sin(1.2 * t_s))
    assert 0.08 <= level.crest_m() <= 0.2


def test_how_fast_the_water_rises_is_the_swell_s_slope_now_and_unknown_after_a_gap():
    level = MeanSeaLevel()  # the slope over RATE_WINDOW_S, 0.4 s
    a_m, w = 0.5, 1.2
    rng = np.random.default_rng(3)
    errors = []
    for t_s in np.arange(0.0, 30.0, 0.1):  # the radar at 10 Hz, 2 cm noise; down positive: a crest is −a
        level.update(float(t_s), 3.0 - a_m * math.sin(w * t_s) + float(rng.normal(0.0, 0.02)))
        rate = level.rise_rate_mps(float(t_s))
        if t_s >= 0.3:
            assert rate is not None
            # the slope of the last 0.4 s: the true rise rate 0.2 s ago, within the noise's share (a slope over
            # 5 samples 0.1 s apart with 2 cm noise: σ = 0.02/√0.1 ≈ 0.063 m/s)
            true_mps = a_m * w * math.cos(w * (t_s - 0.2))
            errors.append(rate - true_mps)
            if abs(true_mps) > 0.3:  # a crest rising, or falling away: told apart every time
                assert (rate > 0.0) == (true_mps > 0.0)
    rms = float(np.sqrt(np.mean(np.square(errors))))
    print(f"rise rate error: rms {rms:.3f}, max {np.max(np.abs(errors)):.3f} m/s")
    assert rms < 0.09 and np.max(np.abs(errors)) < 0.25
    assert level.rise_rate_mps(30.5) is None  # nothing in the last 0.4 s: the radar reads nothing
    level.update(33.0, 3.0)  # a gap longer than max_gap_s starts over
    assert level.rise_rate_mps(33.0) is None
