"""Guards judge a frozen snapshot of the mission's estimates; the mission owns its figures."""

from __future__ import annotations

import dataclasses

import pytest

from app.messages import TargetState
from app.missions.circle import CircleMission
from app.missions.estimates import Estimates, NoEstimates
from app.missions.guards import circle_laps_done
from app.missions.runner import mission_model_for
from app.missions.table import load_mission


def test_the_snapshot_cannot_be_changed_after_it_was_taken():
    progress = {"circle_laps": 1.0}
    e = Estimates(5.0, TargetState(5.0, (1.0, 2.0, 0.0), (0.1, 0.0, 0.0)), progress=progress)
    progress["circle_laps"] = 9.0  # the mission's live dict moves on ...
    assert e.progress["circle_laps"] == 1.0  # ... the snapshot does not
    with pytest.raises(TypeError):
        e.progress["circle_laps"] = 2.0  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        e.fix_age_s = 0.0  # type: ignore[misc]


def test_circle_laps_come_from_the_missions_snapshot_not_from_the_setpoint_loop():
    mission = CircleMission()
    assert mission.snapshot(100.0).progress["circle_laps"] == 0.0  # not started
    mission.start((0.0, 0.0, -5.0), t0_s=100.0, radius_m=4.0, v_reduction_s=4.0, settle_s=10.0)
    three_laps_s = 100.0 + 3 * 2 * 3.141592653589793 * 4.0
    before, after = mission.snapshot(three_laps_s - 0.1), mission.snapshot(three_laps_s + 0.1)

    class Ctx:  # only what the guard reads
        params = load_mission("circle").params

        def __init__(self, e):
            self.estimates = e

    assert not circle_laps_done(Ctx(before)) and circle_laps_done(Ctx(after))  # type: ignore[arg-type]
    assert mission.summary()["tracking_samples"] == 0


def test_the_model_follows_the_actions_a_table_uses():
    table = load_mission("circle")
    assert isinstance(mission_model_for(table), CircleMission)
    states = {k: v.model_copy(update={"entry": tuple(a for a in v.entry if a != "start_circle")})
              for k, v in table.states.items()}  # fmt: skip
    no_circle = table.model_copy(update={"states": states})
    assert isinstance(mission_model_for(no_circle), NoEstimates)
