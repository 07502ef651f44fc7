"""Flight stack: PX4 arming, takeoff, offboard entry and loss failsafe, landing, RTL; ArduCopter profile."""

from __future__ import annotations

import math

import pytest

from app.messages import FlightMode, LandedState
from sim import airframes
from sim.autopilot_modes import MavResult, Mode, Profile
from sim.autopilot_params import ParamStore, ParamType
from sim.dynamics import Dynamics
from sim.flight_stack import FlightStack
from sim.stack_types import PositionTarget, StackEvent
from sim.wind import Wind, WindConfig

TICK_S = 0.05  # how often the "outside" talks to the stack (MAVSDK's setpoint period)


class Harness:
    """A flight stack driven like the endpoint drives it, with a clock we own."""

    def __init__(
        self, profile: Profile = Profile.PX4, wind: WindConfig | None = None, fixed_grid: bool = False, **params: float
    ) -> None:
        self.events: list[StackEvent] = []
        dyn = Dynamics(wind=Wind(wind or WindConfig.off(), seed=1))
        self.fs = FlightStack(dyn, profile, params=params or None, on_event=self.events.append, fixed_grid=fixed_grid)
        self.t_s = 0.0
        self.fs.step(0.0)

    def advance(self, seconds: float, setpoint: PositionTarget | None = None) -> None:
        end_s = self.t_s + seconds
        while self.t_s < end_s - 1e-9:
            self.t_s = min(end_s, self.t_s + TICK_S)
            if setpoint is not None:
                self.fs.position_target(self.t_s, setpoint)
            self.fs.step(self.t_s)

    def until(self, predicate, timeout_s: float, setpoint: PositionTarget | None = None) -> float:
        """Advance until ``predicate()``; returns the time it took."""
        start_s = self.t_s
        while not predicate():
            assert self.t_s - start_s < timeout_s, "condition not reached"
            self.advance(TICK_S, setpoint)
        return self.t_s - start_s

    def mode_changes(self) -> list[tuple[FlightMode, str]]:
        return [(e.mode.flight_mode, e.reason) for e in self.events if e.kind == "mode" and e.mode]

    def flying(self, altitude_m: float | None = None) -> Harness:
        self.advance(1.5)
        assert self.fs.arm(self.t_s) is MavResult.ACCEPTED
        assert self.fs.takeoff(self.t_s, altitude_m) is MavResult.ACCEPTED
        self.until(lambda: self.fs.flight_mode is FlightMode.HOLD, 15.0)
        return self

    @property
    def height_m(self) -> float:
        return -self.fs.dyn.state.pos_ned_m[2]


def test_arm_is_refused_until_pre_arm_checks_pass() -> None:
    h = Harness()
    assert h.fs.arm(h.t_s) is MavResult.DENIED  # no GPS fix yet
    assert any("Arming denied" in e.text for e in h.events)
    h.advance(1.5)
    h.fs.inject_prearm_failure("compass inconsistent")
    assert h.fs.arm(h.t_s) is MavResult.DENIED
    assert not h.fs.prearm_ok
    h.fs.inject_prearm_failure(None)
    assert h.fs.arm(h.t_s) is MavResult.ACCEPTED and h.fs.armed


def test_disarm_is_refused_in_the_air_unless_forced() -> None:
    h = Harness().flying()
    assert h.fs.disarm(h.t_s) is MavResult.DENIED and h.fs.armed
    assert h.fs.disarm(h.t_s, force=True) is MavResult.ACCEPTED and not h.fs.armed
    h.until(lambda: h.fs.landed_state is LandedState.ON_GROUND, 5.0)  # it falls


def test_takeoff_is_refused_when_disarmed() -> None:
    h = Harness()
    h.advance(1.5)
    assert h.fs.takeoff(h.t_s) is MavResult.DENIED


