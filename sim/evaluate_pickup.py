"""One evaluation run of the pickup (many of them: ``sim.evaluate_jobs``).

``run_pickup(scenario, config)`` flies the whole pickup mission (``app.flight.fly_mission``: the same code as a
real flight) on the in-process vehicle with the geometric camera and radar heights (``sim.pickup_eval_world``),
on its own event loop in virtual time (``sim.virtual_loop``: the same clock as looptime's, without its system
calls), and returns one JSON-able dict: a pure function of its
arguments (every random stream is seeded from the scenario), so a local process and a Dask worker give the same
result for the same scenario — only ``wall_s`` differs.

The result's fields: ``run``, ``seed``, ``scenario``, ``config``, ``outcome`` (the mission's — ``picked_up``,
``failed``, ``aborted``, ``pilot`` — or ``timeout`` past ``RUN_LIMIT_S`` of mission time, ``error`` if the run
raised), ``final_state``, ``touchdown_error_m`` (gripper to object, horizontal, from the truth: the grab that
caught it, else the last grab; None without a grab), ``grab_height_m`` (how high the vehicle's lowest point was
over the water under it when the gripper closed on that grab, from the truth: above ``sim.pickup_world.CONTACT_M``
it had not touched the water), ``time_to_pickup_s`` (arming → the grab that caught it),
``retries``, ``grabs``, ``caught`` (the simulator's truth: a grab caught the object),
``abort_reason`` (None when picked up: else the transition that gave up — ``STATE→STATE:
reason`` — or the error), ``envelope_violations`` (setpoints outside the speed envelope or not finite, as the
vehicle received them: ``sim.safety_rules``' ``finite_in_envelope``), ``safety_violations`` (every rule broken),
``off_target_touchdowns`` (touchdowns farther than the scenario's capture radius from the object: grabs, and
the vehicle down on the water without one; ``off_target_grabs`` and ``off_target_contacts`` count each), ``mission_s``,
``wall_s``, ``fixes_rejected`` and ``clutter`` (what the clutter and the detector model did).
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import json
import math
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.cli import one_line
from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.missions.table import MissionTable, load_mission
from app.settings import Settings, load_settings
from sim.airframes import SIM_PROFILES
from sim.estimator import ESTIMATORS
from sim.faults import limits_of
from sim.inproc import InProcessVehicle
from sim.pickup_eval_world import EvalPickupWorld
from sim.pickup_scenarios import CONFIGS, CV_TUNED_Q, EvalConfig
from sim.pickup_world import PickupScenario
from sim.safety_rules import RunFacts, check
from sim.virtual_loop import VirtualTimeLoop
from sim.wind import WindConfig

EVAL_GEOFENCE_M = 400.0  # the evaluation's geofence radius around home (``_fly``)
RUN_LIMIT_S = 1500.0  # mission time; the table's own timeouts end every run well before
# a run allocates short-lived objects by the million and keeps its logs: the collector's first generation
# scanned every 50 000 allocations rather than 700 saves ~5 % of a run's CPU time (a run's heap stays small)
GC_GEN0_THRESHOLD = 50_000
OUTCOMES = ("picked_up", "failed", "aborted", "pilot", "timeout", "error")
TRACE_PERIOD_S = 0.2  # the truth written for a run's report (--run-reports)


@dataclass(frozen=True)
class RunInputs:
    """What every run of an evaluation flies with besides its scenario: the settings and the mission table, read
    once when the evaluation starts (a file edited while it runs must not change its later runs)."""

    settings: Settings
    table: MissionTable

    @classmethod
    def load(cls, mission: str = "pickup") -> RunInputs:
        """The settings and ``mission`` (a built-in mission's name or a file: ``resolve_mission_path``)."""
        return cls(load_settings(), load_mission(mission))


def run_pickup(
    scenario: dict[str, Any], config: str, run: int = 0, run_dir: str | None = None, inputs: RunInputs | None = None
) -> dict[str, Any]:
    """Fly one scenario with one configuration (``CONFIGS``) on a fresh virtual-time loop; see the module docstring.
    ``run_dir``: also write the run's event log, the simulator's truth, ``report.png`` and ``run.mcap`` there.
    ``inputs``: the evaluation's settings and mission (read from their files now when not given)."""
    wall0 = time.perf_counter()
    loop = VirtualTimeLoop()
    try:
        inputs = inputs if inputs is not None else RunInputs.load()
        with _collector_threshold(GC_GEN0_THRESHOLD):
            result = loop.run_until_complete(
                _fly(scenario, CONFIGS[config], inputs, Path(run_dir) if run_dir else None)
            )
    except Exception as e:  # one broken run must not end the evaluation: it is counted as an error
        result = _empty("error", f"{type(e).__name__}: {one_line(e)}")
    finally:
        loop.close()
    wall_s = round(time.perf_counter() - wall0, 3)  # the flight's, not the report's
    if run_dir is not None and result["outcome"] != "error":
        from app.foxglove_log import write_mcap
        from app.report import render_report

        render_report(Path(run_dir), title=f"{config} run {run} (seed {scenario['seed']})")
        try:
            write_mcap(Path(run_dir))
        except Exception as e:  # the recording is a view of the run's logs: without it the result still counts
            print(f"sim.evaluate: {run_dir}: run.mcap not written: {type(e).__name__}: {one_line(e)}", file=sys.stderr)
    return {"run": run, "seed": scenario["seed"], "scenario": scenario, "config": config} | result | {"wall_s": wall_s}


@contextlib.contextmanager
def _collector_threshold(gen0: int) -> Iterator[None]:
    """The garbage collector's first-generation threshold set to ``gen0`` for the block, then put back."""
    before = gc.get_threshold()
    gc.set_threshold(gen0, *before[1:])
    try:
        yield
    finally:
        gc.set_threshold(*before)


def _empty(outcome: str, reason: str) -> dict[str, Any]:
    return {
        "outcome": outcome, "final_state": None, "touchdown_error_m": None, "grab_height_m": None,
        "time_to_pickup_s": None, "retries": 0,
        "grabs": 0, "abort_reason": reason, "envelope_violations": 0, "safety_violations": [], "caught": False,
        "off_target_touchdowns": 0, "off_target_grabs": 0, "off_target_contacts": 0, "mission_s": 0.0,
        "fixes_rejected": {}, "clutter": {},
    }  # fmt: skip


def run_settings(sc: dict[str, Any], cfg: EvalConfig, settings: Settings) -> Settings:
    """The evaluation's settings as scenario ``sc`` flies them with ``cfg``."""
    # the operator sets the fence around the operating area: the objects start 40-80 m out and drift up to 1 m/s
    # for minutes (the default 100 m fence stops the vehicle following most of the faster ones)
    envelope = settings.envelope.model_copy(update={"geofence_radius_m": EVAL_GEOFENCE_M})
    # the operator knows what floats out there: the detector for it (as ``app.main --object``)
    detector = settings.detector.model_copy(update={"kind": "buoy" if sc["object_kind"] == "buoy" else "aruco"})
    camera = settings.camera
    if cfg.camera_f_px is not None:  # the hardware what-if of a configuration (``seapick-stock-lens``)
        camera = camera.model_copy(update={"fx_px": cfg.camera_f_px, "fy_px": cfg.camera_f_px})
    return settings.model_copy(update={"envelope": envelope, "detector": detector, "camera": camera})


async def _fly(sc: dict[str, Any], cfg: EvalConfig, inputs: RunInputs, run_dir: Path | None) -> dict[str, Any]:
    settings = run_settings(sc, cfg, inputs.settings)
    profile = SIM_PROFILES[sc["profile"]]
    wind = WindConfig(mean_mps=sc["wind_mps"], from_deg=sc["wind_from_deg"], gust_sigma_mps=sc["gust_sigma_mps"])
    vehicle = InProcessVehicle(
        seed=sc["seed"],
        wind=wind,
        profile=profile.autopilot,
        vehicle_params=profile.airframe,
        estimator=ESTIMATORS[sc["estimator"]],
    )
    start_ne_m = (float(sc["object_start_ne_m"][0]), float(sc["object_start_ne_m"][1]))
    scenario = PickupScenario(
        seed=sc["seed"],
        sea_state=sc["sea_state"],
        current_mps=sc["current_mps"],
        current_to_deg=sc["current_to_deg"],
        object_start_ne_m=start_ne_m,
        object_kind=sc["object_kind"],
        latency_s=sc["latency_s"],
        pixel_noise_px=sc["pixel_noise_px"],
        stamp_at_arrival=not cfg.latency_compensation,
    )
    world = EvalPickupWorld(vehicle, scenario, settings, sc["clutter"], cfg.full_frame_detection)
    table = inputs.table
    table = table.model_copy(update={"params": table.params.model_copy(update=mission_params(sc, cfg))})
    clock = LoopClock(asyncio.get_running_loop())  # the run's own loop
    events = EventLog(run_dir / "events.jsonl" if run_dir is not None else None)
    states: list[dict[str, Any]] = []
    events.subscribe({"state"}, states.append)
    trace = _TruthTrace(run_dir / "sim_state.jsonl") if run_dir is not None else None
    if trace is not None:
        world.frame_observers.append(trace)
    t0_s = clock.now_s()
    try:
        async with asyncio.timeout(RUN_LIMIT_S):
            flight = await fly_mission(vehicle, table, settings, clock, events, sensors=[world.sensors])
        outcome, reason, final_state = flight.result.outcome, flight.result.reason, flight.result.final_state
        figures = flight.figures
    except TimeoutError:
        outcome, reason, final_state, figures = "timeout", f"still flying after {RUN_LIMIT_S:g} s", None, {}
    finally:
        events.close()
        if trace is not None:
            trace.close()
    end_s = clock.now_s()
    abort_t_s = next((r["t_s"] for r in states if r["to"] == "ABORT"), None)
    facts = RunFacts(
        outcome, reason, frozenset(OUTCOMES), abort_t_s, events.total(), events.total(), grace_s=0.06, end_t_s=end_s
    )
    violations = check(vehicle.records, facts, limits_of(settings))
    grabs = world.outcome.grabs
    caught = [g for g in grabs if g["caught"]]
    touchdown = caught[0] if caught else (grabs[-1] if grabs else None)
    armed_s = next((r["t_s"] for r in vehicle.records if r["event"] == "armed" and r["armed"]), None)
    if run_dir is not None:
        _write_grabs(run_dir, grabs, world.outcome.contacts)
    return {
        "outcome": outcome,
        "final_state": final_state,
        "touchdown_error_m": None if touchdown is None else round(touchdown["error_m"], 4),
        "grab_height_m": None if touchdown is None else round(touchdown["height_m"], 3),
        "time_to_pickup_s": round(caught[0]["t_s"] - armed_s, 2) if caught and armed_s is not None else None,
        "retries": max(0, len(grabs) - 1),
        "grabs": len(grabs),
        "abort_reason": None if outcome == "picked_up" else _gave_up(states, reason),
        "envelope_violations": sum(1 for v in violations if v.rule == "finite_in_envelope"),
        "safety_violations": sorted({v.rule for v in violations}),
        "caught": bool(caught),
        "off_target_touchdowns": _off_target_touchdowns(grabs, world.outcome.contacts, scenario.capture_radius_m),
        "off_target_grabs": sum(1 for g in grabs if g["error_m"] > scenario.capture_radius_m),
        "off_target_contacts": sum(1 for c in world.outcome.contacts if c["error_m"] > scenario.capture_radius_m),
        "mission_s": round(end_s - t0_s, 2),
        "fixes_rejected": dict(sorted(figures.get("fixes_rejected", {}).items())),
        "clutter": world.clutter_summary(),
    }


SAME_TOUCHDOWN_S = 2.0  # a grab and a contact with the water this close in time are one touchdown


def mission_params(sc: dict[str, Any], cfg: EvalConfig) -> dict[str, Any]:
    """What a scenario and a configuration change in the mission's parameters: the target filter and what it is
    told of the sea (the wave filter its sea state, the constant-velocity filter the Q tuned for it), where the
    object was reported and the forecast drift."""
    start_ne_m = (float(sc["object_start_ne_m"][0]), float(sc["object_start_ne_m"][1]))
    params: dict[str, Any] = {
        "target_filter": cfg.target_filter,
        "innovation_gate": cfg.innovation_gate,
        "fix_height_from_size": cfg.height_from_size,
        "sea_state": sc["sea_state"],
        "search_start_ne_m": start_ne_m,
    }
    if cfg.lean_yaw_min_tilt_deg is not None:
        params["lean_yaw_min_tilt_deg"] = cfg.lean_yaw_min_tilt_deg
    if cfg.wave_oscillators is not None:
        params["wave_oscillators"] = cfg.wave_oscillators
    if cfg.wave_drift_q_m2ps3 is not None:
        params["wave_drift_q_m2ps3"] = cfg.wave_drift_q_m2ps3
    if cfg.target_filter == "constant_velocity":
        params["cv_q_pos_m2ps"], params["cv_q_vel_m2ps3"] = CV_TUNED_Q[sc["sea_state"]]
    if "drift_forecast_ne_mps" in sc:  # results.jsonl lines written before the forecast existed have none
        drift = sc["drift_forecast_ne_mps"]
        params["search_drift_ne_mps"] = (float(drift[0]), float(drift[1]))
    return params


def _off_target_touchdowns(grabs: Sequence[dict[str, Any]], contacts: Sequence[dict[str, Any]], radius_m: float) -> int:
    """Touchdowns farther than ``radius_m`` from the object: the vehicle came down onto the water there (grab or
    not), or closed the gripper there just above the water."""

    def same(a: dict[str, Any], b: dict[str, Any]) -> bool:
        return abs(a["t_s"] - b["t_s"]) <= SAME_TOUCHDOWN_S

    on_target_grabs = [g for g in grabs if g["error_m"] <= radius_m]
    off_contacts = [  # down on the water off the object (settling onto it right at a grab on it is that grab)
        c for c in contacts if c["error_m"] > radius_m and not any(same(c, g) for g in on_target_grabs)
    ]
    above_water = [  # off-target grabs without coming down onto the water (just above it)
        g for g in grabs if g["error_m"] > radius_m and not any(same(g, c) for c in contacts)
    ]
    return len(off_contacts) + len(above_water)


def _gave_up(states: Sequence[dict[str, Any]], reason: str) -> str:
    """The first transition that turned back (to RETURN, ABORT or a failed end), else the run's reason."""
    for r in states:
        if r["to"] in ("RETURN", "ABORT", "FAILED", "RETURNED_EMPTY", "MANUAL"):
            return f"{r['from']}→{r['to']}: {r['reason']}"
    return reason


class _TruthTrace:
    """The object's and the vehicle's truth at ``TRACE_PERIOD_S``, for the run's report: a watcher of the world's
    camera frames (``PickupWorld.frame_observers``), so a run flies the same with ``--run-reports`` as without
    (a trace task of its own, merely sleeping 0.2 s at a time, turned a pickup into a failed run)."""

    def __init__(self, path: Path) -> None:
        self._f = path.open("w")
        self._f.write(json.dumps({"event": "start", "t_s": 0.0, "boot_monotonic_s": 0.0}) + "\n")
        self._next_s = -math.inf

    def __call__(self, t_s: float, truth: Any, obj: Any) -> None:
        if t_s < self._next_s - 1e-6:
            return
        self._next_s = t_s + TRACE_PERIOD_S
        self._f.write(
            json.dumps({"event": "object", "t_s": t_s, "pos_ned_m": [float(x) for x in obj.pos_ned_m]}) + "\n"
        )
        self._f.write(
            json.dumps({"event": "truth", "t_s": t_s, "pos_ned_m": [float(x) for x in truth.pos_ned_m]}) + "\n"
        )

    def close(self) -> None:
        self._f.close()


def _write_grabs(run_dir: Path, grabs: list[dict[str, Any]], contacts: list[dict[str, Any]]) -> None:
    with (run_dir / "sim_state.jsonl").open("a") as f:
        for g in grabs:
            f.write(json.dumps({"event": "grab", **g}) + "\n")
        for c in contacts:
            f.write(json.dumps({"event": "contact", **c}) + "\n")
