"""Entry actions: the only place a mission commands the vehicle. Named in the mission table.

Actions command through ``VehicleBoundary`` (``io.boundary``), which refuses anything that is not ours to
send (the pilot has control, an abort is under way) and sets the flight modes to expect. Each action says
which state ``control`` kinds may use it (checked when the table is loaded). The runner runs a state's
actions as one cancellable task: a takeover or an abort cancels them at their next await.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Protocol

from app.missions.circle import CircleMission
from app.missions.descend_target import DescendTarget, horizontal_distance_m
from app.missions.estimates import MissionModel
from app.missions.params import MissionParams
from app.missions.pickup import PickupEstimates
from app.missions.pickup_targets import (
    DriftingPoint,
    ObjectTarget,
    SearchPattern,
    SinkTarget,
    Transit,
    VerifyTarget,
    expanding_square,
)
from app.missions.water import CONTACT_POLL_S, WaterContact, off_the_water
from app.offboard.boundary import VehicleBoundary
from app.offboard.setpoint_loop import FixedPoint, SetpointLoop


class MissionIO(Protocol):
    boundary: VehicleBoundary
    setpoints: SetpointLoop
    params: MissionParams
    mission: MissionModel

    def now_s(self) -> float: ...


Action = Callable[[MissionIO], Awaitable[None]]


@dataclass(frozen=True, slots=True)
class ActionSpec:
    fn: Action
    control: tuple[str, ...] | None  # state control kinds allowed; None: any
    model: str | None = None  # the mission model it works on (``runner.MISSION_MODELS``), if any


async def arm(io: MissionIO) -> None:
    await io.boundary.arm()


async def takeoff(io: MissionIO) -> None:
    await io.boundary.takeoff(io.params.takeoff_altitude_m)


async def start_offboard(io: MissionIO) -> None:
    """Zero setpoint, OFFBOARD, then the setpoint loop holds position until a target is set."""
    await io.boundary.start_offboard()
    io.setpoints.engage(None)


async def start_circle(io: MissionIO) -> None:
    """Track the thesis's circle target, starting at the vehicle's current position."""
    pv = io.boundary.telemetry().pos_vel
    if pv is None:
        return  # the loop keeps holding; position_lost will abort
    if not isinstance(io.mission, CircleMission):
        raise TypeError(f"start_circle needs the circle mission, not {type(io.mission).__name__}")
    p = io.params
    circle = io.mission.start(pv.pos_ned_m, io.now_s(), p.circle_radius_m, p.circle_v_reduction_s, p.tracking_settle_s)
    io.setpoints.engage(circle)


async def hold_position(io: MissionIO) -> None:
    io.setpoints.engage(None)


async def hold(io: MissionIO) -> None:
    """The autopilot's HOLD (PX4 AUTO.LOITER, ArduCopter BRAKE); leaving offboard first sent zero velocity."""
    await io.boundary.hold()


async def land(io: MissionIO) -> None:
    await io.boundary.land()


async def stop_and_hold(io: MissionIO) -> None:
    """ABORT: zero velocity then HOLD if we own offboard, else HOLD if armed (shielded, bounded)."""
    io.setpoints.disengage()
    await io.boundary.abort_stop("abort")


# ---- pickup ------------------------------------------------------------------------------------------


def _pickup(io: MissionIO) -> PickupEstimates:
    if not isinstance(io.mission, PickupEstimates):
        raise TypeError(f"this action needs the pickup mission, not {type(io.mission).__name__}")
    return io.mission


async def calibrate_radar(io: MissionIO) -> None:
    """Thesis §4.2.2: climb until the sea is out of the radar's range, capture the background map there; if it
    fails (an echo: the sea still in range), try ``calibrate_climb_m`` higher, ``calibrate_attempts`` heights in
    all. Without a map the radar task keeps its adaptive clutter map: the mission goes on either way."""
    m, p = _pickup(io), io.params
    cal = m.radar_calibrator
    pv = io.boundary.telemetry().pos_vel
    if cal is None or pv is None:
        m.radar_calibration = "skipped: no radar task to calibrate" if cal is None else "skipped: no position"
        return
    n, e = pv.pos_ned_m[0], pv.pos_ned_m[1]
    home_down = (io.boundary.telemetry().home_ned_m or (0.0, 0.0, 0.0))[2]
    reasons = []
    for attempt in range(p.calibrate_attempts):
        height_m = max(p.takeoff_altitude_m, cal.max_range_m + p.calibrate_margin_m) + attempt * p.calibrate_climb_m
        io.setpoints.engage(FixedPoint("calibrate_radar", (n, e, home_down - height_m)))
        await _reach_height(io, height_m - p.altitude_tolerance_m)
        try:
            await cal.capture(p.calibrate_frames)
        except Exception as exc:  # the radar task says why (sea in range, too few frames, port gone)
            reasons.append(f"{height_m:g} m: {exc}")
            continue
        m.radar_calibration = f"ok at {height_m:g} m"
        return
    m.radar_calibration = "failed: " + "; ".join(reasons)