@pytest.mark.parametrize("altitude_m", [None, math.nan, 0.0])
def test_takeoff_climbs_to_mis_takeoff_alt_then_holds(altitude_m: float | None) -> None:
    h = Harness(MIS_TAKEOFF_ALT=4.0)
    h.advance(1.5)
    h.fs.arm(h.t_s)
    assert h.fs.takeoff(h.t_s, altitude_m) is MavResult.ACCEPTED
    assert h.fs.flight_mode is FlightMode.TAKEOFF
    h.advance(0.4)
    assert h.fs.landed_state is LandedState.ON_GROUND  # motors spooling up
    h.advance(0.6)
    assert h.fs.landed_state is LandedState.TAKING_OFF
    assert h.fs.dyn.state.vel_ned_mps[2] == pytest.approx(-1.5, abs=0.3)  # MPC_TKO_SPEED
    took_s = h.until(lambda: h.fs.flight_mode is FlightMode.HOLD, 10.0)
    assert took_s < 4.0
    assert h.mode_changes()[-1] == (FlightMode.HOLD, "takeoff_done")
    assert h.fs.landed_state is LandedState.IN_AIR
    h.advance(3.0)
    assert h.height_m == pytest.approx(4.0, abs=0.15)


def test_offboard_is_refused_without_a_setpoint_stream_and_accepted_with_one() -> None:
    h = Harness().flying()
    assert h.fs.set_mode(h.t_s, Mode.OFFBOARD) is MavResult.DENIED
    sp = PositionTarget.velocity((2.0, 0.0, 0.0), 0.0)
    h.advance(0.2, sp)
    assert h.fs.set_mode(h.t_s, Mode.OFFBOARD) is MavResult.ACCEPTED
    north0_m = h.fs.dyn.state.pos_ned_m[0]
    h.advance(3.0, sp)
    assert h.fs.flight_mode is FlightMode.OFFBOARD
    assert h.fs.dyn.state.pos_ned_m[0] - north0_m > 4.0
    assert h.fs.dyn.state.vel_ned_mps[0] == pytest.approx(2.0, abs=0.15)


def test_stale_setpoints_do_not_make_offboard_available() -> None:
    h = Harness().flying()
    h.advance(0.1, PositionTarget.velocity((0.0, 0.0, 0.0), 0.0))
    h.advance(0.6)
    assert h.fs.set_mode(h.t_s, Mode.OFFBOARD) is MavResult.DENIED


def test_offboard_loss_switches_to_hold_after_com_of_loss_t() -> None:
    h = Harness().flying()
    sp = PositionTarget.velocity((1.0, 0.0, 0.0), 0.0)
    h.advance(0.2, sp)
    h.fs.set_mode(h.t_s, Mode.OFFBOARD)
    h.advance(2.0, sp)
    last_setpoint_s = h.t_s
    took_s = h.until(lambda: h.fs.flight_mode is not FlightMode.OFFBOARD, 3.0)
    loss = next(e for e in h.events if e.kind == "mode" and e.reason == "offboard_loss")
    assert loss.t_s - last_setpoint_s == pytest.approx(1.0, abs=0.01)
    assert took_s <= 1.0 + TICK_S
    assert h.fs.flight_mode is FlightMode.HOLD
    assert any("offboard lost" in e.text for e in h.events)
    h.advance(5.0)  # it brakes and holds where it stopped
    assert math.hypot(*h.fs.dyn.state.vel_ned_mps[:2]) < 0.1


def test_offboard_position_setpoints_follow_type_mask() -> None:
    h = Harness().flying()
    # position only (ignore velocity, acceleration, yaw rate), yaw 90°
    sp = PositionTarget(type_mask=0b1001_1111_1000, pos_ned_m=(3.0, -2.0, -5.0), yaw_rad=math.pi / 2)
    h.advance(0.1, sp)
    assert h.fs.set_mode(h.t_s, Mode.OFFBOARD) is MavResult.ACCEPTED
    h.advance(12.0, sp)
    assert h.fs.dyn.state.pos_ned_m == pytest.approx((3.0, -2.0, -5.0), abs=0.1)
    assert h.fs.dyn.state.yaw_rad == pytest.approx(math.pi / 2, abs=0.02)


def test_land_touches_down_reports_landed_and_auto_disarms_after_com_disarm_land() -> None:
    h = Harness().flying()
    assert h.fs.land(h.t_s) is MavResult.ACCEPTED
    h.advance(0.5)
    assert h.fs.landed_state is LandedState.LANDING
    assert h.fs.dyn.state.vel_ned_mps[2] == pytest.approx(0.7, abs=0.1)  # MPC_LAND_SPEED
    h.until(lambda: h.fs.landed_state is LandedState.ON_GROUND, 10.0)
    landed_s = h.t_s
    h.until(lambda: not h.fs.armed, 5.0)
    assert h.t_s - landed_s == pytest.approx(2.0, abs=TICK_S + 0.01)  # COM_DISARM_LAND
    assert h.mode_changes()[-1] == (FlightMode.HOLD, "landed")


