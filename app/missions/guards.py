"""Guards: pure predicates over an immutable context snapshot. Named in the mission table.

The context holds the telemetry snapshot, the link health and the mission's ``Estimates`` for this tick
(``app.missions.estimates``) — never a live object.

``LINK_GUARDS`` must appear in every flying state of a table (the validator refuses one without them): an
abort request, a lost link (no HEARTBEAT, or the attitude stream dead, for ``link_lost_s``), a lost position
stream and setpoints that keep failing to go out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from app.messages import TelemetrySnapshot
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


Guard = Callable[[GuardContext], bool]


def always(ctx: GuardContext) -> bool:
    return True


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


GUARDS: dict[str, Guard] = {
    g.__name__: g
    for g in (
        always,
        vehicle_ready,
        at_takeoff_altitude,
        circle_laps_done,
        disarmed,
        position_lost,
        abort_requested,
        link_lost,
        setpoints_failing,
    )
}
LINK_GUARDS = ("abort_requested", "link_lost", "position_lost", "setpoints_failing")
