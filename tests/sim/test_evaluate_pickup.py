"""The pickup's Monte Carlo evaluation (``python -m sim.evaluate``): a small one through the real CLI, its lines, its
JSON and every run's ``run.mcap`` checked, the same runs on a Dask ``LocalCluster``, bad options refused, and the
world's switches."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.missions.pickup_feeds import PickupFeeds
from app.missions.table import load_mission
from app.settings import load_settings
from sim import evaluate_cli
from sim.evaluate_jobs import run_jobs
from sim.evaluate_pickup import OUTCOMES, mission_params, run_settings
from sim.evaluate_report import summarise, table
from sim.inproc import InProcessVehicle
from sim.pickup_eval_world import CLUTTER_KINDS, EvalPickupWorld
from sim.pickup_scenarios import CONFIGS, CV_TUNED_Q, ESTIMATOR_PRESETS, PROFILES, sample_scenario, sample_scenarios
from sim.pickup_world import CONTACT_M, GRIP_REACH_M, PickupScenario, PickupWorld
from sim.touchdown_breakdown import breakdown
from sim.wind import WindConfig
from tests.mcaputil import PICKUP_TOPICS, check_run_mcap

ROOT = Path(__file__).resolve().parents[2]
SEED, RUNS, SEA_STATE = 23, 2, 1  # two quick scenarios: buoys, one on PX4 (picked up), one on ArduPilot
CLI = ["--runs", str(RUNS), "--seed", str(SEED), "--sea-state", str(SEA_STATE), "--compare", "thesis,seapick"]
NUMBERS = {"touchdown_error_m", "time_to_pickup_s"}
EVERY_RUN_TOPICS = ("/tf", "/vehicle/pose", "/vehicle/truth", "/object/truth", "/setpoint", "/mission/state", "/log")


@pytest.fixture(scope="module")
def evaluation(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("eval")
    done = subprocess.run(
        [sys.executable, "-m", "sim.evaluate", *CLI, "--jobs", "2", "--json", "--run-reports", "--out", str(out)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = (out / "results.jsonl").read_text().splitlines()
    return {"out": out, "json": done.stdout, "stderr": done.stderr, "results": [json.loads(x) for x in lines]}


def test_every_result_line_is_well_formed(evaluation):
    """One line per scenario and configuration, each with the fields, types, ranges and vocabulary promised."""
    results = evaluation["results"]
    assert [(r["config"], r["run"]) for r in results] == [(c, i) for c in ("thesis", "seapick") for i in range(RUNS)]
    scenarios = sample_scenarios(SEED, RUNS, SEA_STATE)
    for r in results:
        sc = r["scenario"]
        assert sc == scenarios[r["run"]] and r["seed"] == sc["seed"]  # the same scenarios for both configurations
        assert sc["sea_state"] == SEA_STATE and 0.0 <= sc["current_mps"] <= 1.0 and 0.0 <= sc["wind_mps"] <= 10.0
        assert 0.0 <= sc["latency_s"] <= 0.25 and 40.0 <= math.hypot(*sc["object_start_ne_m"]) <= 80.0
        assert sc["object_kind"] in ("marker", "buoy") and sc["clutter"] in CLUTTER_KINDS
        assert sc["profile"] in PROFILES and sc["estimator"] in ESTIMATOR_PRESETS
        assert r["config"] in CONFIGS and r["outcome"] in OUTCOMES
        for k in NUMBERS:
            assert r[k] is None or (isinstance(r[k], float) and r[k] >= 0.0), k
        assert (r["outcome"] == "picked_up") == (r["abort_reason"] is None)
        assert r["outcome"] != "picked_up" or r["time_to_pickup_s"] is not None  # (a catch can still end in ABORT)
        assert r["touchdown_error_m"] is not None or r["grabs"] == 0
        for k in ("retries", "grabs", "envelope_violations", "off_target_touchdowns"):
            assert isinstance(r[k], int) and r[k] >= 0, k
        assert r["retries"] == max(0, r["grabs"] - 1) and r["off_target_touchdowns"] <= r["grabs"]
        assert isinstance(r["safety_violations"], list) and isinstance(r["fixes_rejected"], dict)
        assert isinstance(r["caught"], bool) and (not r["caught"] or r["grabs"] >= 1)
        # how high over the water the gripper closed, on the grab touchdown_error_m is from: with it, and a catch
        # only within the gripper's reach
        assert (r["grab_height_m"] is None) == (r["touchdown_error_m"] is None)
        assert r["grab_height_m"] is None or isinstance(r["grab_height_m"], float)
        assert not r["caught"] or r["grab_height_m"] < GRIP_REACH_M
        assert r["mission_s"] > 30.0 and 0.0 < r["wall_s"] < r["mission_s"]  # virtual time: faster than real
    print([(r["config"], r["outcome"], r["touchdown_error_m"], r["abort_reason"]) for r in results])
    assert any(r["outcome"] == "picked_up" for r in results)
    assert "runs" in evaluation["stderr"]  # the progress bar
    for f in ("report.png", "index.html", "summary.json"):
        assert (evaluation["out"] / f).stat().st_size > 500, f


def test_every_run_has_a_run_mcap_that_reads_back_channel_by_channel(evaluation):
    """Each run's directory holds run.mcap, linked from index.html; read back with the mcap reader every topic is
    there with messages in time order within the run, and a mid-run pose is its record's (a picked-up run: every
    pickup topic, the estimate, its covariance, the fixes and the radar's height too)."""
    index = (evaluation["out"] / "index.html").read_text()
    for r in evaluation["results"]:
        run_dir = evaluation["out"] / "runs" / r["config"] / f"{r['run']:04d}"
        picked_up = r["outcome"] == "picked_up"
        topics = PICKUP_TOPICS if picked_up else {t: PICKUP_TOPICS[t] for t in EVERY_RUN_TOPICS}
        rec = check_run_mcap(run_dir, topics)
        assert rec.counts["/mission/state"] == len(
            [x for x in (run_dir / "events.jsonl").read_text().splitlines() if '"kind":"state"' in x]
        )
        assert f"runs/{r['config']}/{r['run']:04d}/run.mcap" in index