async def _reach_height(io: MissionIO, height_m: float) -> None:
    """Until the vehicle is ``height_m`` above home (telemetry polled; the state's timeout bounds the wait)."""
    while True:
        h = io.boundary.telemetry().height_above_home_m()
        if h is not None and h >= height_m:
            return
        await asyncio.sleep(0.1)


async def mark_search_datum(io: MissionIO) -> None:
    """The mission starts: the object was at ``search_start_ne_m`` now (the ground station's start may move it),
    drifting at ``search_drift_ne_mps`` from here on."""
    p = io.params
    _pickup(io).set_search_datum(p.search_start_ne_m, io.now_s(), p.search_drift_ne_mps)


async def goto_search(io: MissionIO) -> None:
    """Fly to the search centre, drifting with the water since the mission started, at the search height (above
    home), at the transit speed (``Transit``), slowing to the search speed for the search."""
    m, p = _pickup(io), io.params
    if m.datum_t_s is None:  # resumed past TAKEOFF without a datum: from now
        m.set_search_datum(p.search_start_ne_m, io.now_s(), p.search_drift_ne_mps)
    assert m.datum_t_s is not None
    pv, now_s = io.boundary.telemetry().pos_vel, io.now_s()
    target: Transit | DriftingPoint = (
        DriftingPoint("search_start", m.search_centre_ne_m, -p.search_altitude_m, m.datum_t_s, m.search_drift_ne_mps)
        if pv is None
        else Transit(
            "search_start",
            (pv.pos_ned_m[0], pv.pos_ned_m[1]),
            m.search_centre_at(now_s),
            -p.search_altitude_m,
            p.transit_speed_mps,
            p.transit_brake_mps2,
            now_s,
            drift_ne_mps=m.search_drift_ne_mps,
            end_speed_mps=p.search_speed_mps,
        )
    )
    io.setpoints.engage(target)


async def start_search(io: MissionIO) -> None:
    """An expanding square around the search centre (the last estimate after a loss, when there is one)."""
    m, p = _pickup(io), io.params
    m.restart_search_at_last_estimate()
    spacing_m = m.footprint_m(p.search_altitude_m) * (1.0 - p.search_overlap)
    # the pattern is laid around where the centre is now, and drifts on from here
    now_s = io.now_s()
    waypoints = expanding_square(m.search_centre_at(now_s), spacing_m, p.search_max_radius_m)
    m.search = SearchPattern(waypoints, -p.search_altitude_m, p.search_speed_mps, now_s, m.search_drift_ne_mps)
    search = m.search
    # entered from the water too (TRACK, taking off after an off-target touchdown, lost the object meanwhile and
    # its entry was cancelled): on ArduPilot a landed vehicle would sit there at ground idle
    await off_the_water(io, _pickup(io), lambda: io.setpoints.engage(search), p.verify_height_m)


async def start_approach(io: MissionIO) -> None:
    """Above the estimate at the search height above the sea (from the water first, as ``start_search``)."""
    target = ObjectTarget(_pickup(io), io.boundary.telemetry, io.params.search_altitude_m, _lean_yaw(io))
    await off_the_water(io, _pickup(io), lambda: io.setpoints.engage(target), io.params.verify_height_m)


async def start_track(io: MissionIO) -> None:
    target = ObjectTarget(_pickup(io), io.boundary.telemetry, io.params.track_height_m, _lean_yaw(io))
    await off_the_water(io, _pickup(io), lambda: io.setpoints.engage(target), io.params.verify_height_m)


