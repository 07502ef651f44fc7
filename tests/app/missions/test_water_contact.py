"""GRAB's judgement that the vehicle is on the water (``app.missions.water.WaterContact``), on scripted down speeds
at the setpoint rate: the water meeting it, holding it up, and the vehicle merely passing through zero."""

from __future__ import annotations

from types import SimpleNamespace

from app.messages import LandedState, PositionVelocityNed, Stamped, TelemetrySnapshot
from app.missions.params import MissionParams
from app.missions.water import WaterContact

DT = 0.02


class Scripted:
    """What ``WaterContact`` reads of the mission's IO: the loop clock, the telemetry and the params."""

    def __init__(self) -> None:
        self.t_s = 10.0
        self.down_mps = 0.0
        self.landed = False
        self.params = MissionParams(grab_contact_speed_mps=0.05, grab_contact_drop_mps=0.4)
        self.boundary = SimpleNamespace(telemetry=self.telemetry)

    def now_s(self) -> float:
        return self.t_s

    def telemetry(self) -> TelemetrySnapshot:
        ls = Stamped(self.t_s, LandedState.ON_GROUND if self.landed else LandedState.IN_AIR)
        return TelemetrySnapshot(
            pos_vel=PositionVelocityNed(self.t_s, (0.0, 0.0, 0.0), (0.0, 0.0, self.down_mps)), landed_state=ls
        )


def first_contact_tick(io: Scripted, speeds: list[float]) -> int | None:
    """Poll along a script of down speeds (one per 0.02 s tick from the start); the tick it said on the water."""
    t0_s = io.t_s
    contact = WaterContact(io, t0_s)  # type: ignore[arg-type]
    for k, v in enumerate(speeds):
        io.t_s, io.down_mps = t0_s + k * DT, v
        if contact.on_it():
            return k
    return None


def test_sinking_at_the_grab_speed_and_stopped_by_the_water_is_on_it_at_once():
    io = Scripted()
    assert first_contact_tick(io, [0.8] * 20 + [0.1] * 10) == 20  # the first tick after the stop


def test_water_falling_away_under_it_still_counts_from_the_stop_not_from_standing_still():
    """Met at 0.8 m/s, it goes on after the falling water at 0.3 m/s: never as slow as 0.05, but it stopped."""
    io = Scripted()
    assert first_contact_tick(io, [0.8] * 10 + [0.3] * 20) == 10


def test_a_vehicle_that_came_in_climbing_is_not_on_the_water_as_it_passes_through_zero():
    """Back from an off-target touchdown and down again at once: −0.3 m/s rising to +0.8 through zero; then the
    water at 0.6 s."""
    io = Scripted()
    climbing_to_sinking = [-0.3 + 0.1 * k for k in range(12)]  # −0.3 … +0.8 over 0.22 s
    speeds = climbing_to_sinking + [0.8] * 18 + [0.0] * 5
    assert first_contact_tick(io, speeds) == 30


def test_held_up_from_the_start_it_is_on_the_water_after_the_held_time_or_when_the_autopilot_says_landed():
    io = Scripted()
    assert first_contact_tick(io, [0.0] * 40) in (25, 26)  # 0.5 s (the tick at it, or just after in floats)
    io = Scripted()
    io.landed = True
    assert first_contact_tick(io, [0.0] * 40) == 0


def test_slowing_gently_on_its_own_in_the_air_is_not_the_water():
    io = Scripted()
    assert first_contact_tick(io, [0.8 - 0.01 * k for k in range(40)]) is None  # 0.8 → 0.41 over 0.8 s
