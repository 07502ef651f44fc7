"""Sea world: spectra reproduced by the record, current and drift, the object's motion and its derivatives."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Literal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import curve_fit
from scipy.signal import welch

from sim.sea import SEA_STATES, FloatingObject, SeaConfig, SeaWorld
from sim.sea_spectrum import jonswap, pierson_moskowitz

FS_HZ = 4.0
LONG_RUN_S = 2 * 3600.0
STILL_WATER = SeaConfig(current_mps=0.0, current_variation_mps=0.0, wind_mps=0.0)  # waves only, no drift
Spectrum = Literal["pm", "jonswap"]


def fixed_point_record(sea: SeaWorld) -> np.ndarray:
    """η at a point fixed in the water (drifting with the current, as a wave buoy adrift: the sea state's
    spectrum is the waves' own, not the Doppler-shifted one a moored buoy records), sampled at FS_HZ over
    LONG_RUN_S."""
    t = np.arange(0.0, LONG_RUN_S, 1.0 / FS_HZ)
    d = sea.water_displacement_ne_m(t)
    return np.asarray(sea.surface_elevation_m(t, 12.0 + d[:, 0], -7.0 + d[:, 1]))


def welch_peak_period_s(eta: np.ndarray, spectrum: Spectrum) -> tuple[float, float]:
    """Peak period of the record's Welch PSD (1024 s segments): (argmax of the PSD, least-squares fit of the shape).

    The fit is the robust estimate: near a Pierson–Moskowitz peak the PSD is within 10 % of its maximum over
    ±10 % in frequency, so the raw argmax wanders by several per cent with the seed.
    """
    f_hz, psd = welch(eta, fs=FS_HZ, nperseg=4096)
    omega, s_omega = 2.0 * math.pi * f_hz[1:], psd[1:] / (2.0 * math.pi)  # one-sided, per rad/s

    def shape(w: np.ndarray, hs_m: float, tp_s: float) -> np.ndarray:
        return pierson_moskowitz(w, hs_m, tp_s) if spectrum == "pm" else jonswap(w, hs_m, tp_s)

    argmax_tp_s = 2.0 * math.pi / omega[np.argmax(s_omega)]
    (_, fitted_tp_s), _ = curve_fit(shape, omega, s_omega, p0=(4.0 * eta.std(), argmax_tp_s))
    return argmax_tp_s, float(fitted_tp_s)


def test_sea_state_table_is_wmo_band_tops_with_fully_developed_pm_periods() -> None:
    assert [SEA_STATES[c].hs_m for c in range(6)] == [0.0, 0.1, 0.5, 1.25, 2.5, 4.0]
    assert SEA_STATES[0].tp_s == 0.0  # glassy: no waves
    assert SEA_STATES[1].tp_s == 1.6  # the shortest period
    for code in (2, 3, 4, 5):
        assert SEA_STATES[code].tp_s == pytest.approx(4.99 * math.sqrt(SEA_STATES[code].hs_m), rel=2e-3)


@pytest.mark.parametrize("spectrum", ["pm", "jonswap"])
def test_target_spectrum_integrates_to_hs(spectrum: Spectrum) -> None:
    sea = SeaWorld(SeaConfig(sea_state=4, spectrum=spectrum))
    omega = np.linspace(0.01, 40.0, 400_001)
    m0 = float(np.sum(sea.spectrum(omega)) * (omega[1] - omega[0]))  # S is ~0 at both ends
    assert 4.0 * math.sqrt(m0) == pytest.approx(2.5, rel=1e-3)
    # The components hold the band 0.5–3.5 ωp of it: under 1 % of the energy is left out.
    assert sea.significant_wave_height_m == pytest.approx(2.5, rel=0.01)


@pytest.mark.parametrize(("code", "spectrum"), [(2, "pm"), (3, "pm"), (4, "pm"), (3, "jonswap")])
def test_long_record_reproduces_hs_and_peak_period(code: int, spectrum: Spectrum) -> None:
    sea = SeaWorld(SeaConfig(sea_state=code, spectrum=spectrum), seed=code)
    eta = fixed_point_record(sea)
    target = SEA_STATES[code]
    assert 4.0 * eta.std() == pytest.approx(target.hs_m, rel=0.10)
    argmax_tp_s, fitted_tp_s = welch_peak_period_s(eta, spectrum)
    assert fitted_tp_s == pytest.approx(target.tp_s, rel=0.10)
    assert argmax_tp_s == pytest.approx(target.tp_s, rel=0.10)


def test_long_record_psd_follows_the_target_spectrum_shape() -> None:
    sea = SeaWorld(SeaConfig(sea_state=3), seed=11)
    f_hz, psd = welch(fixed_point_record(sea), fs=FS_HZ, nperseg=1024)
    omega, s_omega = 2.0 * math.pi * f_hz, psd / (2.0 * math.pi)
    band = (omega > 0.6 * sea.peak_omega_radps) & (omega < 3.0 * sea.peak_omega_radps)
    # Spectral moments of the record against those of the target (mean period Tm01 = 2π m0/m1).
    measured_tm01 = 2.0 * math.pi * np.sum(s_omega[band]) / np.sum(omega[band] * s_omega[band])
    target = sea.spectrum(omega[band])
    target_tm01 = 2.0 * math.pi * np.sum(target) / np.sum(omega[band] * target)
    assert measured_tm01 == pytest.approx(target_tm01, rel=0.03)


def test_glassy_sea_is_flat_and_the_object_only_drifts() -> None:
    sea = SeaWorld(SeaConfig(sea_state=0))
    t = np.linspace(0.0, 3600.0, 2001)
    assert np.all(sea.surface_elevation_m(t[:, None], np.arange(5.0), -np.arange(5.0)) == 0.0)
    assert np.all(sea.surface_velocity_ned_mps(t, 3.0, 4.0) == 0.0)
    obj = FloatingObject(sea, start_ne_m=(10.0, -5.0))
    pos, vel, _ = obj.states(t)
    expected_vel = sea.current_ned_mps(t) + np.array(sea.windage_drift_ned_mps)
    np.testing.assert_allclose(vel, expected_vel, atol=1e-12)
    assert np.all(pos[:, 2] == 0.0)
    # Position is the integral of that velocity (trapezoid on a fine grid).
    drift = np.cumsum(0.5 * (expected_vel[1:] + expected_vel[:-1]) * np.diff(t)[:, None], axis=0)
    np.testing.assert_allclose(pos[1:, :2] - pos[0, :2], drift[:, :2], atol=1e-3)
    np.testing.assert_allclose(pos[0, :2], (10.0, -5.0))


@settings(max_examples=12, deadline=None)
@given(
    code=st.sampled_from([1, 3, 5]),
    seed=st.integers(0, 2**31),
    t0_s=st.floats(-1000.0, 20_000.0),
)
def test_velocity_and_acceleration_are_the_derivatives_of_position(code: int, seed: int, t0_s: float) -> None:
    obj = FloatingObject(SeaWorld(SeaConfig(sea_state=code), seed=seed), start_ne_m=(3.0, 4.0))
    h_s = 1e-3
    t = t0_s + np.linspace(0.0, 60.0, 601)
    pos_p, vel_p, _ = obj.states(t + h_s)
    pos_m, vel_m, _ = obj.states(t - h_s)
    _, vel, acc = obj.states(t)
    np.testing.assert_allclose((pos_p - pos_m) / (2.0 * h_s), vel, atol=1e-3)
    np.testing.assert_allclose((vel_p - vel_m) / (2.0 * h_s), acc, atol=1e-3)


def test_states_equals_state_sample_by_sample() -> None:
    obj = FloatingObject(SeaWorld(SeaConfig(sea_state=4), seed=5), start_ne_m=(-2.0, 1.0))
    t = np.linspace(-50.0, 3000.0, 997)  # more than one block of samples
    pos, vel, acc = obj.states(t)
    for i in range(0, len(t), 37):
        truth = obj.state(float(t[i]))
        assert truth.t_s == t[i]
        np.testing.assert_allclose(truth.pos_ned_m, pos[i], atol=1e-6)
        np.testing.assert_allclose(truth.vel_ned_mps, vel[i], atol=1e-6)
        np.testing.assert_allclose(truth.acc_ned_mps2, acc[i], atol=1e-6)


def test_mean_drift_over_hours_is_current_plus_windage() -> None:
    sea = SeaWorld(SeaConfig(sea_state=3), seed=2)
    obj = FloatingObject(sea)
    t = np.arange(0.0, 6 * 3600.0, 1.0)
    pos, vel, _ = obj.states(t)
    to_rad, from_rad = math.radians(60.0), math.radians(240.0)
    # 0.3 m/s towards 060° plus 2 % of 5 m/s from 240° (i.e. towards 060° too): 0.4 m/s towards 060°.
    expected_ne = 0.3 * np.array([math.cos(to_rad), math.sin(to_rad)]) - 0.1 * np.array(
        [math.cos(from_rad), math.sin(from_rad)]
    )
    np.testing.assert_allclose((pos[-1, :2] - pos[0, :2]) / t[-1], expected_ne, atol=2e-3)
    np.testing.assert_allclose(vel[:, :2].mean(axis=0), expected_ne, atol=2e-3)
    assert abs(vel[:, 2].mean()) < 2e-3


def test_the_current_carries_the_waves_so_the_object_rides_them_as_in_still_water() -> None:
    """A uniform current is a moving frame (Galilean): the object it carries rides the same orbits at the
    same frequencies as in still water, and the surface is the still sea's, carried along by U t. Before
    2026-12-03 the waves stood still and the object, carried through them, met them at ω − k·U."""
    current = SeaConfig(sea_state=3, current_mps=0.7, current_to_deg=200.0, current_variation_mps=0.0, wind_mps=0.0)
    still, moving = SeaWorld(replace(STILL_WATER, sea_state=3), seed=8), SeaWorld(current, seed=8)
    u_ne = 0.7 * np.array([math.cos(math.radians(200.0)), math.sin(math.radians(200.0))])
    t = np.arange(0.0, 300.0, 0.25)
    pos_s, vel_s, acc_s = FloatingObject(still, (5.0, -3.0)).states(t)
    pos_m, vel_m, acc_m = FloatingObject(moving, (5.0, -3.0)).states(t)
    np.testing.assert_allclose(pos_m[:, :2] - u_ne * t[:, None], pos_s[:, :2], atol=1e-6)
    np.testing.assert_allclose(pos_m[:, 2], pos_s[:, 2], atol=1e-9)
    np.testing.assert_allclose(vel_m[:, :2] - u_ne, vel_s[:, :2], atol=1e-9)
    np.testing.assert_allclose(acc_m, acc_s, atol=1e-9)
    # the surface: carried along with the water …
    n, e = 12.0 + u_ne[0] * t, -7.0 + u_ne[1] * t
    np.testing.assert_allclose(moving.surface_elevation_m(t, n, e), still.surface_elevation_m(t, 12.0, -7.0), atol=1e-9)
    np.testing.assert_allclose(
        moving.surface_velocity_ned_mps(t, n, e), still.surface_velocity_ned_mps(t, 12.0, -7.0), atol=1e-9
    )
    # … one point and one time at a time too
    for i in (0, 7, 1000):
        ti = float(t[i])
        assert moving.surface_elevation_m(ti, float(n[i]), float(e[i])) == pytest.approx(
            still.surface_elevation_m(ti, 12.0, -7.0), abs=1e-9
        )
    grid_n, grid_e = np.meshgrid(np.linspace(-5.0, 5.0, 7), np.linspace(0.0, 9.0, 5))
    np.testing.assert_allclose(
        moving.surface_elevation_m(40.0, grid_n + 40.0 * u_ne[0], grid_e + 40.0 * u_ne[1]),
        still.surface_elevation_m(40.0, grid_n, grid_e),
        atol=1e-9,
    )
    # a moored point sees the waves pass faster or slower: not the still sea's record
    assert np.abs(moving.surface_elevation_m(t, 12.0, -7.0) - still.surface_elevation_m(t, 12.0, -7.0)).max() > 0.3


def test_current_varies_slowly_around_its_steady_value() -> None:
    sea = SeaWorld(SeaConfig(current_mps=0.3, current_to_deg=90.0, current_variation_mps=0.05), seed=4)
    t = np.arange(0.0, 48 * 3600.0, 10.0)
    current = sea.current_ned_mps(t)
    assert current.shape == (len(t), 3)
    assert np.all(current[:, 2] == 0.0)
    np.testing.assert_allclose(current[:, :2].mean(axis=0), (0.0, 0.3), atol=0.01)
    variation = current[:, :2] - current[:, :2].mean(axis=0)
    assert math.sqrt(np.mean(np.sum(variation**2, axis=1))) == pytest.approx(0.05, rel=0.25)
    # Slow: under 1 mm/s per second, against ~0.5 m/s² of wave orbital acceleration in sea state 3.
    assert np.abs(np.diff(current[:, :2], axis=0)).max() / 10.0 < 1e-3


def test_heave_and_orbital_speed_in_sea_state_3_are_of_the_expected_size() -> None:
    sea = SeaWorld(SeaConfig(sea_state=3), seed=6)
    obj = FloatingObject(sea)
    t = np.arange(0.0, 3600.0, 0.25)
    pos, vel, _ = obj.states(t)
    hs_m = SEA_STATES[3].hs_m
    # Significant heave amplitude 2σ ≈ Hs/2.
    assert 2.0 * pos[:, 2].std() == pytest.approx(hs_m / 2.0, rel=0.15)
    wave_vel_ne = vel[:, :2] - (sea.current_ned_mps(t)[:, :2] + np.array(sea.windage_drift_ned_mps[:2]))
    speed_std_mps = math.sqrt(float(np.sum(wave_vel_ne.var(axis=0))))
    assert 0.3 < speed_std_mps < 0.7


def test_heave_is_the_surface_height_at_the_mean_position() -> None:
    sea = SeaWorld(replace(STILL_WATER, sea_state=3), seed=8)
    obj = FloatingObject(sea, start_ne_m=(20.0, 30.0))
    t = np.linspace(0.0, 600.0, 3001)
    pos, _, _ = obj.states(t)
    np.testing.assert_allclose(pos[:, 2], -np.asarray(sea.surface_elevation_m(t, 20.0, 30.0)), atol=1e-6)


def test_long_crested_waves_travel_away_from_wave_from_deg_with_prograde_orbits() -> None:
    sea = SeaWorld(replace(STILL_WATER, sea_state=3, wave_from_deg=240.0, n_directions=1), seed=9)
    w = sea.components
    heading_deg = np.degrees(np.arctan2(w.k_east, w.k_north)) % 360.0
    np.testing.assert_allclose(heading_deg, 60.0)
    t = np.arange(0.0, 1200.0, 0.25)
    eta = np.asarray(sea.surface_elevation_m(t, 0.0, 0.0))
    u = sea.surface_velocity_ned_mps(t, 0.0, 0.0)
    along_mps = u[:, 0] * math.cos(math.radians(60.0)) + u[:, 1] * math.sin(math.radians(60.0))
    # Under a crest the water moves with the wave, in a trough against it.
    assert np.corrcoef(eta, along_mps)[0, 1] > 0.9
    # Vertical: down = −dη/dt.
    t_fine = np.arange(100.0, 130.0, 1e-3)
    eta_fine = np.asarray(sea.surface_elevation_m(t_fine, 0.0, 0.0))
    w_down = sea.surface_velocity_ned_mps(t_fine[1:-1], 0.0, 0.0)[:, 2]
    np.testing.assert_allclose(w_down, -(eta_fine[2:] - eta_fine[:-2]) / 2e-3, atol=1e-3)


def test_spread_waves_come_from_wave_from_deg_on_average() -> None:
    sea = SeaWorld(SeaConfig(wave_from_deg=300.0, spread_s=4.0), seed=10)
    w = sea.components
    energy = w.amplitude_m**2
    k = np.hypot(w.k_north, w.k_east)
    mean_to_deg = math.degrees(math.atan2(np.sum(energy * w.k_east / k), np.sum(energy * w.k_north / k))) % 360.0
    assert mean_to_deg == pytest.approx(120.0, abs=5.0)
    assert len(np.unique(np.round(np.degrees(np.arctan2(w.k_east, w.k_north)), 6))) == 7


def test_queries_broadcast_and_scalars_give_floats() -> None:
    sea = SeaWorld(seed=1)
    assert isinstance(sea.surface_elevation_m(1.0, 2.0, 3.0), float)
    grid = sea.surface_elevation_m(5.0, np.arange(4.0)[:, None], np.arange(3.0)[None, :])
    assert isinstance(grid, np.ndarray) and grid.shape == (4, 3)
    assert grid[2, 1] == pytest.approx(sea.surface_elevation_m(5.0, 2.0, 1.0), abs=1e-9)
    assert sea.surface_velocity_ned_mps(np.zeros((2, 5)), 0.0, 0.0).shape == (2, 5, 3)
    assert sea.current_ned_mps(3.0).shape == (3,)


def test_same_seed_same_world_other_seed_other_world() -> None:
    a, b, c = SeaWorld(seed=3), SeaWorld(seed=3), SeaWorld(seed=4)
    for name in ("amplitude_m", "omega_radps", "k_north", "k_east", "phase_rad"):
        np.testing.assert_array_equal(getattr(a.components, name), getattr(b.components, name))
    t = np.linspace(0.0, 100.0, 401)
    pos_a, _, _ = FloatingObject(a).states(t)
    pos_b, _, _ = FloatingObject(b).states(t)
    pos_c, _, _ = FloatingObject(c).states(t)
    np.testing.assert_array_equal(pos_a, pos_b)
    assert np.abs(pos_a - pos_c).max() > 0.1
    assert not np.array_equal(a.current_ned_mps(t), c.current_ned_mps(t))


def test_components_are_read_only() -> None:
    sea = SeaWorld()
    with pytest.raises(ValueError, match="read-only"):
        sea.components.phase_rad[0] = 0.0


def test_downwash_pushes_the_object_away_from_a_low_vehicle() -> None:
    obj = FloatingObject(SeaWorld(replace(STILL_WATER, sea_state=0)))
    vehicle_ned_m = (0.0, 0.5, -1.0)  # 1 m above, 0.5 m east of the object
    dt_s = 0.02
    for i in range(50):
        obj.push_downwash(i * dt_s, dt_s, vehicle_ned_m)
    truth = obj.state(1.0)
    north_m, east_m, _ = truth.pos_ned_m
    assert east_m < -0.15  # pushed west, away from the vehicle
    assert abs(north_m) < 1e-9
    # ~0.3 m/s at 1 m height, a little less 0.5 m off the axis.
    first = obj.state(0.01)
    assert -0.3 < first.vel_ned_mps[1] < -0.2
    # After the pushes it stays where it was left; before them it had not moved.
    assert obj.state(5.0).pos_ned_m == pytest.approx(truth.pos_ned_m)
    assert obj.state(-1.0).pos_ned_m == pytest.approx((0.0, 0.0, 0.0))


def test_downwash_from_a_vehicle_at_10_m_does_nothing() -> None:
    sea = SeaWorld(SeaConfig(sea_state=3), seed=12)
    pushed, untouched = FloatingObject(sea), FloatingObject(sea)
    t = np.arange(0.0, 20.0, 0.02)
    for t_s in t:
        n, e, d = pushed.state(float(t_s)).pos_ned_m
        pushed.push_downwash(float(t_s), 0.02, (n, e + 0.5, d - 10.0))
    np.testing.assert_array_equal(pushed.states(t)[0], untouched.states(t)[0])


def test_downwash_in_waves_moves_the_object_away_from_a_vehicle_following_it() -> None:
    sea = SeaWorld(SeaConfig(sea_state=3), seed=13)
    pushed, untouched = FloatingObject(sea), FloatingObject(sea)
    for i in range(100):
        t_s = i * 0.02
        n, e, d = untouched.state(t_s).pos_ned_m
        pushed.push_downwash(t_s, 0.02, (n + 0.5, e, d - 1.0))  # 1 m above, 0.5 m north of where it would be
    offset_ne = np.array(pushed.state(2.0).pos_ned_m[:2]) - np.array(untouched.state(2.0).pos_ned_m[:2])
    assert offset_ne[0] < -0.2  # pushed south
    assert abs(offset_ne[1]) < 0.1 * abs(offset_ne[0])


def test_downwash_pushes_must_come_in_time_order() -> None:
    obj = FloatingObject(SeaWorld(replace(STILL_WATER, sea_state=0)))
    obj.push_downwash(1.0, 0.1, (0.0, 0.5, -1.0))
    with pytest.raises(ValueError, match="before the previous one ended"):
        obj.push_downwash(1.05, 0.1, (0.0, 0.5, -1.0))


def test_config_rejects_unknown_sea_state() -> None:
    with pytest.raises(ValueError, match="WMO"):
        SeaConfig(sea_state=7)
