"""Radar altitude estimator (pure): range axis, sub-bin peak, background and clutter maps, gate, timeout, tilt."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.estimators.radar_altitude import (
    RadarAltitudeEstimator,
    calibrate_background,
)
from app.messages import RadarFrame, RangeAxis
from app.sensors.x4m03_frame_area import quantise_frame_area
from app.settings import RadarAltitudeSettings

AXIS = quantise_frame_area(0.4, 5.0, 0.18)  # 91 bins from 0.385761 m
FC_HZ, C_MPS, SIGMA_M = 7.29e9, 299_792_458.0, 0.055
RNG = np.random.default_rng(7)
R = AXIS.ranges_m()
# what a background map must remove: direct-path coupling and a landing-gear echo, fixed phases
STATIC = 0.029 * np.exp(-(R - 0.334) / 0.09) * np.exp(1j * RNG.uniform(0, 2 * np.pi, AXIS.bins))
STATIC = STATIC + 0.004 * np.exp(-((R - 0.45) ** 2) / (2 * SIGMA_M**2))


def echo(range_m: float, amplitude: float) -> np.ndarray:
    phase = -4 * math.pi * FC_HZ * range_m / C_MPS
    return amplitude * np.exp(-((R - range_m) ** 2) / (2 * SIGMA_M**2)) * np.exp(1j * phase)


def frame(t_s: float, *echoes: tuple[float, float], noise: float = 1.8e-5, static: bool = True) -> RadarFrame:
    z = (STATIC if static else 0) + sum((echo(r, a) for r, a in echoes), np.zeros(AXIS.bins, complex))
    z = z + noise * (RNG.standard_normal(AXIS.bins) + 1j * RNG.standard_normal(AXIS.bins))
    return RadarFrame(t_s, int(t_s * 10), AXIS, z.astype(np.complex64))


def calibrated(
    config: RadarAltitudeSettings | None = None, antenna_offset_frd_m=(0.0, 0.0, 0.0)
) -> RadarAltitudeEstimator:
    config = config or RadarAltitudeSettings()
    calibration = calibrate_background([frame(-3 + 0.1 * k) for k in range(20)], config)
    assert calibration.ok, calibration.reason
    return RadarAltitudeEstimator(config, calibration, antenna_offset_frd_m)


def test_ranges_come_from_the_quantised_frame_area_not_the_thesis_formula():
    est = calibrated()
    e = est.update(frame(0.0, (1.0, 0.01)))
    assert e.status == "tracking" and e.accepted
    assert e.altitude_m == pytest.approx(1.0, abs=0.002)  # the thesis's k·Δr + 0.4 would be 1.4 cm long


@pytest.mark.parametrize("fraction", np.linspace(0.0, 0.9, 7))
def test_sub_bin_interpolation_finds_the_echo_between_bins(fraction):
    range_m = AXIS.start_m + (30 + fraction) * AXIS.bin_m
    assert calibrated().update(frame(0.0, (range_m, 0.005))).altitude_m == pytest.approx(range_m, abs=0.002)


def test_background_map_lets_a_weak_sea_echo_through_a_strong_direct_path():
    uncalibrated = RadarAltitudeEstimator(RadarAltitudeSettings())
    assert uncalibrated.update(frame(0.0, (2.5, 0.002))).status == "uncalibrated"
    e = calibrated().update(frame(0.0, (2.5, 0.002)))
    assert e.altitude_m == pytest.approx(2.5, abs=0.005)
    assert e.range_m == pytest.approx(2.5, abs=0.005) and e.amplitude == pytest.approx(0.002, rel=0.1)


def test_calibration_with_the_sea_in_range_fails_and_says_why():
    config = RadarAltitudeSettings()
    rng = np.random.default_rng(1)
    sea = [frame(0.1 * k, (3.0 + rng.normal(0, 0.02), 0.004 * rng.rayleigh())) for k in range(20)]
    result = calibrate_background(sea, config)
    assert not result.ok
    assert "strong echo at 3.0" in result.reason and "the sea is too close" in result.reason
    with pytest.raises(ValueError, match="calibration failed: strong echo"):
        RadarAltitudeEstimator(config, result)


def test_calibration_needs_enough_frames_on_one_axis():
    config = RadarAltitudeSettings(calibration_min_frames=10)
    assert calibrate_background([frame(0.0)] * 3, config).reason == "need at least 10 frames, got 3"
    other = RadarFrame(0.0, 0, RangeAxis(0.3, AXIS.bin_m, AXIS.bins), frame(0.0).baseband)
    assert "range axis changed" in calibrate_background([frame(0.0)] * 10 + [other], config).reason


def test_an_echo_below_the_threshold_is_not_an_altitude():
    e = calibrated(RadarAltitudeSettings(threshold_amplitude=0.005)).update(frame(0.0, (2.0, 0.002)))
    assert e.status == "lost" and e.altitude_m is None and not e.accepted
    assert e.range_m == pytest.approx(2.0, abs=0.01)  # the strongest echo is still reported


def test_the_gate_keeps_the_track_when_a_stronger_echo_appears_elsewhere():
    est = calibrated()
    est.update(frame(0.0, (2.0, 0.004)))
    e = est.update(frame(0.1, (2.02, 0.004), (4.0, 0.02)))
    assert e.altitude_m == pytest.approx(2.02, abs=0.005)
    assert e.range_m == pytest.approx(4.0, abs=0.01)  # strongest, but outside the gate


def test_no_echo_holds_the_last_altitude_until_the_timeout_then_lost_then_reacquires_anywhere():
    est = calibrated(RadarAltitudeSettings(timeout_s=1.0))
    assert est.update(frame(0.0, (2.0, 0.004))).accepted
    held = est.update(frame(0.5))
    assert (held.status, held.altitude_m, held.age_s) == ("holding", pytest.approx(2.0, abs=0.005), 0.5)
    lost = est.update(frame(1.2))
    assert lost.status == "lost" and lost.altitude_m is None
    again = est.update(frame(1.3, (4.0, 0.004)))  # far outside the old gate: acquired again
    assert again.status == "tracking" and again.altitude_m == pytest.approx(4.0, abs=0.005)


def test_the_gate_widens_while_frames_are_missed():
    est = calibrated(RadarAltitudeSettings(gate_m=0.1, max_range_rate_mps=1.0, timeout_s=2.0))
    est.update(frame(0.0, (2.0, 0.004)))
    assert not est.update(frame(0.1, (2.5, 0.004))).accepted  # 0.5 m in 0.1 s: outside 0.1 + 0.1 m
    assert est.update(frame(0.5, (2.5, 0.004))).accepted  # 0.5 s later the gate is 0.6 m


@pytest.mark.parametrize(
    ("tilt", "expected"),
    [
        ("specular", 2.0 + math.cos(0.2) * math.cos(0.1) * 0.1),
        ("boresight", 2.0 * math.cos(0.2) * math.cos(0.1) + math.cos(0.2) * math.cos(0.1) * 0.1),
    ],
)
def test_tilt_and_the_antenna_lever_arm_are_corrected(tilt, expected):
    est = calibrated(RadarAltitudeSettings(tilt=tilt), antenna_offset_frd_m=(0.0, 0.0, 0.1))
    assert est.update(frame(0.0, (2.0, 0.005)), roll_rad=0.2, pitch_rad=0.1).altitude_m == pytest.approx(
        expected, abs=0.002
    )


def test_forward_lever_arm_under_pitch_moves_the_reference_point():
    est = calibrated(antenna_offset_frd_m=(0.3, 0.0, 0.0))
    e = est.update(frame(0.0, (2.0, 0.005)), pitch_rad=0.2)  # nose up: the antenna in front rises
    assert e.altitude_m == pytest.approx(2.0 - math.sin(0.2) * 0.3, abs=0.002)


def test_clutter_map_tracks_a_moving_echo_without_calibration():
    est = RadarAltitudeEstimator(RadarAltitudeSettings(method="clutter_map"))
    heights = [2.0 + 0.3 * math.sin(0.4 * k) for k in range(60)]
    estimates = [est.update(frame(0.1 * k, (h, 0.004))) for k, h in enumerate(heights)]
    errors = [abs(e.altitude_m - h) for e, h in zip(estimates[5:], heights[5:], strict=True) if e.accepted]
    assert len(errors) >= 50 and max(errors) < 0.02  # the map keeps a faint ghost of where the echo was


def test_clutter_map_absorbs_an_echo_that_stops_moving_as_the_thesis_feared():
    est = RadarAltitudeEstimator(RadarAltitudeSettings(method="clutter_map", timeout_s=1.0))
    moving = [est.update(frame(0.1 * k, (2.0 + 0.02 * k, 0.004))) for k in range(10)]
    assert moving[-1].accepted
    still = [est.update(frame(1.0 + 0.1 * k, (2.2, 0.004))) for k in range(60)]
    assert still[-1].status == "lost"


def test_thesis_amplitude_domain_background_works_too():
    est = calibrated(RadarAltitudeSettings(domain="amplitude"))
    assert est.update(frame(0.0, (3.0, 0.003))).altitude_m == pytest.approx(3.0, abs=0.01)


@pytest.mark.parametrize(("field", "value"), [("clutter_alpha", 1.5), ("gate_m", -0.1), ("calibration_min_frames", 1)])
def test_bad_configuration_is_refused(field, value):
    with pytest.raises(ValueError, match=field.split("_")[0]):
        RadarAltitudeSettings(**{field: value})


def test_leading_edge_finds_the_first_return_where_later_glints_pull_the_peak_long():
    spread = frame(0.0, (2.0, 0.004), (2.06, 0.004), (2.12, 0.003))  # nadir, then off-nadir glints
    peak = calibrated().update(spread).altitude_m
    edge = calibrated(RadarAltitudeSettings(peak="leading_edge")).update(spread).altitude_m
    assert peak > 2.04
    assert edge == pytest.approx(2.0, abs=0.015)
    single = calibrated(RadarAltitudeSettings(peak="leading_edge")).update(frame(0.0, (3.33, 0.004)))
    assert single.altitude_m == pytest.approx(3.33, abs=0.003)