def test_a_picked_up_runs_grabs_break_down_into_tracking_and_estimate_error(evaluation):
    """``sim.touchdown_breakdown`` on a real run directory: a line per grab, the caught one's touchdown error is the
    result line's, and the gripper closed on a fix at most ``grab_blind_max_s`` (0.5 s) old plus a frame or two."""
    picked = [r for r in evaluation["results"] if r["config"] == "seapick" and r["outcome"] == "picked_up"]
    assert picked
    blind_max_s = load_mission("pickup").params.grab_blind_max_s
    for r in picked:
        grabs = breakdown(evaluation["out"] / "runs" / r["config"] / f"{r['run']:04d}")
        print(r["run"], grabs)
        assert len(grabs) == r["grabs"]
        assert r["touchdown_error_m"] in [pytest.approx(g.touchdown_error_m, abs=1e-4) for g in grabs]
        for g in grabs:
            assert g.blind_s is not None and 0.0 <= g.blind_s <= blind_max_s + 0.15
            assert 0.0 <= g.record_lead_s <= 0.3
            assert 0.0 <= g.tracking_error_m < 1.0 and 0.0 <= g.estimate_error_m < 1.0


def test_the_json_object_is_one_line_and_agrees_with_the_results(evaluation):
    """One JSON object on stdout; each configuration's figures recomputed from results.jsonl; ratio_p95 = a/b."""
    doc = json.loads(evaluation["json"])  # the whole of stdout is the one object
    assert table(doc) in evaluation["stderr"]  # and the table, for the reader, on stderr
    assert list(doc["configs"]) == ["thesis", "seapick"]
    for name, c in doc["configs"].items():
        rs = [r for r in evaluation["results"] if r["config"] == name]
        errs = [r["touchdown_error_m"] for r in rs if r["touchdown_error_m"] is not None]
        success = sum(r["outcome"] == "picked_up" and r["caught"] for r in rs)
        assert c["runs"] == RUNS and c["success_rate"] == success / RUNS
        assert c["false_pickups"] == sum(r["outcome"] == "picked_up" and not r["caught"] for r in rs)
        assert c["touchdown_p50_m"] == (round(float(np.percentile(errs, 50)), 4) if errs else None)
        assert c["touchdown_p95_m"] == (round(float(np.percentile(errs, 95)), 4) if errs else None)
        assert c["off_target_touchdowns"] == sum(r["off_target_touchdowns"] for r in rs)
        heights = [r["grab_height_m"] for r in rs if r["outcome"] == "picked_up" and r["caught"]]
        assert c["grab_height_p50_m"] == (round(float(np.percentile(heights, 50)), 4) if heights else None)
        assert c["caught_above_water"] == sum(h > CONTACT_M for h in heights)
        assert c["envelope_violations"] == sum(r["envelope_violations"] for r in rs)
        assert c["speedup_vs_real_time"] > 5.0
        for field, groups in c["touchdown_by"].items():  # the touchdown error split by the scenario's field
            assert sum(g["touchdowns"] for g in groups.values()) == len(errs)
            assert sum(g["off_target_touchdowns"] for g in groups.values()) == c["off_target_touchdowns"]
            for value, g in groups.items():
                theirs = [r for r in rs if str(r["scenario"][field]) == value]
                mine = [r["touchdown_error_m"] for r in theirs if r["touchdown_error_m"] is not None]
                p50, p95 = (round(float(np.percentile(mine, q)), 4) if mine else None for q in (50, 95))
                off = sum(r["off_target_touchdowns"] for r in theirs)
                assert g == {"touchdowns": len(mine), "p50_m": p50, "p95_m": p95, "off_target_touchdowns": off}
    a, b = doc["configs"]["thesis"]["touchdown_p95_m"], doc["configs"]["seapick"]["touchdown_p95_m"]
    assert doc["ratio_p95"] == (round(a / b, 3) if a is not None and b else None)