async def start_descend(io: MissionIO) -> None:
    p, m = io.params, _pickup(io)
    h = m.height_above_sea_m(io.now_s()) or p.track_height_m
    target = DescendTarget(
        m,
        io.boundary.telemetry,
        h,
        p.descend_speed_mps,
        p.safety_height_m,
        p.fix_fresh_s,
        p.descend_converged_s,
        p.final_height_m,
        p.final_radius_m,
        p.final_abort_radius_m,
        p.crest_margin_m,
        p.descend_max_lead_m,
        p.final_max_speed_mps,
        math.inf if p.final_blind_gap_s is None else p.final_blind_gap_s,
        math.inf if p.final_max_lead_m is None else p.final_max_lead_m,
        p.crest_clearance_m,
        _lean_yaw(io),
        p.precise_max_drift_mps,
        p.touchdown_height_m,
        math.inf if p.final_start_max_rise_mps is None else p.final_start_max_rise_mps,
        math.inf if p.final_blind_pause_s is None else p.final_blind_pause_s,
        p.touchdown_height_m / p.grab_sink_speed_mps,
        math.inf if p.grab_blind_max_s is None else p.grab_blind_max_s,
    )
    io.setpoints.engage(target, allow_below_min=True)


def _lean_yaw(io: MissionIO) -> float | None:
    """The mean lean from which APPROACH, TRACK and DESCEND turn the image's wider side along it, rad."""
    deg = io.params.lean_yaw_min_tilt_deg
    return None if deg is None else math.radians(deg)


async def grab(io: MissionIO) -> None:
    """Come down onto the water over the object (it moves on the waves; without an estimate the loop holds where it
    is) and close the gripper (MAV_CMD_DO_GRIPPER) once on it (``water.WaterContact``), or after
    ``grab_contact_timeout_s`` regardless (a grab in the air misses: VERIFY sees the object and retries).

    Touchdown is judged at ``touchdown_height_m`` (0.3 m) over the water by the radar or over the *mean* sea (under
    the radar's first range it sees nothing): a gripper closed there closed in the air, 0.25 m over the water on
    the median catch at sea state 3, up to 0.5 m (README, *Evaluating*: where the gripper closed)."""
    m = _pickup(io)
    m.gripper_closed_t_s = None
    p, now_s = io.params, io.now_s()
    start_m = m.height_over_mean_sea_m(now_s)
    start_m = p.touchdown_height_m if start_m is None else start_m
    sink = SinkTarget(m, io.boundary.telemetry, start_m, p.grab_sink_speed_mps, -p.grab_press_m)
    io.setpoints.engage(sink, allow_below_min=True, keep_integral=True)  # the same object as DESCEND's
    contact = WaterContact(io, now_s)
    m.grab_gone_blind = m.grab_gone_off = False
    while True:  # (polled: the telemetry and the loop clock are what it waits on)
        if io.now_s() - now_s >= p.grab_contact_timeout_s or contact.on_it():
            break
        if _blind_too_long(m, io.now_s(), p.grab_blind_max_s):
            m.grab_gone_blind = True  # (``grab_gone_blind``: climb back, no grab)
            return
        if _off_the_estimate(io, m, p.grab_abort_offset_m):
            m.grab_gone_off = True  # (``grab_gone_off``: climb back, no grab)
            return
        await asyncio.sleep(CONTACT_POLL_S)
    pv = io.boundary.telemetry().pos_vel
    m.on_grab((pv.pos_ned_m[0], pv.pos_ned_m[1]) if pv is not None else m.last_estimate_ne_m or (math.nan, math.nan))
    await io.boundary.grip(True)
    m.gripper_closed_t_s = io.now_s()


def _off_the_estimate(io: MissionIO, m: PickupEstimates, limit_m: float | None) -> bool:
    """Sinking onto the water farther than ``limit_m`` (``grab_abort_offset_m``) from the estimate, horizontally: a
    gust or a late fix has put the vehicle off the object, and the sink — blind, with the gripper under it — does not
    win that back before the water (ArduCopter 0.10 m off as GRAB began, 0.22 m at the water 0.3 s later)."""
    if limit_m is None:
        return False
    pv, est = io.boundary.telemetry().pos_vel, m.estimate(io.now_s())
    return pv is not None and est is not None and horizontal_distance_m(pv.pos_ned_m, est.pos_ned_m) > limit_m


def _blind_too_long(m: PickupEstimates, t_s: float, limit_s: float | None) -> bool:
    """Sinking onto the water with the newest fix older than ``limit_s`` (``grab_blind_max_s``): the estimate has
    been extrapolated that long over orbiting water, and the water met late is met off the object."""
    if limit_s is None:
        return False
    age_s = m.fix_age_s(t_s)
    return age_s is None or age_s > limit_s


