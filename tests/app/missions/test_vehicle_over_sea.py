"""The vehicle over the sea: radar heights between samples, their loss, and the mean sea they give."""

from __future__ import annotations

import pytest

from app.estimators.sea_level import MeanSeaLevel
from app.estimators.sea_state import SEA_STATES
from app.estimators.state_history import StateHistory
from app.flight import build_mission_model
from app.messages import AttitudeEuler, PositionVelocityNed
from app.missions.fix_checks import FixChecks
from app.missions.pickup import PickupEstimates
from app.missions.table import load_mission
from app.missions.vehicle_over_sea import VehicleOverSea
from app.settings import Settings


def over_sea() -> VehicleOverSea:
    return VehicleOverSea(FixChecks(), StateHistory(), MeanSeaLevel())


def test_a_radar_height_is_interpolated_at_a_capture_time_and_refused_when_too_old_or_lost():
    v = over_sea()
    v.on_height(10.0, 4.0)
    v.on_height(10.1, 4.2)
    assert v.radar_height_at(10.05) == pytest.approx(4.1)  # between the two around it
    assert v.radar_height_at(10.5) == 4.2  # the newest, within height_max_age_s (0.5 s) …
    assert v.radar_height_at(10.7) is None  # … not past it
    # the live height: the newest while no older than radar_live_s (0.15 s), not held as long as a capture's
    assert v.height_above_sea_m(10.2) == 4.2
    assert v.height_above_sea_m(10.3) is None and v.radar_height_at(10.3) == 4.2
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


def test_the_seas_elevation_is_measured_from_the_mean_surface_once_the_window_is_nearly_full():
    """A swell of ±0.6 m, 5.6 s, under a vehicle bobbing 0.3 m at another period: the elevations handed on are the
    swell's within 5 cm, from 10 s of samples on; a 2 s gap starts the mean over."""
    import math

    from app.missions.vehicle_over_sea import ELEVATION_MIN_SPAN_S

    v = over_sea()
    got: list[tuple[float, float]] = []
    v.on_elevation = lambda t_s, eta_m: got.append((t_s, eta_m))

    def swell(t_s: float) -> float:
        return 0.6 * math.sin(2.0 * math.pi * t_s / 5.6)

    def fly(t0_s: float, t1_s: float) -> None:
        t_s = t0_s
        while t_s < t1_s:
            down_m = -4.0 + 0.3 * math.sin(2.0 * math.pi * t_s / 9.0)  # sea's mean 0.5 m below the origin
            v.on_vehicle_sample(PositionVelocityNed(t_s, (0.0, 0.0, down_m), (0.0, 0.0, 0.0)))
            v.on_vehicle_sample(AttitudeEuler(t_s, 0.0, 0.0, 0.0))
            v.on_height(t_s, 0.5 - down_m - swell(t_s))
            t_s = round(t_s + 1.0 / 15.0, 6)

    fly(0.0, 30.0)
    assert got and got[0][0] >= ELEVATION_MIN_SPAN_S
    assert max(abs(eta - swell(t)) for t, eta in got) < 0.05
    n = len(got)
    fly(32.0, 50.0)  # 2 s without the sea: the mean starts over
    again = got[n:]
    assert again and again[0][0] >= 32.0 + ELEVATION_MIN_SPAN_S
    assert max(abs(eta - swell(t)) for t, eta in again) < 0.05


def test_the_mission_hands_the_elevation_to_the_filter_only_right_over_the_object():
    """``PickupEstimates`` forwards the sea's elevation under the vehicle only within ``elevation_radius_m`` of the
    estimate: 2 m off, the sea there is another part of the wave."""
    import math

    from app.estimators.triangulation import SeaPlaneTriangulator
    from app.estimators.wave_filter import WaveFilter
    from app.messages import TargetObservation
    from app.settings import CameraSettings

    for off_m, handed in ((0.3, True), (2.0, False)):
        f = WaveFilter(1.25, 5.58, elevation_std_m=0.05)
        est = PickupEstimates(SeaPlaneTriangulator.from_settings(CameraSettings()), f)
        assert est.checks.elevation_radius_m == 0.5
        f.update(TargetObservation(0.0, (10.0, 5.0, 0.0), ((0.01, 0.0), (0.0, 0.01))))
        t_s = 0.0
        while t_s < 20.0:
            est.on_vehicle_sample(PositionVelocityNed(t_s, (10.0 + off_m, 5.0, -3.0), (0.0, 0.0, 0.0)))
            est.on_vehicle_sample(AttitudeEuler(t_s, 0.0, 0.0, 0.0))
            est.on_height(t_s, 3.0 + 0.5 * math.sin(t_s))
            f.update(TargetObservation(t_s, (10.0, 5.0, 0.0), ((0.01, 0.0), (0.0, 0.01))))  # the object, still
            t_s = round(t_s + 1.0 / 15.0, 6)
        # from 10 s of sea on (ELEVATION_MIN_SPAN_S), 15 a second
        assert f.direction_samples == (pytest.approx(150, abs=2) if handed else 0)


