"""Guards: pure predicates over an immutable context snapshot. Named in the mission table.

The context holds the telemetry snapshot, the link health and the mission's ``Estimates`` for this tick
(``app.missions.estimates``) — never a live object.

``LINK_GUARDS`` must appear in every flying state of a table (the validator refuses one without them): an
abort request, a lost link (no HEARTBEAT, or the attitude stream dead, for ``link_lost_s``), a lost position
stream and setpoints that keep failing to go out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from app.messages import LandedState, TelemetrySnapshot
from app.missions.estimates import Estimates
from app.missions.params import MissionParams
from app.offboard.boundary import LinkHealth


@dataclass(frozen=True, slots=True)
class GuardContext:
    t_s: float
    state: str
    time_in_state_s: float
    telemetry: TelemetrySnapshot
    health: LinkHealth
    params: MissionParams
    estimates: Estimates  # frozen for this tick by the mission (never a live object)
    abort_requested: bool
    start_given: bool = True  # the ground station said start (True when there is none)
    land_authorized: bool = True  # the operator authorised the landing (True when none is needed)
    geofence_radius_m: float = math.inf  # the envelope's fence around home (the vehicle cannot go past it)
    airborne_for_s: float | None = None  # since the mission's first flying state (None: not flown yet)


Guard = Callable[[GuardContext], bool]

GRAB_SETTLE_S = 1.0  # the gripper closes within this


def always(ctx: GuardContext) -> bool:
    return True


def start_given(ctx: GuardContext) -> bool:
    """The vehicle is ready and the mission may start (at once without a ground station)."""
    return ctx.start_given and vehicle_ready(ctx)


def vehicle_ready(ctx: GuardContext) -> bool:
    t = ctx.telemetry
    return t.pos_vel is not None and t.home_ned_m is not None and t.flight_mode is not None and t.armed is not None


def at_takeoff_altitude(ctx: GuardContext) -> bool:
    h = ctx.telemetry.height_above_home_m()
    return h is not None and h >= ctx.params.takeoff_altitude_m - ctx.params.altitude_tolerance_m


def circle_laps_done(ctx: GuardContext) -> bool:
    return ctx.estimates.progress.get("circle_laps", 0.0) >= ctx.params.circle_laps


def disarmed(ctx: GuardContext) -> bool:
    return ctx.telemetry.armed is not None and not ctx.telemetry.armed.value


def position_lost(ctx: GuardContext) -> bool:
    pv = ctx.telemetry.pos_vel
    return pv is None or ctx.t_s - pv.t_s > ctx.params.position_lost_abort_s


def abort_requested(ctx: GuardContext) -> bool:
    return ctx.abort_requested


def link_lost(ctx: GuardContext) -> bool:
    """No HEARTBEAT, or no attitude sample (a dead stream), for ``link_lost_s``."""
    h, limit = ctx.health, ctx.params.link_lost_s
    return any(age is None or age > limit for age in (h.heartbeat_age_s, h.attitude_age_s))


def setpoints_failing(ctx: GuardContext) -> bool:
    return ctx.health.send_failures >= ctx.params.setpoint_failures_abort


# ---- pickup ------------------------------------------------------------------------------------------


def _horizontal_m(ctx: GuardContext, n: float, e: float) -> float | None:
    pv = ctx.telemetry.pos_vel
    return None if pv is None else math.hypot(pv.pos_ned_m[0] - n, pv.pos_ned_m[1] - e)


def at_search_start(ctx: GuardContext) -> bool:
    pr, h = ctx.estimates.progress, ctx.telemetry.height_above_home_m()
    d = _horizontal_m(ctx, pr.get("search_centre_n_m", math.nan), pr.get("search_centre_e_m", math.nan))
    p = ctx.params
    return d is not None and d <= p.at_point_m and h is not None and abs(h - p.search_altitude_m) <= p.at_point_m


def search_done(ctx: GuardContext) -> bool:
    return ctx.estimates.progress.get("search_done", 0.0) >= 1.0


def _fresh(ctx: GuardContext) -> bool:
    e = ctx.estimates
    return e.target is not None and e.fix_age_s is not None and e.fix_age_s <= ctx.params.fix_fresh_s


def object_found(ctx: GuardContext) -> bool:
    """A confirmed lock with a fresh fix."""
    return _fresh(ctx)


def above_object(ctx: GuardContext) -> bool:
    t = ctx.estimates.target
    d = None if t is None else _horizontal_m(ctx, t.pos_ned_m[0], t.pos_ned_m[1])
    return _fresh(ctx) and d is not None and d <= ctx.params.approach_radius_m


def ready_to_descend(ctx: GuardContext) -> bool:
    """Fresh fix, converged for long enough, right above the object, off the water — and the landing authorised,
    when the mission asks for an operator's authorisation.

    Off the water: back in TRACK after an off-target touchdown (no grab there: climb back and try again), a vehicle
    still on the water went straight back to DESCEND, its touchdown fired at once and it grabbed there 0.1 s later
    — the off-target judgement was undone by a 0.1 s bounce. It must leave the water first. (A go-around up to the
    safety height before descending again was measured too: over 200 sea-state-3 runs it made more descents, 311
    contacts with the water against 255, and more of them off the object, 17 against 11.)"""
    e, p = ctx.estimates, ctx.params
    t = e.target
    d = None if t is None else _horizontal_m(ctx, t.pos_ned_m[0], t.pos_ned_m[1])
    converged = e.converged_for_s is not None and e.converged_for_s >= p.descend_converged_s
    over = d is not None and d <= p.track_radius_m
    return ctx.land_authorized and _fresh(ctx) and converged and over and not touchdown(ctx)


def target_lost(ctx: GuardContext) -> bool:
    e = ctx.estimates
    return e.target is None or e.fix_age_s is None or e.fix_age_s > ctx.params.target_lost_s


def target_lost_finally(ctx: GuardContext) -> bool:
    """Lost again after ``search_retries`` searches around the last estimate: give up (PX4's PLD_MAX_SRCH,
    ArduPilot's PLND_RET_MAX) rather than search until the battery's budget is spent."""
    return target_lost(ctx) and ctx.estimates.progress.get("searches_after_loss", 0.0) >= ctx.params.search_retries


def _landed(ctx: GuardContext) -> bool:
    """The autopilot says the vehicle is down (on the water)."""
    ls = ctx.telemetry.landed_state
    return ls is not None and ls.value is LandedState.ON_GROUND


def touchdown(ctx: GuardContext) -> bool:
    """On the water: the radar reads the touchdown height, or the vehicle is that low over the mean sea (under the
    radar's first range it reads nothing), or the autopilot says landed."""
    e, limit_m = ctx.estimates, ctx.params.touchdown_height_m
    landed = _landed(ctx)
    radar_low = e.height_above_sea_m is not None and e.height_above_sea_m <= limit_m
    # the mean sea only while the radar reads nothing (the sea inside its first range): when it does read the sea,
    # that is where the water is — over a trough the vehicle is still well above it at "0.3 m over the mean"
    mean_m = e.height_over_mean_sea_m
    mean_low = e.height_above_sea_m is None and mean_m is not None and mean_m <= limit_m
    return landed or radar_low or mean_low


def touchdown_off_target(ctx: GuardContext) -> bool:
    """At the water (``touchdown``) but farther than ``grab_max_offset_m`` from the estimate, without one, with
    a fix older than ``grab_fix_max_age_s``, after DESCEND gave its final part up (``final_descent_given_up``:
    it had drifted or gone blind off the object, or its fix had gone stale, and was climbing back), or — at the
    water only by the mean sea, the radar silent and the autopilot not landed — over water the radar last saw
    falling faster than ``grab_max_fall_mps`` (a deepening trough: GRAB's blind sink chased it for 0.6–0.9 s and
    met it 0.27–0.33 m off the object): no grab there — climb back and try again.
    The last half metre is flown blind (the camera's view there is smaller than the object's offset plus the tilt),
    but a fix much older than that descent means the object was lost higher up, and the estimate drifts off it by
    decimetres a second."""
    if not touchdown(ctx):
        return False
    e = ctx.estimates
    if e.progress.get("final_descent_given_up", 0.0) >= 1.0:  # a crest met on the way back up: not over it
        return True
    if e.fix_age_s is None or e.fix_age_s > ctx.params.grab_fix_max_age_s:
        return True
    max_fall = ctx.params.grab_max_fall_mps
    if max_fall is not None and e.height_above_sea_m is None and not _landed(ctx):
        if e.progress.get("water_falling_mps", -math.inf) > max_fall:
            return True
    t = e.target
    d = None if t is None else _horizontal_m(ctx, t.pos_ned_m[0], t.pos_ned_m[1])
    return d is None or d > ctx.params.grab_max_offset_m


FENCE_MARGIN_M = 2.0  # an object this close to the fence (or beyond) counts as beyond reach


def pickup_time_up(ctx: GuardContext) -> bool:
    """In the air for ``pickup_time_limit_s``: the battery's budget for finding and catching the object is spent
    (an object seen and lost again and again would otherwise keep the vehicle out until the battery failsafe)."""
    return ctx.airborne_for_s is not None and ctx.airborne_for_s > ctx.params.pickup_time_limit_s


def object_beyond_fence(ctx: GuardContext) -> bool:
    """The object's estimate — or, without one, the drifting search centre — lies beyond the geofence (less
    ``FENCE_MARGIN_M``): the vehicle cannot go there, so searching or following on is pointless."""
    home = ctx.telemetry.home_ned_m or (0.0, 0.0, 0.0)
    t = ctx.estimates.target
    if t is not None:
        n, e = t.pos_ned_m[0], t.pos_ned_m[1]
    else:
        p = ctx.estimates.progress
        if "search_centre_n_m" not in p:
            return False
        n, e = p["search_centre_n_m"], p["search_centre_e_m"]
    return math.hypot(n - home[0], e - home[1]) > ctx.geofence_radius_m - FENCE_MARGIN_M


def grab_settled(ctx: GuardContext) -> bool:
    """The gripper closed (on the water: ``actions.grab``) ``GRAB_SETTLE_S`` ago."""
    return ctx.estimates.progress.get("gripper_closed_for_s", -1.0) >= GRAB_SETTLE_S


def lock_renewed(ctx: GuardContext) -> bool:
    """The filter's lock began after this state was entered: the estimate escaped onto fixes it had refused (the
    object moved while unseen — or clutter: a same-ID print 3.6 m off the marker, in the middle of a descent), or a
    lost lock was confirmed anew. A descent goes on only over the object it began over: back to TRACK, which
    descends again once the new lock has converged for ``descend_converged_s`` right above it. GRAB's sink alike,
    until the gripper has closed (then VERIFY looks for what it holds; its older closings count for nothing here)."""
    progress = ctx.estimates.progress
    closed_for_s = progress.get("gripper_closed_for_s", -1.0)
    if 0.0 <= closed_for_s <= ctx.time_in_state_s:  # closed in this state: what is in the gripper is VERIFY's to see
        return False
    return progress.get("lock_age_s", math.inf) < ctx.time_in_state_s


def grab_gone_blind(ctx: GuardContext) -> bool:
    """GRAB gave up before the water: its newest fix grew older than ``grab_blind_max_s`` on the way down."""
    return ctx.estimates.progress.get("grab_gone_blind", 0.0) >= 1.0


def grab_gone_off(ctx: GuardContext) -> bool:
    """GRAB gave up before the water: the vehicle was farther than ``grab_abort_offset_m`` off the estimate."""
    return ctx.estimates.progress.get("grab_gone_off", 0.0) >= 1.0


def _seen_on_sea(ctx: GuardContext) -> bool:
    """Up at the verify height, the camera still fixes the object on the sea: the grab missed it."""
    h = ctx.estimates.height_above_sea_m
    up = h is not None and h >= ctx.params.verify_height_m - 0.5
    return up and ctx.time_in_state_s >= 0.5 and (_fresh(ctx) or _sighted_where_grabbed(ctx, ctx.params.fix_fresh_s))


def _sighted_where_grabbed(ctx: GuardContext, within_s: float) -> bool:
    """The object seen on the sea (the right size, whether or not the filter took it) near where the last grab
    was, within the last ``within_s``."""
    return ctx.estimates.progress.get("grab_sighting_age_s", math.inf) <= within_s


def grab_failed(ctx: GuardContext) -> bool:
    """Missed, with retries left."""
    return _seen_on_sea(ctx) and ctx.estimates.progress.get("grab_attempts", 0.0) <= ctx.params.grab_retries


def grab_failed_finally(ctx: GuardContext) -> bool:
    return _seen_on_sea(ctx) and ctx.estimates.progress.get("grab_attempts", 0.0) > ctx.params.grab_retries


def object_in_gripper(ctx: GuardContext) -> bool:
    """Up at the verify height for ``verify_time_s`` (looking: the camera's footprint there holds where the grab
    was) and no fix or sighting of the object on the sea since the climb began."""
    e, h = ctx.estimates, ctx.estimates.height_above_sea_m
    up = h is not None and h >= ctx.params.verify_height_m - 0.5
    looked = e.progress.get("verify_up_for_s", -1.0) >= ctx.params.verify_time_s
    no_fix_since_grab = e.fix_age_s is None or e.fix_age_s >= ctx.time_in_state_s
    unseen = no_fix_since_grab and not _sighted_where_grabbed(ctx, ctx.time_in_state_s)
    return up and looked and unseen


def disarmed_with_object(ctx: GuardContext) -> bool:
    return disarmed(ctx) and ctx.estimates.progress.get("picked_up", 0.0) >= 1.0


def at_lift_altitude(ctx: GuardContext) -> bool:
    h = ctx.telemetry.height_above_home_m()
    return h is not None and h >= ctx.params.lift_altitude_m - ctx.params.altitude_tolerance_m


def radar_calibration_done(ctx: GuardContext) -> bool:
    """CALIBRATE_RADAR is through: a background map, or given up (the adaptive clutter map carries on)."""
    return ctx.estimates.progress.get("radar_calibration_done", 0.0) >= 1.0


def above_home(ctx: GuardContext) -> bool:
    home = ctx.telemetry.home_ned_m
    d = None if home is None else _horizontal_m(ctx, home[0], home[1])
    return d is not None and d <= ctx.params.at_point_m


GUARDS: dict[str, Guard] = {
    g.__name__: g
    for g in (
        always,
        start_given,
        vehicle_ready,
        at_takeoff_altitude,
        circle_laps_done,
        disarmed,
        position_lost,
        abort_requested,
        link_lost,
        setpoints_failing,
        at_search_start,
        search_done,
        object_found,
        above_object,
        ready_to_descend,
        target_lost,
        target_lost_finally,
        touchdown,
        grab_settled,
        grab_gone_blind,
        grab_gone_off,
        lock_renewed,
        grab_failed,
        grab_failed_finally,
        object_in_gripper,
        disarmed_with_object,
        touchdown_off_target,
        object_beyond_fence,
        pickup_time_up,
        at_lift_altitude,
        above_home,
        radar_calibration_done,
    )
}
LINK_GUARDS = ("abort_requested", "link_lost", "position_lost", "setpoints_failing")
