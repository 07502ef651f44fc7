"""One mission on one connected vehicle: the boundary, the setpoint loop and the runner built from settings, the
mission's own model (the pickup's estimate chain), the sensor tasks feeding it, the ground station's link —
all in one TaskGroup, with a safe exit on the way out (``fly_mission``). The CLI (``app.main``), the tests and
the fault matrix (``sim.faults``) fly missions through here, on MAVSDK or on the in-process vehicle.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import math
import signal
from collections.abc import Callable, Coroutine, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from app.clock import Clock
from app.estimators.factory import make_target_filter
from app.estimators.sea_state import SEA_STATES, peak_wave_slope
from app.estimators.triangulation import SeaPlaneTriangulator
from app.eventlog import EventLog
from app.gcs.config import GcsSettings
from app.gcs.mission import MissionBridge
from app.messages import Autopilot
from app.missions.estimates import MissionModel
from app.missions.fix_checks import WATER_FALL_LIVE_PERIODS, FixChecks
from app.missions.pickup import PickupEstimates
from app.missions.pickup_feeds import PickupFeeds
from app.missions.runner import MissionRunner, RunResult, mission_model_for, model_name
from app.missions.table import MissionTable
from app.offboard.boundary import BoundaryParams, VehicleBoundary
from app.offboard.envelope import EnvelopeLimits
from app.offboard.guidance import ConstantBearingParams
from app.offboard.setpoint_loop import SetpointLoop
from app.offboard.vehicle import Vehicle
from app.settings import AutopilotCompensation, Settings


@dataclass
class Flight:
    result: RunResult
    duration_s: float
    autopilot: str
    setpoints_sent: int
    figures: dict[str, Any]  # the mission's own (circle: tracking error percentiles)
    timing: dict[str, Any]  # telemetry latency and setpoint spacing: what a busy computer did to the run
    safety: dict[str, Any]  # what the boundary refused, dropped or had to do (watchdog)


def compensation_for(settings: Settings, autopilot: Autopilot) -> AutopilotCompensation:
    """``guidance.ardupilot`` or ``guidance.px4``: what the loop adds for this autopilot, and its parameters."""
    return settings.guidance.ardupilot if autopilot is Autopilot.ARDUPILOT else settings.guidance.px4


async def set_autopilot_params(vehicle: Vehicle, settings: Settings, clock: Clock, events: EventLog) -> None:
    """Set the autopilot's parameters the settings ask for (``guidance.<autopilot>.autopilot_params``), each
    logged; one that is not taken raises ``VehicleError`` and the mission does not start."""
    for name, value in compensation_for(settings, vehicle.autopilot).autopilot_params.items():
        await vehicle.set_param(name, value)
        events.write(clock.now_s(), "run", event="param_set", name=name, value=value)


def build_flight(
    vehicle: Vehicle, table: MissionTable, settings: Settings, clock: Clock, events: EventLog
) -> tuple[VehicleBoundary, SetpointLoop, MissionRunner]:
    """The boundary, the setpoint loop and the runner for one mission on ``vehicle``."""
    g, e = settings.guidance, settings.envelope
    comp = compensation_for(settings, vehicle.autopilot)
    boundary = VehicleBoundary(
        vehicle,
        clock,
        events,
        BoundaryParams(
            limits=EnvelopeLimits(**e.model_dump()),
            setpoint_period_s=1.0 / g.setpoint_rate_hz,
            exit_zero_s=g.exit_zero_s,
            exit_timeout_s=g.exit_timeout_s,
            watchdog_timeout_s=g.watchdog_timeout_s,
            position_stale_s=settings.telemetry.position_stale_s,
        ),
    )
    setpoints = SetpointLoop(
        boundary,
        clock,
        events,
        ConstantBearingParams(
            g.approach_speed_max_mps if comp.approach_speed_max_mps is None else comp.approach_speed_max_mps,
            g.transient_distance_m if comp.transient_distance_m is None else comp.transient_distance_m,
            g.velocity_lead_s if comp.velocity_lead_s is None else comp.velocity_lead_s,
            comp.integral_gain_per_s2,
            g.integral_max_mps,
            g.integral_within_m,
            comp.inconsistency_tau_s,
            g.inconsistency_max_mps,
            comp.velocity_error_gain,
            g.velocity_error_max_mps,
            comp.precise_transient_distance_m,
            g.separate_vertical,
            comp.precise_velocity_lead_s,
            g.precise_velocity_error_max_mps,
            precise_damping_s=comp.precise_damping_s,
            climb_speed_max_mps=g.climb_speed_max_mps,
        ),
        g.setpoint_rate_hz,
        g.standby_rate_hz,
        settings.telemetry.position_stale_s,
    )
    runner = MissionRunner(
        table,
        boundary,
        setpoints,
        clock,
        events,
        settings.runner.tick_rate_hz,
        settings.runner.mode_confirm_timeout_s,
        mission=build_mission_model(table, settings),
    )
    return boundary, setpoints, runner


def build_mission_model(table: MissionTable, settings: Settings) -> MissionModel:
    """The mission's own model: the pickup's estimate chain is built from the camera settings and params."""
    if model_name(table) != "pickup":
        return mission_model_for(table)
    p = table.params
    sea = SEA_STATES[p.sea_state]
    checks = FixChecks(
        marker_size_m=p.marker_size_m,
        buoy_diameter_m=settings.detector.buoy_diameter_m,
        size_tolerance=p.size_tolerance,
        height_from_size=p.fix_height_from_size,
        height_uncertainty_m=sea.hs_m / 2.0,  # the sea under the radar vs under the object
        wave_slope=peak_wave_slope(sea.hs_m, sea.tp_s),
        confirm_frames=p.confirm_frames,
        confirm_fraction=p.confirm_fraction,
        converged_sigma_m=p.converged_sigma_m,
        water_fall_live_s=WATER_FALL_LIVE_PERIODS * sea.tp_s,
    )
    tri = SeaPlaneTriangulator.from_settings(
        settings.camera, attitude_std_rad=math.radians(settings.camera.attitude_noise_std_deg)
    )
    return PickupEstimates(tri, make_target_filter(p), checks, search_centre_ne_m=p.search_start_ne_m)


SEARCH_ALTITUDE_FLOOR_M = 3.0  # params.search_altitude_m's lower bound


def resolve_search_altitude(table: MissionTable, settings: Settings) -> MissionTable:
    """The pickup's search height from the detector's reach (``search_object_px``): as high as the object — the
    marker's edge, or the buoy's diameter (``detector.kind``) — still spans that many pixels on the camera, but no
    higher than ``search_altitude_m``. A printed marker is found from higher up than a small buoy, and a higher
    search sees a wider strip of sea: it outruns an object drifting away from the search's centre."""
    p = table.params
    if model_name(table) != "pickup" or p.search_object_px is None:
        return table
    size_m = settings.detector.buoy_diameter_m if settings.detector.kind == "buoy" else p.marker_size_m
    reach_m = min(settings.camera.fx_px, settings.camera.fy_px) * size_m / p.search_object_px
    altitude_m = max(SEARCH_ALTITUDE_FLOOR_M, min(p.search_altitude_m, reach_m))
    return table.model_copy(update={"params": p.model_copy(update={"search_altitude_m": altitude_m})})