def over_falling_water(checks: FixChecks) -> tuple[VehicleOverSea, float]:
    """A vehicle holding 2 m up over water falling at 0.5 m/s (a trough coming): heights grow 5 cm a frame; and
    the newest height's time."""
    v = VehicleOverSea(checks, StateHistory(), MeanSeaLevel())
    hovering_over(v, [1.0 + 0.05 * k for k in range(11)])
    last = v.sea_level.last()
    assert last is not None
    return v, last.t_s


def test_the_water_falling_is_the_rate_the_radar_last_saw_and_stands_a_while():
    """When the radar goes silent (the water inside its first range) the rate it last saw stands for
    ``water_fall_live_s``; then it is unknown. Rising water falls negatively; a lost radar tells nothing."""
    assert over_sea().water_falling_mps(0.0) is None
    checks = FixChecks()
    v, t_last = over_falling_water(checks)
    assert v.water_falling_mps(t_last) == pytest.approx(0.5, abs=1e-6)
    assert v.water_falling_mps(t_last + checks.water_fall_live_s - 0.01) == pytest.approx(0.5, abs=1e-6)
    assert v.water_falling_mps(t_last + checks.water_fall_live_s + 0.01) is None
    v.on_radar_lost()
    assert v.water_falling_mps(t_last) is None

    rising = over_sea()
    hovering_over(rising, [1.5 - 0.04 * k for k in range(11)])
    t_last = rising.sea_level.last().t_s  # type: ignore[union-attr]
    assert rising.water_falling_mps(t_last) == pytest.approx(-0.4, abs=1e-6)


@pytest.mark.parametrize(("sea_state", "stands_at_0_75_s"), [(1, False), (2, False), (3, True), (4, True)])
def test_the_mission_lets_the_fall_rate_stand_for_a_share_of_the_seas_period(sea_state: int, stands_at_0_75_s: bool):
    """Water falls for half a wave period. Sea state 3 (Tp 5.6 s), seed 1 run 110: the touchdown by the mean sea
    came 0.75 s into the radar's silence over a deepening trough, and GRAB's blind sink met the water 0.27-0.33 m
    off the object — the rate must still stand then. On a sea state 1 ripple (Tp 1.6 s) a fall seen 0.75 s
    before has turned into a rise (an older rate would refuse good grabs)."""
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update={"sea_state": sea_state})})
    model = build_mission_model(table, Settings())
    assert isinstance(model, PickupEstimates)
    live_s = model.checks.water_fall_live_s
    assert 0.1 * SEA_STATES[sea_state].tp_s < live_s < 0.25 * SEA_STATES[sea_state].tp_s  # well inside the fall
    v, t_last = over_falling_water(model.checks)
    assert (v.water_falling_mps(t_last + 0.75) is not None) is stands_at_0_75_s


def hovering_over(v: VehicleOverSea, heights_m: list[float]) -> None:
    """The vehicle 2 m up from 1.0 s on, a radar height every 0.1 s (the newest waits for the vehicle's sample
    after it)."""
    for k in range(len(heights_m) + 1):
        t_s = 1.0 + 0.1 * k
        v.on_vehicle_sample(PositionVelocityNed(t_s, (0.0, 0.0, -2.0), (0.0, 0.0, 0.0)))
        v.on_vehicle_sample(AttitudeEuler(t_s, 0.0, 0.0, 0.0))
    for k, h in enumerate(heights_m):
        v.on_height(1.0 + 0.1 * k, h)
