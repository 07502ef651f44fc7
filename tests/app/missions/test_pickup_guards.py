"""The pickup's touchdown and verify guards on hand-made snapshots: when the water counts as reached, when a
grab counts as off target, and when the object counts as in the gripper."""

from __future__ import annotations

import dataclasses

from app.messages import PositionVelocityNed, TargetState, TelemetrySnapshot
from app.missions.estimates import Estimates
from app.missions.guards import (
    GuardContext,
    grab_gone_off,
    lock_renewed,
    object_beyond_fence,
    object_in_gripper,
    pickup_time_up,
    ready_to_descend,
    touchdown,
    touchdown_off_target,
)
from app.missions.table import load_mission
from app.offboard.boundary import LinkHealth

PARAMS = load_mission("pickup").params  # touchdown 0.3 m, grab offset 0.15 m, verify 3 m for 2 s


def ctx(estimates: Estimates, vehicle_ne=(0.0, 0.0), time_in_state_s: float = 5.0, state: str = "DESCEND"):
    n, e = vehicle_ne
    tel = TelemetrySnapshot(pos_vel=PositionVelocityNed(10.0, (n, e, -0.3), (0.0, 0.0, 0.0)))
    health = LinkHealth(10.0, 0.1, 0.01, 0.01, 0, 0)
    return GuardContext(10.0, state, time_in_state_s, tel, health, PARAMS, estimates, abort_requested=False)