def test_auto_disarm_10_s_after_arming_without_takeoff() -> None:
    h = Harness()
    h.advance(1.5)
    h.fs.arm(h.t_s)
    armed_s = h.t_s
    h.until(lambda: not h.fs.armed, 15.0)
    assert h.t_s - armed_s == pytest.approx(10.0, abs=TICK_S + 0.01)  # COM_DISARM_PRFLT


def test_rtl_climbs_to_return_altitude_flies_home_and_lands() -> None:
    h = Harness().flying()
    sp = PositionTarget.velocity((4.0, 3.0, 0.0), 0.0)
    h.advance(0.1, sp)
    h.fs.set_mode(h.t_s, Mode.OFFBOARD)
    h.advance(4.0, sp)
    assert h.fs.return_to_launch(h.t_s) is MavResult.ACCEPTED
    max_height_m = 0.0
    while h.fs.armed:
        h.advance(0.5)
        max_height_m = max(max_height_m, h.height_m)
        assert h.t_s < 60.0
    assert max_height_m == pytest.approx(10.0, abs=0.5)  # RTL_RETURN_ALT
    assert math.hypot(*h.fs.dyn.state.pos_ned_m[:2]) < 0.5
    assert h.fs.landed_state is LandedState.ON_GROUND


def test_pilot_modes_hold_position_in_wind() -> None:
    h = Harness(wind=WindConfig(mean_mps=6.0, gust_sigma_mps=1.0)).flying()
    assert h.fs.set_mode(h.t_s, Mode.POSCTL, "pilot") is MavResult.ACCEPTED
    start = h.fs.dyn.state.pos_ned_m
    h.advance(20.0)
    end = h.fs.dyn.state.pos_ned_m
    assert math.dist(start, end) < 1.0
    assert h.mode_changes()[-1] == (FlightMode.POSCTL, "pilot")


def test_px4_params_use_bytewise_int_encoding_and_ardupilot_a_cast() -> None:
    px4 = ParamStore(Profile.PX4)
    p = px4.param("SYS_AUTOSTART")
    assert p is not None and p.type is ParamType.INT32
    wire = px4.encode(p)
    assert wire != 10015.0 and px4.decode(wire, ParamType.INT32) == 10015.0
    ap = ParamStore(Profile.ARDUPILOT)
    q = ap.param("RTL_ALT")
    assert q is not None and ap.encode(q) == 1500.0


@pytest.mark.parametrize(
    ("jerk", "accel", "shaping", "defaults", "ranges_ends"),
    [
        # PSC_JERK_XY 5 m/s³, WPNAV_ACCEL 250 cm/s²; documented ranges 1-20 m/s³, 50-500 cm/s²
        ("PSC_JERK_XY", "WPNAV_ACCEL", "shaping_xy", (5.0, 2.5), (1.0, 5.0)),
        # PSC_JERK_Z 5 m/s³, WPNAV_ACCEL_Z 100 cm/s²; documented ranges 5-50 m/s³, 50-500 cm/s²
        ("PSC_JERK_Z", "WPNAV_ACCEL_Z", "shaping_z", (5.0, 1.0), (5.0, 5.0)),
    ],
)
def test_ardupilot_shaping_limits_follow_their_params_within_the_documented_ranges(
    jerk: str, accel: str, shaping: str, defaults: tuple[float, float], ranges_ends: tuple[float, float]
) -> None:
    fs = FlightStack(Dynamics(airframes.ARDUCOPTER, Wind(WindConfig.off(), seed=1)), Profile.ARDUPILOT)
    other = "shaping_z" if shaping == "shaping_xy" else "shaping_xy"
    fs.step(0.0)
    fs.step(0.1)
    untouched = getattr(fs.dyn, other)
    assert getattr(fs.dyn, shaping) == defaults
    assert fs.params.set(jerk, 12.0) and fs.params.set(accel, 400.0)
    fs.step(0.2)
    assert getattr(fs.dyn, shaping) == (12.0, 4.0) and getattr(fs.dyn, other) == untouched
    assert fs.params.set(jerk, 0.0) and fs.params.set(accel, 9000.0)
    fs.step(0.3)
    assert getattr(fs.dyn, shaping) == ranges_ends
    px4 = Harness(Profile.PX4).fs
    assert px4.tuning.shaping() is None and getattr(px4.dyn, shaping) is None


