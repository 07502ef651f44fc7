"""The return's target (``Transit``): a point that flies the line home at the cruise speed, never far ahead of the
vehicle, and brakes to a stop at the end."""

from __future__ import annotations

import itertools
import math

from app.messages import PositionVelocityNed
from app.missions.pickup_targets import Transit

DT_S = 0.02


def fly(transit: Transit, vehicle_ne_m, seconds: float):
    """The target every tick while the vehicle sits at ``vehicle_ne_m(t)``: (t, n, e, speed, accel, down)."""
    for k in range(int(seconds / DT_S) + 1):
        t_s = k * DT_S
        n, e = vehicle_ne_m(t_s)
        transit.observe(PositionVelocityNed(t_s, (n, e, -10.0), (0.0, 0.0, 0.0)))
        ts = transit.target_at(t_s)
        speed = math.hypot(ts.vel_ned_mps[0], ts.vel_ned_mps[1])
        yield (t_s, ts.pos_ned_m[0], ts.pos_ned_m[1], speed, math.hypot(*ts.acc_ned_mps2[:2]), ts.pos_ned_m[2])


def test_the_point_cruises_along_the_line_then_brakes_to_a_stop_at_the_end():
    # 60 m south-west to home; the vehicle keeps up (it sits on the point)
    transit = Transit("home", (36.0, 48.0), (0.0, 0.0), -10.0, speed_mps=5.0, brake_mps2=1.0, t0_s=0.0)
    here = [(36.0, 48.0)]
    out = []
    for row in fly(transit, lambda _t_s: here[-1], 30.0):
        out.append(row)
        here.append((row[1], row[2]))
    assert all(r[5] == -10.0 for r in out)
    assert max(r[3] for r in out) == 5.0
    # on the line home, heading there
    for _, n, e, *_ in out:
        assert abs(n * 48.0 - e * 36.0) < 1e-6 and 0.0 <= n <= 36.0
    # cruising until it must brake (v² = 2 a d: 12.5 m out), then slowing at the braking rate, stopping at home
    cruise = [r for r in out if math.hypot(r[1], r[2]) > 13.0 and r[0] > 0.0]
    assert all(abs(r[3] - 5.0) < 1e-9 and r[4] == 0.0 for r in cruise)
    speeds = [r[3] for r in out]
    assert all(b <= a + 1e-9 for a, b in zip(speeds[len(cruise) :], speeds[len(cruise) + 1 :], strict=False))
    decel = [(a[3] - b[3]) / DT_S for a, b in itertools.pairwise(out) if b[3] > 0.0]
    assert max(decel) < 1.0 + 0.3  # the braking rate (the sqrt law's discrete steps add a little)
    arrived = next(r for r in out if math.hypot(r[1], r[2]) < 1e-9)
    assert arrived[3] == 0.0 and 60.0 / 5.0 + 2.0 < arrived[0] < 60.0 / 5.0 + 5.0 / 1.0
    assert math.hypot(out[-1][1], out[-1][2]) < 1e-9 and out[-1][3] == 0.0


def test_a_vehicle_that_cannot_keep_up_has_the_point_wait_for_it_a_leash_ahead():
    transit = Transit("home", (0.0, 100.0), (0.0, 0.0), -10.0, speed_mps=5.0, brake_mps2=1.0, t0_s=0.0, leash_m=3.0)
    # into a strong wind the vehicle makes only 2 m/s
    out = list(fly(transit, lambda t_s: (0.0, 100.0 - 2.0 * t_s), 10.0))
    for t_s, n, e, *_ in out:
        assert n == 0.0
        assert 100.0 - 2.0 * t_s - 3.0 - 1e-9 <= e <= 100.0 - 2.0 * t_s  # never more than the leash ahead
    # and it never goes back along the line when the vehicle does (pushed back by a gust)
    transit = Transit("home", (0.0, 100.0), (0.0, 0.0), -10.0, speed_mps=5.0, brake_mps2=1.0, t0_s=0.0, leash_m=3.0)
    out = list(fly(transit, lambda t_s: (0.0, 100.0 + 1.0 * t_s), 4.0))
    es = [r[2] for r in out]
    assert all(b <= a for a, b in itertools.pairwise(es))  # (it stopped where the leash caught it)
    assert 100.0 - 3.0 < es[-1] == es[-100] < 100.0


def test_already_home_it_holds_there():
    transit = Transit("home", (0.0, 0.0), (0.0, 0.0), -10.0, speed_mps=5.0, brake_mps2=1.0, t0_s=0.0)
    out = list(fly(transit, lambda t_s: (0.0, 0.0), 1.0))
    assert all(r[1:4] == (0.0, 0.0, 0.0) for r in out)


def test_to_a_search_that_goes_on_it_slows_only_to_the_search_speed_and_drifts_with_the_water():
    drift = (0.3, -0.4)  # 0.5 m/s
    transit = Transit(
        "search_start", (0.0, 0.0), (40.0, 30.0), -15.0, 5.0, 1.0, t0_s=0.0, drift_ne_mps=drift, end_speed_mps=2.0
    )
    here = [(0.0, 0.0)]
    out = []
    for row in fly(transit, lambda _t_s: here[-1], 20.0):
        out.append(row)
        here.append((row[1], row[2]))
    arrived = next(k for k, r in enumerate(out) if r[3] < 0.6)  # only the drift left
    # up to the end the point's speed over the water stays at or above the search speed (2 m/s; with the 0.5 m/s
    # drift, which runs against the line's north-east, the speed over the ground at least 2 - 0.5)
    assert min(r[3] for r in out[1:arrived]) > 2.0 - 0.5
    t_s, n, e, speed, *_ = out[-1]
    assert math.isclose(n, 40.0 + drift[0] * t_s, abs_tol=1e-6) and math.isclose(e, 30.0 + drift[1] * t_s, abs_tol=1e-6)
    assert math.isclose(speed, 0.5, abs_tol=1e-9)  # arrived: it moves with the water, where the search starts