async def fly_mission(
    vehicle: Vehicle,
    table: MissionTable,
    settings: Settings,
    clock: Clock,
    events: EventLog,
    on_start: Callable[[MissionRunner], None] | None = None,
    sensors: Sequence[Callable[[PickupFeeds], Coroutine[Any, Any, None]]] = (),
    ground: GcsSettings | None = None,
) -> Flight:
    """Run one mission on a connected vehicle; always ends with a safe exit.

    The first SIGINT/SIGTERM asks the mission to ABORT; a second one cancels the run, and the safe exit
    (zero velocity, then HOLD, if we still own offboard) runs on the way out — shielded, bounded.
    ``on_start(runner)`` is called once the runner exists (fault injection, the ground station).
    ``sensors`` produce into the pickup's queues (``PickupFeeds``): the camera and radar tasks, or the
    simulator's in-process sensors. With ``ground`` the ground station's link runs alongside (``app.gcs.mission``):
    the mission waits for its start, takes its commands and reports to it.
    """
    resolved = resolve_search_altitude(table, settings)
    if resolved is not table:
        p = resolved.params
        events.write(clock.now_s(), "run", event="search_altitude", altitude_m=round(p.search_altitude_m, 3),
                     object_px=p.search_object_px, detector=settings.detector.kind)  # fmt: skip
    table = resolved
    boundary, setpoints, runner = build_flight(vehicle, table, settings, clock, events)
    bridge = MissionBridge(ground, runner, clock, events) if ground is not None else None
    margin_s = float(getattr(clock, "work_margin_s", 0.0))
    feeds = PickupFeeds(
        model=runner.mission if isinstance(runner.mission, PickupEstimates) else None,
        make_room=functools.partial(setpoints.make_room, margin_s),
    )
    if on_start is not None:
        on_start(runner)
    loop = asyncio.get_running_loop()
    main_task = asyncio.current_task()
    signals_seen = 0

    def on_signal(signame: str) -> None:
        nonlocal signals_seen
        signals_seen += 1
        if signals_seen == 1:
            runner.request_abort(signame)
        elif main_task is not None:
            events.write(clock.now_s(), "run", event="second_signal", signal=signame)
            main_task.cancel()

    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, on_signal, sig.name)
    t_start_s = clock.now_s()
    try:
        async with asyncio.TaskGroup() as tg:
            streams = tg.create_task(vehicle.run(), name="vehicle.telemetry")
            loop_task = tg.create_task(setpoints.run(), name="offboard.setpoints")
            sensor_tasks: list[asyncio.Task[None]] = []
            if bridge is not None:
                sensor_tasks.append(tg.create_task(bridge.run(), name="gcs"))
            if isinstance(runner.mission, PickupEstimates):
                vehicle.add_sample_listener(runner.mission.on_vehicle_sample)
                sensor_tasks += [
                    tg.create_task(feeds.consume_frames(runner.mission), name="estimator.frames"),
                    tg.create_task(feeds.consume_heights(runner.mission), name="estimator.heights"),
                ]
                sensor_tasks += [tg.create_task(s(feeds), name=f"sensors.{i}") for i, s in enumerate(sensors)]
                sensor_tasks.append(tg.create_task(trace_pickup(runner, clock, events), name="pickup.trace"))
            try:
                await vehicle.wait_ready(settings.connection.ready_timeout_s)
                events.write(clock.now_s(), "run", event="vehicle_ready", autopilot=vehicle.autopilot.value)
                await set_autopilot_params(vehicle, settings, clock, events)
                result = await runner.run()
            finally:
                try:
                    await boundary.release("safe exit")
                    if bridge is not None:
                        await bridge.finish()  # the outcome and the last events to the ground station
                finally:
                    loop_task.cancel()
                    streams.cancel()
                    for t in sensor_tasks:
                        t.cancel()
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                loop.remove_signal_handler(sig)
    timing = vehicle.link_stats() | setpoints.interval_summary()
    safety = {
        "non_finite_samples": boundary.non_finite_samples,
        "setpoint_send_failures": boundary.send_failures_total,
        "watchdog_fired": boundary.watchdog.fired_count,
        "refused": dict(boundary.refused),
    }
    return Flight(
        result,
        clock.now_s() - t_start_s,
        vehicle.autopilot.value,
        setpoints.sent,
        runner.mission.summary()
        | (feeds.summary() if isinstance(runner.mission, PickupEstimates) else {})
        | ({"gcs": asdict(bridge.link.counters)} if bridge is not None else {}),
        timing,
        safety,
    )