# -- ArduCopter profile ---------------------------------------------------------------------------


def test_ardupilot_takeoff_only_in_guided_with_an_altitude() -> None:
    h = Harness(Profile.ARDUPILOT)
    assert h.fs.flight_mode is FlightMode.STABILIZED  # ArduCopter boots in STABILIZE
    h.advance(1.5)
    assert h.fs.arm(h.t_s) is MavResult.ACCEPTED
    assert h.fs.takeoff(h.t_s, 5.0) is MavResult.DENIED  # not GUIDED
    assert h.fs.set_mode(h.t_s, Mode.AP_GUIDED) is MavResult.ACCEPTED
    assert h.fs.takeoff(h.t_s, math.nan) is MavResult.DENIED
    assert h.fs.takeoff(h.t_s, 5.0) is MavResult.ACCEPTED
    h.advance(1.0)
    assert h.fs.landed_state is LandedState.TAKING_OFF
    h.until(lambda: h.height_m > 4.8, 10.0)
    h.advance(2.0)
    assert h.fs.flight_mode is FlightMode.OFFBOARD  # GUIDED reads as OFFBOARD, also after takeoff
    assert h.fs.landed_state is LandedState.IN_AIR


def ardupilot_guided_at_5_m() -> Harness:
    """An ArduCopter that armed, switched to GUIDED and took off to 5 m."""
    h = Harness(Profile.ARDUPILOT)
    h.advance(1.5)
    h.fs.arm(h.t_s)
    h.fs.set_mode(h.t_s, Mode.AP_GUIDED)
    h.fs.takeoff(h.t_s, 5.0)
    h.until(lambda: h.height_m > 4.8, 10.0)
    return h


def test_ardupilot_guided_takes_setpoints_without_a_stream_and_stops_after_3_s() -> None:
    h = ardupilot_guided_at_5_m()
    h.fs.position_target(h.t_s, PositionTarget.velocity((2.0, 0.0, 0.0), 0.0))  # one setpoint only
    h.advance(2.5)
    assert h.fs.dyn.state.vel_ned_mps[0] > 1.5  # still flying the last velocity
    h.advance(4.0)
    assert abs(h.fs.dyn.state.vel_ned_mps[0]) < 0.3  # GUID_TIMEOUT: stopped and holding
    assert h.fs.flight_mode is FlightMode.OFFBOARD  # no mode change


def test_ardupilot_brake_stops_and_holds_and_reads_as_hold() -> None:
    h = ardupilot_guided_at_5_m()
    h.advance(2.0, PositionTarget.velocity((3.0, 0.0, 0.0), 0.0))
    assert h.fs.set_mode(h.t_s, Mode.AP_BRAKE) is MavResult.ACCEPTED
    assert h.fs.flight_mode is FlightMode.HOLD
    h.advance(2.0)
    stopped = h.fs.dyn.state.pos_ned_m
    h.advance(5.0)
    assert math.dist(stopped, h.fs.dyn.state.pos_ned_m) < 0.3


def test_ardupilot_land_disarms_at_touchdown_and_stays_in_land() -> None:
    h = Harness(Profile.ARDUPILOT)
    h.advance(1.5)
    h.fs.arm(h.t_s)
    h.fs.set_mode(h.t_s, Mode.AP_GUIDED)
    h.fs.takeoff(h.t_s, 3.0)
    h.until(lambda: h.height_m > 2.8, 10.0)
    assert h.fs.land(h.t_s) is MavResult.ACCEPTED
    h.until(lambda: not h.fs.armed, 15.0)
    assert h.fs.flight_mode is FlightMode.LAND
    assert h.fs.arm(h.t_s) is MavResult.DENIED  # LAND is not armable on ArduCopter


