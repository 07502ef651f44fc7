"""The vehicle over the sea: radar heights between samples, their loss, and the mean sea they give."""

from __future__ import annotations

import pytest

from app.estimators.sea_level import MeanSeaLevel
from app.estimators.state_history import StateHistory
from app.messages import AttitudeEuler, PositionVelocityNed
from app.missions.fix_checks import FixChecks
from app.missions.vehicle_over_sea import VehicleOverSea


def over_sea() -> VehicleOverSea:
    return VehicleOverSea(FixChecks(), StateHistory(), MeanSeaLevel())


def test_a_radar_height_is_interpolated_at_a_capture_time_and_refused_when_too_old_or_lost():
    v = over_sea()
    v.on_height(10.0, 4.0)
    v.on_height(10.1, 4.2)
    assert v.radar_height_at(10.05) == pytest.approx(4.1)  # between the two around it
    assert v.radar_height_at(10.5) == 4.2  # the newest, within height_max_age_s (0.5 s) …
    assert v.radar_height_at(10.7) is None  # … not past it
    assert v.height_above_sea_m(10.3) == 4.2
    v.on_radar_lost()
    assert v.radar_height_at(10.1) is None and v.height_above_sea_m(10.1) is None
    v.on_height(10.2, 4.4)  # a height again: the radar is back
    assert v.height_above_sea_m(10.2) == 4.4


def test_heights_become_the_mean_sea_only_once_the_vehicles_altitude_at_their_time_is_known():
    v = over_sea()
    assert v.sea_reference(0.0) == (0.0, 0.0)  # no height yet: home_above_sea_m below home
    v.on_height(1.0, 5.0)
    assert v.sea_level.last() is None  # the vehicle's sample at 1.0 s has not arrived
    for k in range(3):
        t_s = 0.9 + 0.1 * k
        v.on_vehicle_sample(PositionVelocityNed(t_s, (0.0, 0.0, -6.0), (0.0, 0.0, 0.0)))
        v.on_vehicle_sample(AttitudeEuler(t_s, 0.0, 0.0, 0.0))
    v.on_height(1.1, 5.0)  # the next height lets the first one through
    last = v.sea_level.last()
    assert last is not None and last.down_m == pytest.approx(-1.0)  # 6 m up, 5 m over the sea: sea 1 m up
    assert v.height_over_mean_sea_m(1.1) == pytest.approx(5.0)
    assert v.height_at(1.05) == (pytest.approx(5.0), FixChecks().height_uncertainty_m)  # the radar's
