"""Mission tables are validated at load: every error names its YAML path, before anything connects."""

import copy
from pathlib import Path

import pytest
import yaml

from app.errors import MissionTableError
from app.missions.table import MISSIONS_DIR, load_mission

CIRCLE = yaml.safe_load((MISSIONS_DIR / "circle.yaml").read_text())


def write(tmp_path: Path, table: dict) -> str:
    p = tmp_path / "m.yaml"
    p.write_text(yaml.safe_dump(table))
    return str(p)


def broken(tmp_path, mutate, table: dict = CIRCLE) -> MissionTableError:
    t = copy.deepcopy(table)
    mutate(t)
    with pytest.raises(MissionTableError) as e:
        load_mission(write(tmp_path, t))
    return e.value


def test_builtin_circle_loads_by_name_and_by_file_name():
    assert load_mission("circle").mission == "circle"
    assert load_mission("circle.yaml").initial == "PREFLIGHT"


def test_unknown_mission_lists_the_builtin_ones():
    with pytest.raises(MissionTableError, match=r"built-in missions: .*circle"):
        load_mission("nope")


def test_unknown_guard_names_its_path_and_the_known_guards(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["TRACK"]["transitions"][2].update(when="laps_finished"))
    assert e.path == "states.TRACK.transitions[2].when"
    assert "unknown guard 'laps_finished'" in e.message and "circle_laps_done" in e.message


def test_unknown_action_names_its_path(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["TAKEOFF"]["entry"].append("do_a_flip"))
    assert e.path == "states.TAKEOFF.entry[2]" and "unknown action 'do_a_flip'" in e.message


def test_transition_to_unknown_state(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["LAND"]["transitions"][1].update(to="HOME"))
    assert e.path == "states.LAND.transitions[1].to" and "unknown state 'HOME'" in e.message


def test_unreachable_state_is_an_error(tmp_path):
    e = broken(tmp_path, lambda t: t["states"].update(ORPHAN={"terminal": "completed"}))
    assert e.path == "states.ORPHAN" and "unreachable" in e.message


def test_flying_state_without_a_way_to_abort(tmp_path):
    def mutate(t):
        s = t["states"]["TRACK"]
        s["transitions"] = [tr for tr in s["transitions"] if tr["to"] != "ABORT"]
        s["on_timeout"] = "LAND"

    e = broken(tmp_path, mutate)
    assert e.path == "states.TRACK" and "no way to ABORT" in e.message


def test_flying_state_without_timeout(tmp_path):
    def mutate(t):
        del t["states"]["LAND"]["timeout_s"]
        del t["states"]["LAND"]["on_timeout"]

    e = broken(tmp_path, mutate)
    assert e.path == "states.LAND.timeout_s" and "needs a timeout" in e.message


def test_offboard_action_in_an_autopilot_state_is_refused(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["LAND"]["entry"].insert(0, "start_circle"))
    assert e.path == "states.LAND.entry[0]" and "needs control offboard" in e.message


def test_param_out_of_range_names_path_and_allowed_range(tmp_path):
    e = broken(tmp_path, lambda t: t["params"].update(circle_radius_m=500))
    assert e.path == "params.circle_radius_m"
    assert "got 500" in e.message and "allowed 0.5..50.0 m" in e.message


def test_unknown_param_is_refused(tmp_path):
    e = broken(tmp_path, lambda t: t["params"].update(circle_radius=4))
    assert e.path == "params.circle_radius" and "unknown field" in e.message


def test_manual_state_must_not_command(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["MANUAL"].update(control="offboard"))
    assert e.path == "states.MANUAL.control"


def test_mermaid_lists_every_transition():
    m = load_mission("circle").to_mermaid()
    assert "TRACK --> LAND: circle_laps_done" in m and "MANUAL --> TRACK: handed back (from TRACK)" in m


@pytest.mark.parametrize("guard", ["abort_requested", "link_lost", "position_lost", "setpoints_failing"])
def test_a_flying_state_without_a_link_guard_is_refused(tmp_path, guard):
    def drop(t):
        t["states"]["LAND"]["transitions"] = [x for x in t["states"]["LAND"]["transitions"] if x["when"] != guard]

    e = broken(tmp_path, drop)
    assert e.path == "states.LAND.transitions" and f"a flying state needs the guards {guard}" in e.message


def test_abort_requested_must_lead_to_the_abort_state(tmp_path):
    e = broken(tmp_path, lambda t: t["states"]["TRACK"]["transitions"][0].update(to="LAND"))
    assert e.path == "states.TRACK.transitions[0].to" and "abort_requested must lead to the abort state" in e.message


PICKUP = yaml.safe_load((MISSIONS_DIR / "pickup.yaml").read_text())


def broken_pickup(tmp_path, mutate) -> MissionTableError:
    return broken(tmp_path, mutate, PICKUP)


def test_the_pickup_loads_with_its_requests():
    t = load_mission("pickup")
    assert t.requests == {"hold": "HOLD", "rtl": "RETURN"} and t.states["HOLD"].resume["TRACK"] == "TRACK"


def test_a_request_to_an_unknown_or_grounded_state_is_refused(tmp_path):
    e = broken_pickup(tmp_path, lambda t: t["requests"].update(hold="PARK"))
    assert e.path == "requests.hold" and "unknown state 'PARK'" in e.message
    e = broken_pickup(tmp_path, lambda t: t["requests"].update(rtl="DONE"))
    assert e.path == "requests.rtl" and "does not fly" in e.message
    e = broken_pickup(tmp_path, lambda t: t["requests"].update(land_now="LAND_HOME"))
    assert "requests.land_now" in str(e)


def test_only_the_manual_and_the_hold_state_resume(tmp_path):
    e = broken_pickup(tmp_path, lambda t: t["states"]["TRACK"].update(resume={"SEARCH": "SEARCH"}))
    assert e.path == "states.TRACK.resume" and "hold request's state" in e.message


def test_a_choice_param_names_its_path_and_the_choices(tmp_path):
    e = broken(tmp_path, lambda t: t["params"].update(wave_oscillators="huge"))
    assert e.path == "params.wave_oscillators"
    assert "huge" in e.message and "'standard'" in e.message and "'wide'" in e.message