def est(**kw) -> Estimates:
    target = TargetState(10.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    return Estimates(10.0, **({"target": target, "fix_age_s": 0.1, "converged_for_s": 3.0} | kw))


def test_the_mean_sea_counts_only_while_the_radar_reads_nothing():
    # 0.25 m over the mean sea, but the radar sees the water 0.9 m below (a trough): not there yet
    assert not touchdown(ctx(est(height_above_sea_m=0.9, height_over_mean_sea_m=0.25)))
    # the radar reads nothing (the sea inside its first range) and the mean is that close: at the water
    assert touchdown(ctx(est(height_above_sea_m=None, height_over_mean_sea_m=0.25)))
    assert touchdown(ctx(est(height_above_sea_m=0.25, height_over_mean_sea_m=0.8)))
    assert not touchdown(ctx(est(height_above_sea_m=None, height_over_mean_sea_m=0.6)))


def test_at_the_water_off_the_estimate_is_no_grab():
    low = est(height_above_sea_m=None, height_over_mean_sea_m=0.2)
    assert not touchdown_off_target(ctx(low, vehicle_ne=(0.1, 0.0)))
    assert touchdown_off_target(ctx(low, vehicle_ne=(0.2, 0.0)))
    assert touchdown_off_target(ctx(Estimates(10.0, height_over_mean_sea_m=0.2)))  # no estimate at all
    assert not touchdown_off_target(ctx(est(height_above_sea_m=1.5), vehicle_ne=(0.5, 0.0)))  # not at the water


def test_at_the_water_with_a_stale_fix_is_no_grab():
    """Over the estimate, but the object went out of view on the way down: the estimate is no longer trusted."""
    fresh_s = load_mission("pickup").params.grab_fix_max_age_s
    at_water = {"height_above_sea_m": None, "height_over_mean_sea_m": 0.2}
    assert not touchdown_off_target(ctx(est(**at_water, fix_age_s=fresh_s - 0.05)))
    assert touchdown_off_target(ctx(est(**at_water, fix_age_s=fresh_s + 0.05)))


def test_a_touchdown_a_second_after_the_last_fix_is_no_grab():
    """Sea state 3, seed 3 run 161 (0.8 m/s current, 0.22 s camera latency): the mean sea said "at the water" over
    a trough with the radar silent, 0.095 m off the estimate but 1.0 s after the last fix — the estimate was
    0.17 m behind the object, the gripper closed 0.26 m off it, and sitting on for the grab the vehicle met a
    crest 0.41 m off. The 187 good grabs of seed 2's traced runs came on fixes at most 0.87 s old, so the default
    refuses this one."""
    assert PARAMS.grab_fix_max_age_s < 1.0
    at_water = {"height_above_sea_m": None, "height_over_mean_sea_m": 0.015}
    assert touchdown_off_target(ctx(est(**at_water, fix_age_s=1.0), vehicle_ne=(0.07, 0.064)))
    assert not touchdown_off_target(ctx(est(**at_water, fix_age_s=0.6), vehicle_ne=(0.07, 0.064)))


def test_at_the_water_by_the_mean_sea_over_water_falling_away_is_no_grab():
    """Sea state 3, seed 1 runs 69 and 125: the radar went silent 0.5 m over a deepening trough, the mean sea said
    "at the water", and the blind sink chased the water down for 0.6-0.7 s — meeting it 0.27 and 0.33 m off the
    object. With ``grab_max_fall_mps`` set, water last seen falling faster than that is no grab: climb back. Only
    when the mean sea is all there is: not when the radar reads the water, nor once the autopilot says landed."""
    from app.messages import LandedState, Stamped

    p = PARAMS.model_copy(update={"grab_max_fall_mps": 0.25})
    at_mean = {"height_above_sea_m": None, "height_over_mean_sea_m": 0.17}

    def judged(params, landed: bool = False, **kw) -> bool:
        c = ctx(est(**kw))
        if landed:
            tel = dataclasses.replace(c.telemetry, landed_state=Stamped(10.0, LandedState.ON_GROUND))
            c = dataclasses.replace(c, telemetry=tel)
        return touchdown_off_target(dataclasses.replace(c, params=params))

    assert judged(p, **at_mean, progress={"water_falling_mps": 0.37})
    assert not judged(p, **at_mean, progress={"water_falling_mps": 0.13})
    assert not judged(p, **at_mean, progress={"water_falling_mps": -0.3})  # rising: the water comes to it
    assert not judged(p, **at_mean)  # not known (the radar silent for over a second)
    assert not judged(p, height_above_sea_m=0.25, progress={"water_falling_mps": 0.37})  # the radar sees it there
    assert not judged(p, landed=True, **at_mean, progress={"water_falling_mps": 0.37})  # on it already
    assert judged(PARAMS, **at_mean, progress={"water_falling_mps": 0.37}) is (PARAMS.grab_max_fall_mps is not None)


def test_at_the_water_after_descend_gave_its_final_part_up_is_no_grab():
    """DESCEND had given the final part up (drifted or gone blind off the object) and was climbing back when a
    crest met it: right over the estimate and with a fresh fix, still no grab there."""
    at_water = {"height_above_sea_m": 0.25}
    assert not touchdown_off_target(ctx(est(**at_water, progress={"final_descent_given_up": 0.0})))
    assert touchdown_off_target(ctx(est(**at_water, progress={"final_descent_given_up": 1.0})))
    assert touchdown(ctx(est(**at_water, progress={"final_descent_given_up": 1.0})))  # it is at the water


def test_no_new_descent_from_the_water():
    """Back in TRACK from an off-target touchdown, a fresh converged fix right above the object is not enough: the
    vehicle must have left the water (else its touchdown fires again at once and it grabs where it judged it must
    not)."""
    assert ready_to_descend(ctx(est(height_above_sea_m=4.0), state="TRACK"))
    assert ready_to_descend(ctx(est(height_above_sea_m=PARAMS.touchdown_height_m + 0.05), state="TRACK"))
    assert not ready_to_descend(ctx(est(height_above_sea_m=PARAMS.touchdown_height_m - 0.05), state="TRACK"))
    assert not ready_to_descend(ctx(est(height_above_sea_m=None, height_over_mean_sea_m=0.2), state="TRACK"))
    assert not ready_to_descend(ctx(est(height_above_sea_m=4.0), vehicle_ne=(0.5, 0.0), state="TRACK"))  # not over it


def test_in_the_gripper_only_after_looking_from_up_there_for_the_verify_time():
    def verify(up_for_s: float, fix_age_s: float | None = None, sighting_age_s: float = float("inf")):
        e = Estimates(
            10.0, fix_age_s=fix_age_s, height_above_sea_m=3.0,
            progress={"verify_up_for_s": up_for_s, "grab_sighting_age_s": sighting_age_s},
        )  # fmt: skip
        return object_in_gripper(ctx(e, time_in_state_s=6.0, state="VERIFY"))

    assert verify(up_for_s=2.5)
    assert not verify(up_for_s=1.0)  # 6 s in VERIFY, but most of it spent climbing: not looked long enough
    assert not verify(up_for_s=-1.0)  # never got up there
    assert not verify(up_for_s=2.5, fix_age_s=0.5)  # a fix of the object on the sea since the climb began
    assert not verify(up_for_s=2.5, sighting_age_s=3.0)  # seen where the grab was (no lock needed)


def test_an_object_beyond_the_geofence_is_beyond_reach():
    def beyond(target_ne=None, centre_ne=(0.0, 0.0), fence_m=100.0) -> bool:
        target = None if target_ne is None else TargetState(10.0, (*target_ne, 0.0), (0.0, 0.0, 0.0))
        progress = {"search_centre_n_m": centre_ne[0], "search_centre_e_m": centre_ne[1]}
        c = ctx(Estimates(10.0, target=target, progress=progress), state="SEARCH")
        return object_beyond_fence(dataclasses.replace(c, geofence_radius_m=fence_m))

    assert beyond(target_ne=(60.0, 80.0))  # 100 m out: on the fence
    assert not beyond(target_ne=(60.0, 70.0))
    assert beyond(centre_ne=(0.0, 99.0))  # no estimate: where the search has drifted to
    assert not beyond(centre_ne=(0.0, 97.0))
    assert not beyond(target_ne=(60.0, 80.0), fence_m=400.0)


def test_the_pickup_time_limit_counts_from_the_first_flying_state():
    limit_s = PARAMS.pickup_time_limit_s
    on_deck = ctx(est())
    assert on_deck.airborne_for_s is None and not pickup_time_up(on_deck)
    assert not pickup_time_up(dataclasses.replace(on_deck, airborne_for_s=limit_s - 1.0))
    assert pickup_time_up(dataclasses.replace(on_deck, airborne_for_s=limit_s + 1.0))


def test_a_lock_begun_after_the_descent_began_sends_it_back_to_track():
    """DESCEND goes on only over the object it began over: a lock that began since (the filter escaped onto other
    fixes, or a lost lock was confirmed anew) is a new object until TRACK has seen it converge right above it."""
    table = load_mission("pickup")
    assert any(t.when == "lock_renewed" and t.to == "TRACK" for t in table.states["DESCEND"].transitions)
    assert lock_renewed(ctx(est(progress={"lock_age_s": 1.9}), time_in_state_s=2.0))
    assert not lock_renewed(ctx(est(progress={"lock_age_s": 2.1}), time_in_state_s=2.0))
    assert not lock_renewed(ctx(est(), time_in_state_s=2.0))  # (no lock reported: nothing renewed)


def test_a_lock_begun_during_the_grabs_sink_sends_it_back_until_the_gripper_has_closed():
    """GRAB's sink follows the estimate as DESCEND does: a new lock before the gripper closed sends it back to
    TRACK; once it closed in this state, VERIFY is the one to look at what it holds (an older closing, from a grab
    before, counts for nothing)."""
    table = load_mission("pickup")
    grab = [t.when for t in table.states["GRAB"].transitions]
    assert grab.index("lock_renewed") < grab.index("grab_settled")
    assert table.states["GRAB"].transitions[grab.index("lock_renewed")].to == "TRACK"

    def renewed(lock_age_s: float, gripper_closed_for_s: float) -> bool:
        progress = {"lock_age_s": lock_age_s, "gripper_closed_for_s": gripper_closed_for_s}
        return lock_renewed(ctx(est(progress=progress), time_in_state_s=1.0, state="GRAB"))

    assert renewed(0.4, -1.0)  # a lock 0.4 s old, 1 s into GRAB, the gripper open
    assert not renewed(0.4, 0.2)  # … the gripper closed 0.2 s ago: VERIFY's
    assert renewed(0.4, 30.0)  # … closed 30 s ago, in a grab before this one
    assert not renewed(1.5, -1.0)  # the lock older than this GRAB


def test_a_grab_given_up_off_the_estimate_goes_back_to_track():
    """``grab_gone_off`` is GRAB's own report (the sink came farther than ``grab_abort_offset_m`` off the estimate
    before the water): the mission file sends it back to TRACK, before the gripper's settling is looked at."""
    table = load_mission("pickup")
    grab = [t.when for t in table.states["GRAB"].transitions]
    assert grab.index("grab_gone_off") < grab.index("grab_settled")
    assert table.states["GRAB"].transitions[grab.index("grab_gone_off")].to == "TRACK"
    assert table.params.grab_abort_offset_m == 0.08
    assert grab_gone_off(ctx(est(progress={"grab_gone_off": 1.0}), state="GRAB"))
    assert not grab_gone_off(ctx(est(progress={"grab_gone_off": 0.0}), state="GRAB"))
    assert not grab_gone_off(ctx(est(), state="GRAB"))