def _line(run: int, estimator: str, error_m: float | None, off_target: int) -> dict[str, Any]:
    """A result line with just what the summary reads (a run of seapick at sea state 3)."""
    return {
        "run": run, "config": "seapick", "outcome": "picked_up" if error_m is not None else "failed", "caught": True,
        "scenario": {"sea_state": 3, "estimator": estimator, "profile": "px4", "object_kind": "buoy"},
        "touchdown_error_m": error_m, "grab_height_m": None, "time_to_pickup_s": None, "abort_reason": None,
        "off_target_touchdowns": off_target, "envelope_violations": 0, "safety_violations": [],
        "mission_s": 100.0, "wall_s": 1.0,
    }  # fmt: skip


def test_a_configuration_that_never_touched_down_leaves_the_ratio_null_and_says_so():
    """The thesis configuration at sea state 3 picks nothing up: there is no p95 to divide, and the summary and
    its table say which configuration had no touchdown rather than leaving a bare null; with both down, the ratio
    and no reason."""
    seapick = [_line(0, "gnss", 0.04, 0), _line(1, "gnss", 0.08, 0)]
    never = [{**_line(i, "gnss", None, 0), "config": "thesis"} for i in range(3)]
    summary = summarise(never + seapick, ["thesis", "seapick"])
    assert summary["ratio_p95"] is None
    assert summary["ratio_p95_why"] == "thesis touched down in none of its 3 runs"
    assert "ratio p95 thesis/seapick: — (thesis touched down in none of its 3 runs)" in table(summary)
    down = [{**_line(i, "gnss", 0.12, 0), "config": "thesis"} for i in range(3)]
    summary = summarise(down + seapick, ["thesis", "seapick"])
    assert summary["ratio_p95"] == round(0.12 / 0.078, 3) and "ratio_p95_why" not in summary
    assert f"ratio p95 thesis/seapick: {0.12 / 0.078:.2f}" in table(summary)


