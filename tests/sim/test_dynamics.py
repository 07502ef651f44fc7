"""Multirotor dynamics: PX4-like velocity loop response, tilt limit, wind rejection, ground, battery."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.dynamics import Dynamics, velocity_from_position
from sim.multirotor import ControlInput, MultirotorParams
from sim.wind import Wind, WindConfig

DT_S = 0.005


def hovering(wind: Wind | None = None, altitude_m: float = 10.0) -> Dynamics:
    """A vehicle settled in a hover at ``altitude_m`` (still air unless ``wind``)."""
    dyn = Dynamics(wind=wind, pos_ned_m=(0.0, 0.0, -altitude_m))
    for _ in range(int(1.0 / DT_S)):
        dyn.step(DT_S, ControlInput())
    return dyn


def run(dyn: Dynamics, seconds: float, control: ControlInput) -> None:
    for _ in range(round(seconds / DT_S)):
        dyn.step(DT_S, control)


def test_velocity_step_reaches_90_percent_within_1_5_s() -> None:
    dyn = hovering()
    t_s = 0.0
    while dyn.state.vel_ned_mps[0] < 0.9 * 2.0:
        dyn.step(DT_S, ControlInput((2.0, 0.0, 0.0)))
        t_s += DT_S
        assert t_s < 1.6, f"north velocity {dyn.state.vel_ned_mps[0]:.2f} m/s after {t_s:.2f} s"
    run(dyn, 5.0, ControlInput((2.0, 0.0, 0.0)))
    assert abs(dyn.state.vel_ned_mps[0] - 2.0) < 0.05  # the integrator removes the drag error
    assert dyn.state.pitch_rad < 0.0  # nose down to go north


def test_climb_and_descent_speeds_are_limited() -> None:
    dyn = hovering(altitude_m=30.0)
    run(dyn, 3.0, ControlInput((0.0, 0.0, -10.0)))
    assert math.isclose(dyn.state.vel_ned_mps[2], -3.0, abs_tol=0.05)  # MPC_Z_VEL_MAX_UP
    run(dyn, 6.0, ControlInput((0.0, 0.0, 10.0)))
    assert math.isclose(dyn.state.vel_ned_mps[2], 1.5, abs_tol=0.05)  # MPC_Z_VEL_MAX_DN


@settings(max_examples=15, deadline=None)
@given(
    steps=st.lists(st.tuples(st.floats(-15, 15), st.floats(-15, 15), st.floats(-4, 4)), min_size=1, max_size=4),
    seed=st.integers(0, 1000),
)
def test_tilt_never_exceeds_the_limit(steps: list[tuple[float, float, float]], seed: int) -> None:
    dyn = hovering(Wind(WindConfig(mean_mps=8.0, gust_sigma_mps=2.0), seed=seed), altitude_m=50.0)
    limit_rad = math.radians(MultirotorParams().tilt_max_deg)
    for vel_sp in steps:
        for _ in range(int(1.5 / DT_S)):
            dyn.step(DT_S, ControlInput(vel_sp))
            assert dyn.tilt_rad() <= limit_rad + 1e-6


def test_steady_wind_is_rejected_by_the_integrator() -> None:
    wind = Wind(WindConfig(mean_mps=5.0, from_deg=270.0, gust_sigma_mps=0.0, vertical_sigma_mps=0.0))
    dyn = hovering(wind)  # the wind starts at once: the vehicle is pushed east, then recovers
    run(dyn, 8.0, ControlInput())
    assert math.hypot(*dyn.state.vel_ned_mps[:2]) < 0.15
    run(dyn, 12.0, ControlInput())
    assert math.hypot(*dyn.state.vel_ned_mps[:2]) < 0.02
    # The integrator now supplies the drag force: c·v_wind towards the wind (west).
    expected = dyn.params.drag_per_s * 5.0
    assert math.isclose(-dyn.vel_int_ned_mps2[1], expected, rel_tol=0.05)
    assert dyn.state.roll_rad < 0.0  # leaning into the wind (left wing down, towards west)


def test_position_controller_is_p_with_cruise_clamp() -> None:
    params = MultirotorParams()
    assert velocity_from_position((1.0, 0.0, -10.0), (0.0, 0.0, -10.0), params) == (0.95, 0.0, 0.0)
    vn, ve, vd = velocity_from_position((100.0, 0.0, -20.0), (0.0, 0.0, -10.0), params)
    assert math.isclose(math.hypot(vn, ve), params.cruise_hor_mps)
    assert vd == -params.vel_up_max_mps


def test_deterministic_for_a_seed() -> None:
    def trajectory(seed: int) -> list[tuple[float, float, float]]:
        dyn = hovering(Wind(seed=seed))
        out = []
        for i in range(600):
            dyn.step(DT_S, ControlInput((1.0 if i > 100 else 0.0, 0.5, 0.0), yaw_sp_rad=1.0))
            out.append(dyn.state.pos_ned_m)
        return out

    assert trajectory(5) == trajectory(5)
    assert trajectory(5) != trajectory(6)


def test_ground_holds_a_vehicle_without_climb_thrust_and_wind_cannot_slide_it() -> None:
    dyn = Dynamics(wind=Wind(WindConfig(mean_mps=10.0)))
    run(dyn, 2.0, ControlInput(motors_on=False))
    assert dyn.state.on_ground and dyn.state.pos_ned_m == (0.0, 0.0, 0.0)
    run(dyn, 2.0, ControlInput((0.0, 0.0, 0.5)))  # pushing down into the ground
    assert dyn.state.on_ground and dyn.state.pos_ned_m[2] == 0.0
    run(dyn, 2.0, ControlInput((0.0, 0.0, -1.0)))
    assert not dyn.state.on_ground and dyn.state.pos_ned_m[2] < -1.0


def test_a_vehicle_resting_on_the_water_moves_with_it_and_leaves_it_climbing() -> None:
    """On the sea the ground moves (``ground_vel_ne_mps``: the surface's orbital velocity and the current, as they
    move the floating object): a vehicle pushing down onto it is carried along at that velocity, in the wind too,
    and a climb takes it off."""
    dyn = Dynamics(wind=Wind(WindConfig(mean_mps=10.0)))
    dyn.ground_vel_ne_mps = (0.3, -0.4)
    run(dyn, 2.0, ControlInput((0.0, 0.0, 0.5)))  # pushing down onto the water
    s = dyn.state
    assert s.on_ground and s.pos_ned_m[2] == 0.0 and s.vel_ned_mps == (0.3, -0.4, 0.0)
    assert s.pos_ned_m[:2] == pytest.approx((0.6, -0.8), abs=0.01)
    run(dyn, 2.0, ControlInput((0.0, 0.0, -1.0)))
    assert not dyn.state.on_ground and dyn.state.pos_ned_m[2] < -1.0


def test_free_fall_without_thrust_ends_on_the_ground() -> None:
    dyn = hovering(altitude_m=5.0)
    run(dyn, 3.0, ControlInput(motors_on=False))
    assert dyn.state.on_ground and dyn.state.vel_ned_mps == (0.0, 0.0, 0.0)


def test_battery_sags_and_drains_for_about_20_minutes_of_hover() -> None:
    dyn = hovering()
    v_start = dyn.battery.voltage_v
    run(dyn, 60.0, ControlInput())
    used = 1.0 - dyn.battery.remaining_frac
    assert 1.0 / used == pytest.approx(20.0, rel=0.1)  # minutes of hover endurance
    assert dyn.battery.voltage_v < v_start
    assert 14.0 < dyn.battery.voltage_v < 16.8  # a 4S pack under hover load