async def start_verify(io: MissionIO) -> None:
    """Climb ``verify_height_m`` from the water over the object's estimate (``VerifyTarget``): a caught object
    leaves the camera's sea, a missed one is seen drifting on. Notes when
    it is up there (``verify_up_t_s``): ``object_in_gripper`` wants ``verify_time_s`` of looking from that height."""
    pv = io.boundary.telemetry().pos_vel
    if pv is None:
        return
    m = _pickup(io)
    verify = VerifyTarget(m, io.boundary.telemetry, io.params.verify_height_m, (pv.pos_ned_m[0], pv.pos_ned_m[1]))
    await off_the_water(
        io, _pickup(io), lambda: io.setpoints.engage(verify, allow_below_min=True), io.params.verify_height_m
    )
    m.verify_up_t_s = None
    while True:  # up (by the radar, as the guards judge it) and over where a missed object would be: VERIFY looks
        t_s = io.now_s()
        h, drifted, pv = m.height_above_sea_m(t_s), m.drifted(t_s), io.boundary.telemetry().pos_vel
        up = h is not None and h >= io.params.verify_height_m - 0.5
        if up and h is not None and pv is not None and drifted is not None:
            # the drifted point well inside the view (a quarter footprint from its edge): the mean drift is only
            # an expectation, and ArduCopter's takeoff from the water leaves it metres behind
            (n, e), _ = drifted
            up = math.hypot(pv.pos_ned_m[0] - n, pv.pos_ned_m[1] - e) <= m.footprint_m(h) / 4.0
        if up:
            m.verify_up_t_s = t_s
            return
        await asyncio.sleep(0.05)


async def confirm_pickup(io: MissionIO) -> None:
    _pickup(io).picked_up = True


async def release(io: MissionIO) -> None:
    """Open the gripper (before another grab, or to drop what a failed grab may hold)."""
    await io.boundary.grip(False)


async def lift(io: MissionIO) -> None:
    pv = io.boundary.telemetry().pos_vel
    if pv is None:
        return
    lift = FixedPoint("lift", (pv.pos_ned_m[0], pv.pos_ned_m[1], -io.params.lift_altitude_m))
    await off_the_water(io, _pickup(io), lambda: io.setpoints.engage(lift), io.params.verify_height_m)


async def return_home(io: MissionIO) -> None:
    """Climb to the return altitude (above home) and fly home at the return speed (``Transit``), from where the
    vehicle is (without a position yet: to home at guidance's approach speed)."""
    home, p = io.boundary.telemetry().home_ned_m or (0.0, 0.0, 0.0), io.params
    pv = io.boundary.telemetry().pos_vel
    down_m = home[2] - p.return_altitude_m
    target: Transit | FixedPoint = (
        FixedPoint("home", (home[0], home[1], down_m))
        if pv is None
        else Transit(
            "home",
            (pv.pos_ned_m[0], pv.pos_ned_m[1]),
            (home[0], home[1]),
            down_m,
            p.transit_speed_mps,
            p.transit_brake_mps2,
            io.now_s(),
        )
    )
    await off_the_water(io, _pickup(io), lambda: io.setpoints.engage(target), io.params.verify_height_m)


ACTIONS: dict[str, ActionSpec] = {
    "arm": ActionSpec(arm, ("autopilot",)),
    "takeoff": ActionSpec(takeoff, ("autopilot",)),
    "start_offboard": ActionSpec(start_offboard, ("offboard",)),
    "start_circle": ActionSpec(start_circle, ("offboard",), "circle"),
    "hold_position": ActionSpec(hold_position, ("offboard",)),
    "land": ActionSpec(land, ("autopilot",)),
    "hold": ActionSpec(hold, ("autopilot",)),
    "stop_and_hold": ActionSpec(stop_and_hold, None),
    "calibrate_radar": ActionSpec(calibrate_radar, ("offboard",), "pickup"),
    "mark_search_datum": ActionSpec(mark_search_datum, None, "pickup"),
    "goto_search": ActionSpec(goto_search, ("offboard",), "pickup"),
    "start_search": ActionSpec(start_search, ("offboard",), "pickup"),
    "start_approach": ActionSpec(start_approach, ("offboard",), "pickup"),
    "start_track": ActionSpec(start_track, ("offboard",), "pickup"),
    "start_descend": ActionSpec(start_descend, ("offboard",), "pickup"),
    "grab": ActionSpec(grab, ("offboard",), "pickup"),
    "lift": ActionSpec(lift, ("offboard",), "pickup"),
    "start_verify": ActionSpec(start_verify, ("offboard",), "pickup"),
    "confirm_pickup": ActionSpec(confirm_pickup, None, "pickup"),
    "release": ActionSpec(release, ("offboard",), "pickup"),
    "return_home": ActionSpec(return_home, ("offboard",), "pickup"),
}