def test_ardupilot_takeoff_is_cancelled_by_a_setpoint_while_still_on_the_ground() -> None:
    h = Harness(Profile.ARDUPILOT)
    h.advance(1.5)
    h.fs.arm(h.t_s)
    h.fs.set_mode(h.t_s, Mode.AP_GUIDED)
    h.fs.position_target(h.t_s, PositionTarget.velocity((0.0, 0.0, 0.0), 0.0))
    assert h.fs.takeoff(h.t_s, 5.0) is MavResult.ACCEPTED
    h.advance(3.0, PositionTarget.velocity((0.0, 0.0, 0.0), 0.0))  # a stream already running (§5)
    assert h.height_m < 0.1 and h.fs.landed_state is LandedState.ON_GROUND


def _watched_and_plain_diverge(fixed_grid: bool) -> float | None:
    """Two stacks in the same gusts on the same setpoints every 50 ms; the second also looked at 7 and 31 ms after
    each: the first time their truths differ, or None over 10 s."""
    gusty = WindConfig(mean_mps=6.0, from_deg=200.0, gust_sigma_mps=1.5)
    plain, watched = (Harness(wind=gusty, fixed_grid=fixed_grid).flying() for _ in range(2))
    setpoint = PositionTarget.velocity((1.5, -0.7, 0.2), 0.3)
    for h in (plain, watched):
        h.fs.position_target(h.t_s, setpoint)
        assert h.fs.set_mode(h.t_s, Mode.OFFBOARD, "test") is MavResult.ACCEPTED
    for k in range(1, 201):
        t_s = plain.t_s + k * TICK_S
        for look_s in (t_s - 0.043, t_s - 0.019):
            watched.fs.step(look_s)
            watched.fs.truth()
        for h in (plain, watched):
            h.fs.position_target(t_s, setpoint)
            h.fs.step(t_s)
        if watched.fs.truth() != plain.fs.truth():
            return t_s
    assert plain.fs.dyn.state.vel_ned_mps[0] == pytest.approx(1.5, abs=0.5)  # it flew the setpoint
    assert t_s - 0.005 < plain.fs.t_s <= t_s + 1e-6  # the last tick at or before now
    return None


def test_on_the_fixed_grid_who_looks_at_the_vehicle_and_when_changes_nothing_of_its_flight() -> None:
    """Physics ticks on a fixed grid (the in-process vehicle): a stack also stepped at odd times in between (a
    truth trace for a report, a camera at its own rate) flies bit for bit as the one stepped only when setpoints
    come, gusts included. Stepping to every query's time (the MAVLink endpoint's way, kept there) cuts the
    ticks at the query times, and the flight changes with its observers: an evaluation run with ``--run-reports``
    was not the run without."""
    assert _watched_and_plain_diverge(fixed_grid=True) is None
    assert _watched_and_plain_diverge(fixed_grid=False) is not None


def test_between_two_ticks_the_truth_and_the_telemetry_are_the_last_tick_carried_on_to_now() -> None:
    """Looked at 3 ms after a tick, the vehicle flying at ~2 m/s is where it will be then (not where the tick left
    it): camera frames and telemetry are stamped with their own time, and a state up to 5 ms older than its stamp
    would put what the camera saw and the state history the app looks it up in out of step."""
    h, forward = Harness(fixed_grid=True).flying(), PositionTarget.velocity((2.0, 0.0, 0.0), 0.0)
    h.fs.position_target(h.t_s, forward)
    assert h.fs.set_mode(h.t_s, Mode.OFFBOARD, "test") is MavResult.ACCEPTED
    h.advance(4.0, forward)
    tick = h.fs.truth()
    tick_est = h.fs.estimate()
    assert tick.t_s == pytest.approx(h.t_s) and tick.vel_ned_mps[0] == pytest.approx(2.0, abs=0.1)
    h.fs.step(h.t_s + 0.003)  # no tick falls in these 3 ms
    later, later_est = h.fs.truth(), h.fs.estimate()
    assert later.t_s == pytest.approx(h.t_s + 0.003)
    assert later.pos_ned_m[0] - tick.pos_ned_m[0] == pytest.approx(0.003 * tick.vel_ned_mps[0], rel=0.05)
    assert later_est.pos_ned_m[0] - tick_est.pos_ned_m[0] == pytest.approx(0.003 * tick_est.vel_ned_mps[0], rel=0.05)
    h.fs.step(h.t_s + 0.005)  # the next tick: its state, not the extrapolation, from here on
    assert h.fs.truth().pos_ned_m[0] == pytest.approx(later.pos_ned_m[0] + 0.002 * later.vel_ned_mps[0], abs=1e-3)
