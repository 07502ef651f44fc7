"""The radar emulator's echo model: where the sea echo is, how strong, how it fades, what stays static."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.sensors.x4m03_frame_area import quantise_frame_area
from sim.radar_signal import RadarSignalConfig, SeaRadarScene
from sim.radar_track import VehicleTrack, hover
from sim.sea import SeaConfig, SeaWorld

AXIS = quantise_frame_area(0.4, 5.0, 0.18)
STILL = {"height_wobble_m": 0.0, "position_wobble_m": 0.0, "tilt_wobble_deg": 0.0}


def scene(sea_state: int, height_m: float, seed: int = 1, **track) -> SeaRadarScene:
    sea = SeaWorld(SeaConfig(sea_state=sea_state), seed)
    return SeaRadarScene(sea, VehicleTrack(hover(height_m, **{**STILL, **track}), seed), seed=seed)


def echoes(s: SeaRadarScene, n: int, dt_s: float = 0.1):
    """Per frame: the echo (frame minus the static part), and the truth."""
    out = [s.baseband(k * dt_s, AXIS) for k in range(n)]
    return np.array([f - s._static_part(AXIS) for f, _ in out]), [t for _, t in out]


def test_on_a_glassy_sea_the_echo_peaks_at_the_antenna_height():
    s = scene(0, 2.0)
    frames, truths = echoes(s, 20)
    peak_m = AXIS.ranges_m()[np.argmax(np.abs(frames), axis=1)]
    assert np.all(np.abs(peak_m - [t.specular_range_m for t in truths]) <= AXIS.bin_m)
    assert truths[0].antenna_height_m == pytest.approx(2.0 - 0.08, abs=1e-6)  # antenna 8 cm below the reference
    assert truths[0].height_m == pytest.approx(2.0)


def test_echo_amplitude_falls_as_one_over_height_on_calm_water():
    amp = {h: np.abs(echoes(scene(0, h), 10)[0]).max(axis=1).mean() for h in (1.0, 3.0)}
    ratio = amp[1.0] / amp[3.0]
    assert ratio == pytest.approx((3.0 - 0.08) / (1.0 - 0.08), rel=0.1)
    assert amp[1.0] == pytest.approx(0.02 / 0.92, rel=0.15)  # A₁ = 0.02 at 1 m


def test_tilting_the_vehicle_30_degrees_costs_the_antenna_pattern():
    level = np.abs(echoes(scene(0, 2.0), 10)[0]).max(axis=1).mean()
    tilted = np.abs(echoes(scene(0, 2.0, roll_deg=30.0), 10)[0]).max(axis=1).mean()
    assert tilted / level == pytest.approx(math.exp(-math.log(2) * (30 / 35) ** 2), rel=0.1)


def test_calm_water_is_steady_and_a_rough_sea_fades():
    def spread(sea_state: int) -> float:
        peaks = np.abs(echoes(scene(sea_state, 2.0), 200)[0]).max(axis=1)
        return float(np.std(peaks) / np.mean(peaks))

    assert spread(0) < 0.15  # a mirror with a little incoherent glitter (ρ = 0.99)
    assert spread(3) > 0.3  # Rayleigh-like: 0.52 for a single scatterer


def test_waves_move_the_surface_under_a_hovering_vehicle():
    _, truths = echoes(scene(3, 3.0), 100, dt_s=0.2)
    heights = [t.height_m for t in truths]
    assert max(heights) - min(heights) > 0.5  # sea state 3: Hs 1.25 m


def test_with_the_sea_out_of_range_frames_are_the_static_background_plus_noise():
    s = scene(1, 7.0)
    frames = np.array([s.baseband(k * 0.1, AXIS)[0] for k in range(100)])
    deviation = frames - s._static_part(AXIS)
    far = AXIS.ranges_m() > 2.0
    noise = np.std(deviation[:, far].real)
    assert noise == pytest.approx(math.hypot(1.8e-5, 0.005 * 3e-4 / math.sqrt(2)), rel=0.2)


def test_frames_are_reproducible_for_a_seed():
    a, b = scene(3, 2.0, seed=5), scene(3, 2.0, seed=5)
    assert np.array_equal(a.baseband(1.0, AXIS)[0], b.baseband(1.0, AXIS)[0])


def test_small_scale_roughness_can_be_set_explicitly():
    sea = SeaWorld(SeaConfig(sea_state=0), 0)
    cfg = RadarSignalConfig(small_scale_rms_m=0.02, mean_square_slope=0.02)
    s = SeaRadarScene(sea, VehicleTrack(hover(2.0, **STILL)), cfg)
    assert s.coherence < 0.01 and s.exponent == pytest.approx(1.5, abs=0.01)