def test_off_target_touchdowns_are_split_by_estimator_with_those_of_runs_that_never_picked_up():
    """The touchdown split by the scenario's fields counts each value's off-target touchdowns over all its runs:
    a failed run that met the water off the object is counted, and a value with neither a touchdown nor an
    off-target one is not listed."""
    results = [
        _line(0, "gnss", 0.04, 0),
        _line(1, "gnss", 0.30, 1),  # picked up at last, after meeting the water off the object once
        _line(2, "px4-sih", None, 2),  # never picked up, twice down on the water off it
        _line(3, "perfect", None, 0),  # never touched down at all
    ]
    by = summarise(results, ["seapick"])["configs"]["seapick"]["touchdown_by"]
    assert by["estimator"] == {
        "gnss": {"touchdowns": 2, "p50_m": 0.17, "p95_m": 0.287, "off_target_touchdowns": 1},
        "px4-sih": {"touchdowns": 0, "p50_m": None, "p95_m": None, "off_target_touchdowns": 2},
    }
    assert by["profile"]["px4"]["off_target_touchdowns"] == 3
    text = table(summarise(results, ["seapick"]))
    assert "by estimator: gnss 0.170/0.287 (2, 1 off-target), px4-sih —/— (0, 2 off-target)" in text
    assert "by object_kind: buoy 0.170/0.287 (2, 3 off-target)" in text