TRACE_PERIOD_S = 0.2


def sigmas_and_correlation(cov_ne_m2: tuple[tuple[float, float], tuple[float, float]] | None) -> dict[str, Any]:
    """The estimate's horizontal covariance as the trace logs it: standard deviations keep their precision where the
    event log's 4 decimals would round a small variance away."""
    if cov_ne_m2 is None:
        return {"estimate_sigma_ne_m": None, "estimate_rho_ne": None}
    sigma_n_m, sigma_e_m = math.sqrt(max(cov_ne_m2[0][0], 0.0)), math.sqrt(max(cov_ne_m2[1][1], 0.0))
    rho = cov_ne_m2[0][1] / (sigma_n_m * sigma_e_m) if sigma_n_m * sigma_e_m > 0.0 else 0.0
    return {"estimate_sigma_ne_m": [sigma_n_m, sigma_e_m], "estimate_rho_ne": rho}


async def trace_pickup(runner: MissionRunner, clock: Clock, events: EventLog) -> None:
    """5 Hz ``pickup`` records for the report and ``run.mcap``: the vehicle (position, attitude), the estimate
    (position; horizontal standard deviations and their correlation), the height above the sea, the fix's age."""
    model = runner.mission
    assert isinstance(model, PickupEstimates)
    while True:
        await clock.sleep(TRACE_PERIOD_S)
        t_s = clock.now_s()
        pv = runner.boundary.telemetry().pos_vel
        if pv is None:
            continue
        while model.fix_log:
            t_fix_s, n_m, e_m, result = model.fix_log.popleft()
            events.write(t_fix_s, "fix", ne_m=[round(n_m, 3), round(e_m, 3)], result=result)
        snap = model.snapshot(t_s)
        target, cov, att = snap.target, snap.target_cov_ne_m2, runner.boundary.telemetry().attitude
        events.write(
            t_s,
            "pickup",
            state=runner.state,
            vehicle_ne_m=[round(pv.pos_ned_m[0], 3), round(pv.pos_ned_m[1], 3)],
            vehicle_down_m=round(pv.pos_ned_m[2], 3),
            vehicle_rpy_rad=None if att is None else [round(a, 4) for a in (att.roll_rad, att.pitch_rad, att.yaw_rad)],
            estimate_ne_m=None if target is None else [round(target.pos_ned_m[0], 3), round(target.pos_ned_m[1], 3)],
            estimate_down_m=None if target is None else round(target.pos_ned_m[2], 3),
            **sigmas_and_correlation(cov),
            height_above_sea_m=None if snap.height_above_sea_m is None else round(snap.height_above_sea_m, 3),
            fix_age_s=None if snap.fix_age_s is None else round(snap.fix_age_s, 3),
        )
