"""DESCEND's desired height, tick by tick: the final part is flown only right over the object, from a height a
crest cannot reach, and the desired height does not run away from a vehicle that lags it.

The estimates are the real ``PickupEstimates``' pieces a ``DescendTarget`` reads (snapshot, estimate, the mean
sea and its crests), fed by hand here so each rule can be driven on its own."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.estimators.sea_level import MeanSeaLevel
from app.messages import PositionVelocityNed, TargetEstimate, TelemetrySnapshot
from app.missions.descend_target import DescendTarget
from app.missions.estimates import Estimates
from app.missions.pickup_targets import SinkTarget, VerifyTarget

DT = 0.02


class Scene:
    """The object at the origin, the mean sea at down 0 (with a crest history), the vehicle where put."""

    def __init__(self, crest_m: float = 0.0) -> None:
        self.sea_level = MeanSeaLevel(tau_s=5.0)
        for k in range(600):  # 40 s of a swell whose crests rise ``crest_m`` over the mean
            t_s = k / 15.0
            self.sea_level.update(t_s, -crest_m * math.sin(1.2 * t_s))
        self.vehicle_ne = (0.0, 0.0)
        self.vehicle_vel_ne = (0.0, 0.0)  # the object's estimate stands still
        self.vehicle_height_m = 4.0
        self.drift: tuple[tuple[float, float], tuple[float, float]] | None = None  # the filter's mean drift
        self.last_fix_t_s: float | None = None  # None: a new fix (0.05 s old) every tick; else no fix since
        self.radar_m: float | None = None  # the radar's height over the water under the vehicle (None: not seen)

    # -- what DescendTarget reads --
    def snapshot(self, t_s: float) -> Estimates:
        age_s = 0.05 if self.last_fix_t_s is None else t_s - self.last_fix_t_s
        return Estimates(
            t_s, fix_age_s=age_s, converged_for_s=5.0, height_above_sea_m=self.radar_m,
            height_over_mean_sea_m=self.vehicle_height_m,
        )  # fmt: skip

    def estimate(self, t_s: float) -> TargetEstimate:
        return TargetEstimate(t_s, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), ((0.01, 0.0), (0.0, 0.01)))

    def drifted(self, t_s: float) -> tuple[tuple[float, float], tuple[float, float]] | None:
        return self.drift

    def sea_reference(self, t_s: float) -> tuple[float, float]:
        return 0.0, 0.0

    def telemetry(self) -> TelemetrySnapshot:
        (n, e), (vn, ve) = self.vehicle_ne, self.vehicle_vel_ne
        return TelemetrySnapshot(pos_vel=PositionVelocityNed(0.0, (n, e, -self.vehicle_height_m), (vn, ve, 0.0)))


def descend(scene: Scene, **kw) -> DescendTarget:
    params = dict(speed_mps=0.5, safety_height_m=2.0, fresh_s=0.5, converged_s=2.0, final_height_m=1.0,
                  final_radius_m=0.1, final_abort_radius_m=0.2, crest_margin_m=0.3, max_lead_m=0.5,
                  final_max_speed_mps=0.3)  # fmt: skip
    return DescendTarget(scene, scene.telemetry, 4.0, **(params | kw))  # type: ignore[arg-type]


def fly(target: DescendTarget, scene: Scene, t0_s: float, seconds: float, follow: bool = True) -> float:
    """Tick for ``seconds``; the vehicle follows the desired height exactly (``follow``) or stays put."""
    t_s = t0_s
    for _ in range(round(seconds / DT)):
        t_s += DT
        state = target.target_at(t_s)
        assert state is not None
        if follow:
            scene.vehicle_height_m = -state.pos_ned_m[2]
    return t_s


def test_it_waits_above_the_highest_crest_until_it_is_over_the_object():
    scene = Scene(crest_m=0.9)  # sea state 3: crests 0.9 m over the mean
    target = descend(scene)
    scene.vehicle_ne = (0.15, 0.0)  # near the object, but not within the final radius
    t_s = fly(target, scene, 100.0, 10.0)
    final_m = target.final_height_now_m()
    print(f"final height {final_m:.2f} m (crest {scene.sea_level.crest_m():.2f} m)")
    assert 1.15 <= final_m <= 1.3  # crest + 0.3 m, above the 1 m of the parameter
    assert target.height_m == final_m and not target.plunging and target.waits > 0
    scene.vehicle_ne = (0.05, 0.0)  # over it now: the last part goes down
    fly(target, scene, t_s, 4.0)
    assert target.plunging and target.height_m == 0.0


def test_drifting_off_the_object_low_climbs_back_to_the_final_height():
    scene = Scene(crest_m=0.2)
    target = descend(scene)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object: down through the final height
    assert target.plunging and 0.0 < target.height_m < 1.0
    scene.vehicle_ne = (0.15, 0.0)  # past the final radius but within the abort radius: on down
    low_m = target.height_m
    t_s = fly(target, scene, t_s, 0.2)
    assert target.plunging and target.height_m < low_m
    scene.vehicle_ne = (0.25, 0.0)  # past the abort radius: back up, and a go-around counted
    fly(target, scene, t_s, 0.1)
    assert not target.plunging and target.go_arounds == 1 and target.height_m == target.final_height_now_m()
    assert scene.final_descent_given_up


def test_off_the_object_on_the_way_down_it_holds_its_height_until_guidance_has_caught_up():
    scene = Scene()
    target = descend(scene)
    scene.vehicle_ne = (0.3, 0.0)  # past the abort radius, high above the final height
    fly(target, scene, 100.0, 3.0)
    assert target.height_m == 4.0 and target.waits > 0
    scene.vehicle_ne = (0.15, 0.0)  # within it: on down, at 0.5 m/s
    fly(target, scene, 103.0, 2.0)
    assert target.height_m == pytest.approx(3.0, abs=0.05)


def test_the_last_part_starts_only_while_the_vehicle_moves_with_the_object():
    scene = Scene()
    target = descend(scene)
    scene.vehicle_vel_ne = (0.4, 0.0)  # right over it, but sliding past it (a vehicle lagging the wave orbit)
    t_s = fly(target, scene, 100.0, 8.0)
    assert not target.plunging and target.height_m == target.final_height_now_m()
    scene.vehicle_vel_ne = (0.2, 0.0)  # moving with it (within 0.3 m/s): the last part goes down
    fly(target, scene, t_s, 3.0)
    assert target.plunging and target.height_m == 0.0


def test_the_desired_height_leads_a_lagging_vehicle_by_at_most_the_lead():
    scene = Scene()
    target = descend(scene)
    scene.vehicle_height_m = 3.5  # the vehicle does not follow
    fly(target, scene, 100.0, 3.0, follow=False)
    assert target.height_m == 3.0  # 3.5 − 0.5, not the 2.5 m the 0.5 m/s ramp would have reached


def test_in_the_final_part_the_desired_height_leads_the_vehicle_by_at_most_the_final_lead():
    """Low over the water the lead is smaller: 0.5 m of lead asked for ~1 m/s down, and an ArduCopter coming
    down at that speed (1 m/s² vertically) met the water when it had to climb back."""
    scene = Scene()
    target = descend(scene, final_max_lead_m=0.1)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object, following: down through the final height
    assert target.plunging and target.height_m < 1.0
    scene.vehicle_height_m = 0.8  # the vehicle stops following at 0.8 m
    fly(target, scene, t_s, 2.0, follow=False)
    assert target.height_m == pytest.approx(0.7)  # 0.8 − 0.1, not the 0.3 m the 0.5 m lead would allow
    above = descend(Scene(), final_max_lead_m=0.1)
    above_scene = above.model
    above_scene.vehicle_height_m = 3.5  # above the final height the descent's own lead holds
    fly(above, above_scene, 100.0, 3.0, follow=False)
    assert above.height_m == 3.0


def test_verify_follows_the_estimate_up_and_stays_where_it_was_last_when_it_is_gone():
    scene = Scene()
    target = VerifyTarget(scene, scene.telemetry, 3.0, (5.0, 5.0))  # type: ignore[arg-type]
    state = target.target_at(100.0)
    assert state.pos_ned_m == (0.0, 0.0, -3.0)  # over the object's estimate (at the origin), 3 m over the sea
    scene.estimate = lambda t_s: None  # type: ignore[method-assign]  # the lock timed out
    state = target.target_at(101.0)
    assert state.pos_ned_m == (0.0, 0.0, -3.0) and state.vel_ned_mps == (0.0, 0.0, 0.0)


def test_grab_sinks_over_the_object_tightly_its_sinking_speed_fed_forward_down_to_its_floor():
    scene = Scene()
    target = SinkTarget(scene, scene.telemetry, 0.3, 0.8, -1.0)  # type: ignore[arg-type]
    first = target.target_at(100.0)
    assert first.pos_ned_m == (0.0, 0.0, -0.3) and first.vel_ned_mps == (0.0, 0.0, 0.8) and first.precise
    later = target.target_at(100.5)  # 0.4 m lower, still sinking at 0.8 m/s
    assert later.pos_ned_m == pytest.approx((0.0, 0.0, 0.1)) and later.vel_ned_mps == (0.0, 0.0, 0.8)
    bottom = target.target_at(102.5)  # at its floor, 1 m under the mean sea: no more sinking fed forward
    assert bottom.pos_ned_m == (0.0, 0.0, 1.0) and bottom.vel_ned_mps == (0.0, 0.0, 0.0) and bottom.precise


def test_verify_without_an_estimate_follows_where_the_objects_drift_takes_it():
    scene = Scene()
    target = VerifyTarget(scene, scene.telemetry, 3.0, (5.0, 5.0))  # type: ignore[arg-type]
    scene.estimate = lambda t_s: None  # type: ignore[method-assign]  # the lock timed out
    scene.drift = ((2.0, -1.0), (0.6, -0.3))  # the filter's current, carried on from its last fix
    state = target.target_at(101.0)
    assert state.pos_ned_m == (2.0, -1.0, -3.0) and state.vel_ned_mps == (0.6, -0.3, 0.0)
    scene.drift = None  # the filter was reset: stays where the drift was last
    assert target.target_at(102.0).pos_ned_m == (2.0, -1.0, -3.0)


@pytest.mark.parametrize("gap_s", [0.25, math.inf])
def test_going_blind_low_it_goes_on_only_right_over_the_object_else_it_climbs_back_while_it_can_see(gap_s):
    """The last half metre is flown blind: when the fixes stop (here 0.25 s without one), the final descent goes
    on only within the final radius of the estimate; 0.15 m off (inside the abort radius) it climbs back to the
    final height, and a stale estimate starts no new final descent. Without the check (gap ∞) it went on down."""
    scene = Scene(crest_m=0.2)
    target = descend(scene, blind_gap_s=gap_s)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object with fresh fixes: down through the final height
    assert target.plunging and 0.0 < target.height_m < 0.9
    scene.vehicle_ne = (0.15, 0.0)  # past the final radius, within the abort radius …
    scene.last_fix_t_s = t_s - 0.05  # … as the camera loses the object
    low_m = target.height_m
    t_s = fly(target, scene, t_s, 0.2)  # not yet 0.25 s without a fix: on down
    assert target.plunging and target.height_m < low_m
    t_s = fly(target, scene, t_s, 0.1)
    if gap_s == math.inf:
        assert target.plunging and target.blind_go_arounds == 0 and target.height_m < low_m - 0.1
        return
    assert not target.plunging and target.blind_go_arounds == 1 and target.go_arounds == 0
    assert scene.final_descent_given_up  # a crest that meets it now is no place to grab (the guards)
    assert target.height_m == target.final_height_now_m()  # back up (fix age 0.35 s: still "fresh", 0.5 s)
    scene.vehicle_ne = (0.05, 0.0)  # over the stale estimate again: no final descent on it
    t_s = fly(target, scene, t_s, 0.1)
    assert not target.plunging and target.height_m == target.final_height_now_m()
    scene.last_fix_t_s = None  # the camera sees it again: down
    fly(target, scene, t_s, 1.0)
    assert target.plunging and target.height_m < target.final_height_now_m() - 0.4
    assert not scene.final_descent_given_up


def test_going_blind_right_over_the_object_it_goes_on_down_to_the_water():
    scene = Scene(crest_m=0.2)
    target = descend(scene, blind_gap_s=0.25)
    t_s = fly(target, scene, 100.0, 7.0)
    assert target.plunging
    scene.vehicle_ne = (0.05, 0.0)  # within the final radius as the fixes stop: committed
    scene.last_fix_t_s = t_s
    t_s = fly(target, scene, t_s, 0.3)
    assert target.plunging and target.blind_go_arounds == 0
    scene.vehicle_ne = (0.15, 0.0)  # blind and committed: only the abort radius still counts
    low_m = target.height_m
    fly(target, scene, t_s, 0.15)
    assert target.plunging and target.height_m < low_m


@pytest.mark.parametrize(("radar_m", "goes_on"), [(0.35, True), (0.6, False)])
def test_going_blind_it_goes_on_only_if_it_reaches_the_water_while_its_fix_is_fresh(radar_m, goes_on):
    """Blind right over the object ~0.28 s after the last fix, going down at 0.5 m/s: from 0.35 m over the water
    the touchdown height (0.3 m) comes 0.1 s later, on a fix 0.38 s old (fresh: 0.5 s) — on down; from 0.6 m it
    would come 0.6 s later, on a fix 0.88 s old: stale on the way, the descent would turn back at the bottom, where
    crests met it off the object. It climbs back now instead, while the camera can still see the object."""
    going_blind_right_over_the_object(radar_m, goes_on)


def going_blind_right_over_the_object(radar_m: float, goes_on: bool, **kw) -> None:
    """Into the final part on fresh fixes, then the camera loses the object right over it ``radar_m`` over the
    water: 0.3 s later the descent goes on (``goes_on``) or has climbed back to the final height, given up."""
    scene = Scene(crest_m=0.2)
    target = descend(scene, blind_gap_s=0.25, touchdown_height_m=0.3, **kw)
    t_s = fly(target, scene, 100.0, 7.0)
    assert target.plunging
    scene.radar_m = radar_m
    scene.last_fix_t_s = t_s  # the camera loses the object right over it
    fly(target, scene, t_s, 0.3)
    assert target.plunging is goes_on
    assert target.blind_go_arounds == (0 if goes_on else 1) and target.go_arounds == 0
    if not goes_on:
        assert scene.final_descent_given_up and target.height_m == target.final_height_now_m()


@pytest.mark.parametrize(("blind_max_s", "goes_on"), [(0.8, True), (0.5, False), (None, True)])
def test_going_blind_it_goes_on_only_if_the_grabs_sink_reaches_the_water_before_its_fix_is_too_old(
    blind_max_s, goes_on
):
    """As above from 0.35 m: the touchdown height comes on a fix 0.38 s old, and GRAB's sink from there takes
    0.375 s more (0.3 m at 0.8 m/s): the water on a fix ~0.76 s old. GRAB gives a grab up once its fix is older
    than ``grab_blind_max_s`` — then still sinking, low over the water, where it met the water off the object. So
    with 0.8 s it goes on down; with 0.5 s it climbs back now, while the camera can still see the object."""
    limit = {} if blind_max_s is None else {"grab_blind_max_s": blind_max_s}
    going_blind_right_over_the_object(0.35, goes_on, grab_sink_s=0.3 / 0.8, **limit)


@pytest.mark.parametrize(("radar_m", "fixes_back"), [(0.6, False), (0.6, True), (0.35, False)])
def test_going_blind_where_it_cannot_go_on_it_stops_going_down_before_the_gap(radar_m, fixes_back):
    """0.6 m over the water the descent could not go on blind (its fix would be stale before the touchdown height),
    so once 0.14 s have passed without a new fix it stops going down: the fixes come back → on down; they do not →
    at the gap (0.25 s) it climbs back, from where it stopped rather than 0.05 m lower and still coming down at
    0.5 m/s (the rising water met it there). 0.35 m over the water it would reach the water fresh: no pause."""
    scene = Scene(crest_m=0.2)
    target = descend(scene, blind_gap_s=0.25, blind_pause_s=0.14, touchdown_height_m=0.3)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object with fresh fixes: into the final part
    assert target.plunging
    scene.radar_m = radar_m
    scene.last_fix_t_s = t_s  # the newest fix, seen on the next tick; then none
    start_m = target.height_m
    t_s = fly(target, scene, t_s, 0.1)
    assert target.plunging and target.height_m == pytest.approx(start_m - 0.05)  # 0.1 s at 0.5 m/s
    t_s = fly(target, scene, t_s, 0.1)  # 0.18 s after the fix was seen
    paused_m = target.height_m
    t_s = fly(target, scene, t_s, 0.04)  # 0.22 s: within the gap
    if radar_m < 0.5:  # it reaches the water while the fix is fresh: on down, and on blind past the gap
        assert target.plunging and target.height_m == pytest.approx(paused_m - 0.02)
        fly(target, scene, t_s, 0.1)
        assert target.plunging and target.blind_go_arounds == 0
        return
    assert target.plunging and target.height_m == paused_m  # stopped going down …
    assert start_m - 0.09 < paused_m < start_m - 0.07  # … 0.14–0.18 s after the fix was seen
    if fixes_back:
        scene.last_fix_t_s = None  # the camera sees the object again: on down
        fly(target, scene, t_s, 0.2)
        assert target.plunging and target.height_m < paused_m - 0.05 and target.blind_go_arounds == 0
        return
    fly(target, scene, t_s, 0.06)  # past the gap: it climbs back from where it stopped
    assert not target.plunging and target.blind_go_arounds == 1
    assert target.height_m == target.final_height_now_m() and scene.final_descent_given_up


@pytest.mark.parametrize("in_final_part", [True, False])
def test_a_fix_gone_stale_turns_the_descent_back_and_a_final_one_is_given_up(in_final_part):
    """A fix older than ``fresh_s`` (0.5 s) ends any descent: back up to the safety height. One that was in its final
    part, going down onto the object, is given up: water that meets the vehicle on the way back up is no place to
    grab (``touchdown_off_target``), as after going blind. Seed 3 run 175 (sea state 3): paused blind 0.25 m over
    the mean sea, its fix went stale just before the blind gap passed, and the crest that met it climbing back was
    taken for a touchdown: GRAB sank into it 0.39 m off the object. Higher up it only stops going down."""
    scene = Scene(crest_m=0.2)
    target = descend(scene)  # no blind gap: only the fix's age turns it back
    t_s = fly(target, scene, 100.0, 7.0 if in_final_part else 2.0)
    assert target.plunging is in_final_part and target.height_m < (0.9 if in_final_part else 3.1)
    scene.last_fix_t_s = t_s  # no fix since
    t_s = fly(target, scene, t_s, 0.46)
    assert target.plunging is in_final_part and not scene.final_descent_given_up
    before_m = target.height_m
    fly(target, scene, t_s, 0.1)  # now older than fresh_s: up to the safety height, or no lower above it
    assert not target.plunging and (target.height_m == 2.0 if in_final_part else 2.0 < target.height_m <= before_m)
    assert scene.final_descent_given_up is in_final_part


def test_a_crest_rising_under_a_vehicle_waiting_for_the_final_part_lifts_it_and_then_it_comes_back():
    scene = Scene(crest_m=0.7)
    target = descend(scene, crest_clearance_m=0.8)
    scene.vehicle_ne = (0.15, 0.0)  # not over the object: it waits at the final height
    t_s = fly(target, scene, 100.0, 10.0)
    final_m = target.final_height_now_m()
    assert not target.plunging and target.height_m == final_m and scene.vehicle_height_m == pytest.approx(final_m)
    scene.radar_m = 0.5  # a crest 0.3 m closer than the clearance under it
    state = target.target_at(t_s + DT)
    assert state is not None and -state.pos_ned_m[2] == pytest.approx(final_m + 0.3)
    assert target.height_m == final_m  # only this tick's aim: the desired height itself stays
    scene.radar_m = final_m  # the crest has passed
    state = target.target_at(t_s + 2 * DT)
    assert state is not None and -state.pos_ned_m[2] == pytest.approx(final_m)


def test_a_crest_that_rises_into_the_radars_first_range_keeps_lifting_a_waiting_vehicle_for_a_while():
    """The radar sees nothing closer than its first range (0.4 m): a crest rising that close under a waiting
    vehicle makes it go silent. That silence right after a close height keeps the lift (the height last seen
    stands in for the water's) for ``CLOSE_WATER_HOLD_S``, then the aim is the final height again."""
    scene = Scene(crest_m=0.7)
    target = descend(scene, crest_clearance_m=0.8)
    scene.vehicle_ne = (0.15, 0.0)  # not over the object: it waits at the final height
    t_s = fly(target, scene, 100.0, 10.0)
    final_m = target.final_height_now_m()
    scene.radar_m = 0.5
    state = target.target_at(t_s + DT)
    assert state is not None and -state.pos_ned_m[2] == pytest.approx(final_m + 0.3)
    scene.radar_m = None  # the crest is inside the first range now
    lifted = []
    for k in range(2, round(1.5 / DT)):
        scene.vehicle_height_m = final_m + 0.1 * k * DT  # climbing (slower than asked)
        state = target.target_at(t_s + k * DT)
        assert state is not None
        lifted.append((k * DT, -state.pos_ned_m[2] - scene.vehicle_height_m))
    assert all(lead == pytest.approx(0.3) for dt_s, lead in lifted if dt_s <= 1.0)  # still 0.3 m over the vehicle
    assert all(lead < 0.0 for dt_s, lead in lifted if dt_s > 1.0 + DT)  # then the final height again (under it)
    assert target.height_m == final_m


def test_radar_silence_without_a_close_height_before_it_lifts_nothing():
    scene = Scene(crest_m=0.7)
    target = descend(scene, crest_clearance_m=0.8)
    scene.vehicle_ne = (0.15, 0.0)
    t_s = fly(target, scene, 100.0, 10.0)
    final_m = target.final_height_now_m()
    scene.radar_m = 1.0  # the water well clear under it, then nothing (a radar dropping out, not a crest)
    target.target_at(t_s + DT)
    scene.radar_m = None
    state = target.target_at(t_s + 2 * DT)
    assert state is not None and -state.pos_ned_m[2] == pytest.approx(final_m)


def test_going_down_onto_the_object_the_water_close_under_it_does_not_lift_it():
    scene = Scene(crest_m=0.2)
    target = descend(scene, crest_clearance_m=0.8)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object: into the final part
    assert target.plunging
    scene.radar_m = 0.4
    low_m = target.height_m
    state = target.target_at(t_s + DT)
    assert state is not None and target.plunging and -state.pos_ned_m[2] == pytest.approx(target.height_m)
    assert target.height_m < low_m


def test_it_asks_guidance_for_precision_while_it_goes_down_on_a_fresh_fix_and_not_while_it_climbs_back():
    """Going down onto the object, the target asks for the autopilot's precise Δ (what the vehicle lags the object's
    wave orbit by there is where it meets the water); climbing back without a fresh fix it does not."""
    scene = Scene()
    target = descend(scene)
    t_s = fly(target, scene, 100.0, 2.0)
    state = target.target_at(t_s + DT)
    assert state is not None and state.precise and 2.0 < target.height_m < 4.0
    scene.last_fix_t_s = t_s  # no fix since: stale after fresh_s (0.5 s), back up to the safety height
    t_s = fly(target, scene, t_s + DT, 1.0)
    state = target.target_at(t_s + DT)
    assert state is not None and not state.precise and target.height_m >= 2.0


@pytest.mark.parametrize(("drift_mps", "precise"), [(0.3, True), (0.8, False), (None, False)])
def test_it_asks_for_precision_only_over_an_object_drifting_slower_than_the_limit(drift_mps, precise):
    """Over an object drifting 0.77-0.91 m/s (sea state 3) the precise loop's tilt swings lost it from view low
    down, descent after descent: there (and with no drift known) the target does not ask for precision."""
    scene = Scene()
    scene.drift = None if drift_mps is None else ((0.0, 0.0), (drift_mps, 0.0))
    target = descend(scene, precise_max_drift_mps=0.6)
    t_s = fly(target, scene, 100.0, 1.0)
    state = target.target_at(t_s + DT)
    assert state is not None and state.precise is precise and target.height_m < 4.0


@pytest.mark.parametrize("max_rise_mps", [0.0, None])
def test_the_final_part_starts_only_while_the_water_under_it_falls_when_asked(max_rise_mps):
    """Right over the object at the final height, over a swell the radar reads at 10 Hz: with the limit the final
    descent starts only while the water falls (behind a crest); without it, at once, whatever the water does."""
    scene = Scene(crest_m=0.5)
    target = descend(scene, **({} if max_rise_mps is None else {"final_start_max_rise_mps": max_rise_mps}))
    a_m, w = 0.5, 1.2
    rng = np.random.default_rng(5)

    def water_up_m(t: float) -> float:
        return a_m * math.sin(w * t)

    starts, t_s, radar_next_s = [], 100.0, 100.0
    for _ in range(round(40.0 / DT)):
        t_s += DT
        if t_s >= radar_next_s:  # the radar's sample of the surface under the vehicle (down), 2 cm noise
            scene.sea_level.update(t_s, -water_up_m(t_s) + float(rng.normal(0.0, 0.02)))
            radar_next_s += 0.1
        was = target.plunging
        state = target.target_at(t_s)
        assert state is not None
        if target.plunging and not was:
            starts.append(t_s)
            target.plunging = False  # back to the final height: the next start is judged again
        target.height_m = max(target.height_m, target.final_height_now_m())
        scene.vehicle_height_m = target.height_m
    rises = [a_m * w * math.cos(w * t) for t in starts]
    print(f"{len(starts)} starts; water rising at them: max {max(rises):+.2f} m/s (swell ±{a_m * w:.2f})")
    if max_rise_mps is None:
        assert len(starts) > 100 and max(rises) > 0.5  # every tick again, rising or not
    else:
        # the slope of the last 0.4 s lags the swell by 0.2 s and carries ~0.06 m/s of the radar's noise
        assert len(starts) > 100 and max(rises) < a_m * w * math.sin(w * 0.2) + 0.2
        assert min(rises) < -0.5  # it does start, behind the crests


def test_a_final_descent_the_lead_lifted_over_the_final_height_still_turns_back_off_the_object():
    """A vehicle rising with a crest (lifted clear of it, with inertia) drags its final descent's desired height up
    with it (the lead): above the final height it is still a final descent, and drifting past the abort radius
    turns it back. It did not (sea state 3, two ArduCopter runs): the desired height, 0.15 m over the final
    height, held, the vehicle went on down as the crest came up and met it 0.27–0.28 m off the object."""
    scene = Scene(crest_m=0.2)
    target = descend(scene, final_max_lead_m=0.1)
    t_s = fly(target, scene, 100.0, 7.0)  # over the object: into the final part
    assert target.plunging and target.height_m < 1.0
    scene.vehicle_height_m = 1.4  # the vehicle rises (and does not follow): the lead lifts the desired height
    t_s = fly(target, scene, t_s, 0.2, follow=False)
    assert target.plunging and target.height_m > target.final_height_now_m()
    scene.vehicle_ne = (0.25, 0.0)  # past the abort radius
    fly(target, scene, t_s, 0.1, follow=False)
    assert not target.plunging and target.go_arounds == 1 and scene.final_descent_given_up


@pytest.mark.parametrize("close_m", [0.5, None])
def test_no_final_descent_starts_while_the_radar_is_silent_right_after_seeing_the_water_close(close_m):
    """Silence right after a height closer than the crest clearance is a crest inside the radar's first range, not
    a radar that cannot tell how the water moves: no final descent starts until that hold has passed (one that
    did, met the crest 0.27–0.28 m off the object). Silence after the water well clear starts it at once."""
    scene = Scene(crest_m=0.7)
    target = descend(scene, crest_clearance_m=0.8, final_start_max_rise_mps=0.0)
    scene.vehicle_ne = (0.15, 0.0)  # not over the object: it waits at the final height
    t_s = fly(target, scene, 100.0, 10.0)
    assert not target.plunging and scene.sea_level.rise_rate_mps(t_s) is None  # (no radar for 60 s: unknown)
    scene.radar_m = 1.0 if close_m is None else close_m
    t_s = fly(target, scene, t_s, DT)
    scene.radar_m, scene.vehicle_ne = None, (0.0, 0.0)  # silent, and right over the object now
    started_after_s, t0_s = None, t_s
    for _ in range(round(1.5 / DT)):
        t_s = fly(target, scene, t_s, DT, follow=False)
        if target.plunging:
            started_after_s = t_s - t0_s
            break
    print(f"close height {close_m}: the final descent started {started_after_s} s into the silence")
    assert started_after_s is not None
    assert started_after_s > 1.0 if close_m is not None else started_after_s <= 2 * DT