def test_a_dask_cluster_gives_the_same_result_per_seed_as_local_processes(evaluation, monkeypatch):
    """The same run function submitted through dask.distributed's Client: identical lines but for the wall time.
    The job carries the evaluation's settings and mission, read once at its start: the run reads no file."""
    from dask.distributed import LocalCluster

    import sim.evaluate_pickup as evaluate_pickup

    local = [r for r in evaluation["results"] if r["config"] == "seapick"][:1]  # one run: ~10 s under the GIL
    inputs = evaluate_pickup.RunInputs.load()

    def no_file(*args: Any) -> None:
        raise AssertionError("a run read a settings or mission file")

    monkeypatch.setattr(evaluate_pickup, "load_settings", no_file)
    monkeypatch.setattr(evaluate_pickup, "load_mission", no_file)
    jobs = [(r["scenario"], r["config"], r["run"], None, inputs) for r in local]
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cluster:
        remote = run_jobs(jobs, 1, cluster.scheduler_address)

    def same(r: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in r.items() if k != "wall_s"}

    assert [same(r) for r in remote] == [same(r) for r in local]


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        ("--runs 0", "argument --runs: 0 is outside"),
        ("--jobs 0", "argument --jobs: 0 is outside"),
        ("--sea-state 9", "argument --sea-state: 9 is outside"),
        ("--compare thesis,nope", "argument --compare: 'thesis,nope': give distinct names"),
        ("--compare seapick,seapick", "give distinct names"),
        ("--dask nonsense", "argument --dask: 'nonsense' is not a scheduler address"),
        ("--out /proc/seapick/out --runs 1", "/proc/seapick"),
        ("--mission no-such-mission --runs 1", "no-such-mission: no such mission file; built-in missions:"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(args, fragment):
    done = subprocess.run(
        [sys.executable, "-m", "sim.evaluate", *args.split()], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2 and fragment in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and done.stdout == ""


def test_a_mission_file_of_ones_own_flies_the_same_scenarios_and_a_bad_one_flies_none(tmp_path, evaluation):
    """``--mission FILE``: a copy of the pickup asking for an operator's landing authorisation (none comes in an
    evaluation) flies the scenario the fixture picked up but never comes down; a bad field is one line, names its
    path, and leaves no output behind."""
    source = (ROOT / "app/missions/pickup.yaml").read_text()
    assert "  land_authorization: false" in source
    mission = tmp_path / "ask-to-land.yaml"
    mission.write_text(source.replace("  land_authorization: false", "  land_authorization: true", 1))
    out = tmp_path / "eval"
    args = ["--runs", "1", "--seed", str(SEED), "--sea-state", str(SEA_STATE), "--no-progress", "--out", str(out)]
    done = subprocess.run(
        [sys.executable, "-m", "sim.evaluate", *args, "--mission", str(mission), "--jobs", "1", "--json"],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    (line,) = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    (flown,) = [r for r in evaluation["results"] if r["config"] == "seapick" and r["run"] == 0]
    assert flown["outcome"] == "picked_up" and line["scenario"] == flown["scenario"]
    assert line["outcome"] == "failed" and line["touchdown_error_m"] is None and line["grabs"] == 0
    assert line["abort_reason"].startswith("TRACK→"), line["abort_reason"]
    assert json.loads(done.stdout)["mission"] == str(mission)

    bad = tmp_path / "bad.yaml"
    bad.write_text(source.replace("  wave_drift_q_m2ps3: 1.0e-4", "  wave_drift_q_m2ps3: 5.0", 1))
    bad_out = tmp_path / "bad-eval"
    done = subprocess.run(
        [sys.executable, "-m", "sim.evaluate", "--runs", "1", "--mission", str(bad), "--out", str(bad_out)],
        cwd=ROOT, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "params.wave_drift_q_m2ps3" in done.stderr and "0.1" in done.stderr, done.stderr
    assert not bad_out.exists()


def test_the_same_seed_and_index_draw_the_same_scenario_whatever_the_number_of_runs():
    assert sample_scenarios(5, 3)[2] == sample_scenario(5, 2) and sample_scenario(5, 2) != sample_scenario(6, 2)


class Recorder:
    def __init__(self) -> None:
        self.items: list[Any] = []

    def put(self, item: Any) -> None:
        self.items.append(item)


async def frames_handed_over(world: PickupWorld, seconds: float) -> list[tuple[float, float]]:
    """(arrival, stamp) of every frame the world hands to the mission in ``seconds`` of virtual time."""
    loop = asyncio.get_running_loop()
    got: list[tuple[float, float]] = []

    class Frames(Recorder):
        def put(self, item: Any) -> None:
            got.append((loop.time(), item.t_s))

    feeds = PickupFeeds()
    feeds.frames = Frames()  # type: ignore[assignment]
    feeds.heights = Recorder()  # type: ignore[assignment]
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(world.sensors(feeds), seconds)
    return got


@pytest.mark.parametrize("stamp_at_arrival", [False, True])
@pytest.mark.looptime(noop_cycles=2)
async def test_frames_carry_their_capture_time_unless_stamped_at_arrival(stamp_at_arrival):
    """By default (today's behaviour) a frame reaches the mission ``latency_s`` later with its capture time; with
    ``stamp_at_arrival`` (the thesis: no latency compensation) it carries the time it arrived."""
    scenario = PickupScenario(seed=1, latency_s=0.15, stamp_at_arrival=stamp_at_arrival)
    world = PickupWorld(InProcessVehicle(seed=1, wind=WindConfig.off()), scenario, load_settings())
    got = await frames_handed_over(world, 2.0)
    ages = [arrived - stamp for arrived, stamp in got]
    assert len(got) >= 25
    if stamp_at_arrival:
        assert max(ages) == 0.0
    else:
        assert all(0.15 <= a < 0.15 + scenario.frame_period_s + 1e-9 for a in ages)


@pytest.mark.looptime(noop_cycles=2)
async def test_full_frame_detection_hands_frames_over_later_and_in_order():
    """The thesis's full-frame detector adds ~16 ms a frame (as measured); frames still arrive in capture order."""
    scenario = PickupScenario(seed=1, latency_s=0.06)
    world = EvalPickupWorld(InProcessVehicle(seed=1, wind=WindConfig.off()), scenario, load_settings(), "none", True)
    extra = [world.frame_latency_s() - 0.06 for _ in range(2000)]
    assert 0.013 <= float(np.median(extra)) <= 0.018 and 0.018 <= float(np.percentile(extra, 95)) <= 0.024
    got = await frames_handed_over(world, 2.0)
    stamps = [s for _, s in got]
    assert stamps == sorted(stamps) and len(stamps) >= 25


def test_results_are_on_disk_as_they_come_in_and_an_evaluation_that_dies_keeps_them(tmp_path, monkeypatch, evaluation):
    """Each result is appended to results.partial.jsonl when it arrives; a finished evaluation removes it (its
    results.jsonl holds them all), one that dies half-way leaves the lines flown so far."""
    assert not (evaluation["out"] / evaluate_cli.PARTIAL_RESULTS).exists()
    flown = evaluation["results"][:3]

    def dies_after_three(jobs, processes, dask_address, progress):
        for r in flown:
            progress(r)
        raise KeyboardInterrupt  # the machine went away

    monkeypatch.setattr(evaluate_cli, "run_jobs", dies_after_three)
    with pytest.raises(KeyboardInterrupt):
        evaluate_cli.main([*CLI, "--no-progress", "--out", str(tmp_path)])
    kept = [json.loads(x) for x in (tmp_path / evaluate_cli.PARTIAL_RESULTS).read_text().splitlines()]
    assert kept == flown and not (tmp_path / "results.jsonl").exists()


def test_a_glyph_metres_off_the_tracked_marker_does_not_hide_it_but_hides_it_from_a_fresh_search():
    """The glyph clutter as the marker detector meets it: searching the whole frame, the ID twice gives no
    detection; tracking the marker (reported the frame before), the window around it does not reach a glyph 4 m
    off, so the marker is still reported."""
    from types import SimpleNamespace

    from sim.sea import FloatingObject

    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.0, object_start_ne_m=(40.0, 20.0))
    world = EvalPickupWorld(InProcessVehicle(seed=1, wind=WindConfig.off()), scenario, load_settings(), "glyph")
    world.glyph = FloatingObject(world.sea, start_ne_m=(44.0, 20.0))  # 4 m north of the object
    obj = world.object.state(0.0).pos_ned_m

    def seen_from(n_m: float, height_m: float) -> bool:
        truth = SimpleNamespace(pos_ned_m=(n_m, 20.0, -height_m), roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0)
        seen = world._largest_seen(0.0, truth, obj)
        return seen.corners_px is not None

    # from 8 m the 0.20 m glyph spans 15 px on the settings' 600 px lens (decodable: ≥ 14 px), the marker 22 px
    assert not seen_from(42.0, 8.0)  # both in view, nothing tracked: no detection
    assert world._tracked_ne_m is None and world.glyph_frames == 0
    assert seen_from(40.0, 3.0)  # low over the marker: the glyph (4 m off) is out of view (3.2 m at most)
    assert world._tracked_ne_m == (float(obj[0]), float(obj[1]))
    assert seen_from(42.0, 8.0)  # both in view again, but the marker is tracked
    assert world.glyph_frames == 0
    world._tracked_ne_m = None  # the track lost: a fresh search sees the ID twice
    assert not seen_from(42.0, 8.0)


def test_the_stock_lens_configuration_flies_the_1000_px_lens_and_the_others_the_settings_lens():
    """``seapick-stock-lens`` changes the camera's focal length and nothing else; the geometric camera sees with it."""
    settings = load_settings()
    sc = sample_scenario(SEED, 0, 3)
    flown = {name: run_settings(sc, cfg, settings) for name, cfg in CONFIGS.items()}
    assert settings.camera.fx_px == settings.camera.fy_px == 600.0
    assert {name: (s.camera.fx_px, s.camera.fy_px) for name, s in flown.items()} == {
        name: (1000.0, 1000.0) if name == "seapick-stock-lens" else (600.0, 600.0) for name in CONFIGS
    }
    stock, seapick = flown["seapick-stock-lens"], flown["seapick"]
    assert stock.model_copy(update={"camera": seapick.camera}) == seapick
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.0, object_start_ne_m=(40.0, 20.0))
    world = EvalPickupWorld(InProcessVehicle(seed=1, wind=WindConfig.off()), scenario, stock, "none")
    assert world.fx_px == 1000.0


@pytest.mark.parametrize("sea_state", sorted(CV_TUNED_Q))
def test_each_configuration_flies_its_filter_told_of_the_sea(sea_state):
    """The wave filter gets the sea state (its Hs and Tp), gated; the thesis's constant-velocity filter the process
    noise tuned for that sea, without a gate; and the mission accepts both."""
    from app.estimators.cv_filter import ConstantVelocityFilter
    from app.estimators.factory import make_target_filter
    from app.estimators.wave_filter import WaveFilter
    from app.missions.table import load_mission

    sc = sample_scenario(SEED, 0, sea_state)
    base = load_mission("pickup").params
    thesis = base.model_copy(update=mission_params(sc, CONFIGS["thesis"]))
    seapick = base.model_copy(update=mission_params(sc, CONFIGS["seapick"]))
    cv, wave = make_target_filter(thesis), make_target_filter(seapick)
    q_pos, q_vel = CV_TUNED_Q[sea_state]
    assert isinstance(cv, ConstantVelocityFilter) and (cv.q_pos_m2ps, cv.q_vel_m2ps3) == (q_pos, q_vel)
    assert not cv.innovation_gate and wave.innovation_gate  # the thesis fused every fix (Listing 4.1)
    assert isinstance(wave, WaveFilter) and seapick.sea_state == thesis.sea_state == sea_state
    assert (seapick.cv_q_pos_m2ps, seapick.cv_q_vel_m2ps3) == (base.cv_q_pos_m2ps, base.cv_q_vel_m2ps3)
    assert thesis.search_start_ne_m == seapick.search_start_ne_m == tuple(sc["object_start_ne_m"])
    lean = base.model_copy(update=mission_params(sc, CONFIGS["seapick-lean"]))
    assert seapick.lean_yaw_min_tilt_deg is None and thesis.lean_yaw_min_tilt_deg is None  # the heading held
    assert lean.lean_yaw_min_tilt_deg == 5.0 and lean.target_filter == seapick.target_filter
    # low down, seapick's fixes take the height from the object's size (the mission's default); the thesis's and
    # seapick-held's the radar's (held)
    held = base.model_copy(update=mission_params(sc, CONFIGS["seapick-held"]))
    from app.flight import build_mission_model
    from app.settings import Settings

    table = load_mission("pickup")
    checks = {
        name: build_mission_model(table.model_copy(update={"params": params}), Settings()).checks.height_from_size
        for name, params in [("thesis", thesis), ("seapick", seapick), ("seapick-held", held), ("seapick-lean", lean)]
    }
    assert checks == {"thesis": False, "seapick": True, "seapick-held": False, "seapick-lean": True}
    assert seapick.fix_height_from_size == base.fix_height_from_size  # seapick flies the mission's defaults
    # seapick's wave filter is the mission's default, the fine bank: 14 narrower oscillators (damping 0.03 against
    # 0.1) over 0.6-3.0·ω_p; seapick-standard's the 8 at 0.7-2.3·ω_p (the default before), seapick-wide's those and
    # two more for the short waves (at 2.8 and 3.4·ω_p); a glassy sea has none
    assert seapick.wave_oscillators == base.wave_oscillators == "fine"
    assert seapick.wave_drift_q_m2ps3 == base.wave_drift_q_m2ps3 == 1e-4  # (the mission's; 1e-6 before the fine bank)
    assert wave.q_current_m2ps3 == 1e-4
    standard = make_target_filter(base.model_copy(update=mission_params(sc, CONFIGS["seapick-standard"])))
    wide = make_target_filter(base.model_copy(update=mission_params(sc, CONFIGS["seapick-wide"])))
    assert isinstance(wide, WaveFilter) and wide.innovation_gate and isinstance(standard, WaveFilter)
    assert wave.damping == 0.03 and standard.damping == wide.damping == 0.1 and standard.q_current_m2ps3 == 1e-6
    if sea_state == 0:
        assert len(wide.omegas) == len(standard.omegas) == len(wave.omegas) == 0
    else:
        assert len(wide.omegas) == len(standard.omegas) + 2 == 10 and len(wave.omegas) == 14
        assert wide.omegas[-1] / wide.omegas[2] == pytest.approx(3.4)
        assert standard.omegas[-1] / standard.omegas[2] == pytest.approx(2.3)
        assert wave.omegas[-1] / wave.omegas[0] == pytest.approx(3.0 / 0.6)


def test_a_run_flies_the_same_with_its_report_as_without(tmp_path):
    """``--run-reports`` only watches: the result line of a run with its event log, truth trace, report and MCAP is
    the one without them (a trace task of its own, sleeping 0.2 s at a time, had turned a pickup into a failure)."""
    from sim.evaluate_pickup import run_pickup

    sc = sample_scenario(1, 8, 3)  # a buoy at sea state 3, on ArduPilot: picked up only without the old trace task
    bare = run_pickup(sc, "seapick", 8)
    reported = run_pickup(sc, "seapick", 8, str(tmp_path))
    bare.pop("wall_s"), reported.pop("wall_s")
    print(bare)
    assert reported == bare
    trace = [json.loads(x) for x in (tmp_path / "sim_state.jsonl").read_text().splitlines()]
    truth_t = [r["t_s"] for r in trace if r["event"] == "truth"]
    assert len(truth_t) > 100 and all(0.19 < b - a < 0.21 for a, b in itertools.pairwise(truth_t))
    assert (tmp_path / "report.png").stat().st_size > 0 and (tmp_path / "run.mcap").stat().st_size > 0
