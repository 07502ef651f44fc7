"""How closely guidance and each calibrated autopilot follow a floating object's wave orbit as it drifts.

    python -m sim.bench_orbit [--profiles px4,ardupilot] [--radii 0.45,0.79,1.1] [--drifts 0,0.9] [--json]

The circle mission (``app/missions/circle.yaml``, thesis eqs. 5.3–5.4) flies a small, fast circle — a wave orbit
of ``radius`` m, one turn in ``PERIOD_S`` (sea state 3's orbits: 0.6–1.0 m/s at their p95) — whose centre drifts
at ``drift`` m/s (a current), on the in-process vehicle with wind, in virtual time; the target asks for precision
or not (``TargetState.precise``, as the pickup's descent does). Prints the horizontal tracking error p50/p95 per
case. A linear loop follows a drifting orbit exactly as well as a still one; where the figures jump to a metre,
the loop has fallen into a limit cycle (the autopilot's acceleration limit: ArduCopter's WPNAV_ACCEL shapes
GUIDED's velocity setpoints).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from typing import Any

from app.cli import OneLineParser, name_list, number_list, run_cli
from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import TargetState
from app.missions.circle import CircleTarget
from app.missions.table import load_mission
from app.settings import load_settings
from sim.airframes import SIM_PROFILES
from sim.inproc import InProcessVehicle
from sim.virtual_loop import VirtualTimeLoop

PERIOD_S = 4.5  # one orbit (sea state 3's waves: 4–5 s)
LAPS = 8
DRIFT_TO_DEG = 45.0


class DriftingOrbit(CircleTarget):
    """The circle, its centre drifting at ``drift_mps`` towards ``DRIFT_TO_DEG``; precise if asked."""

    drift_mps = 0.0
    precise = False

    def target_at(self, t_s: float) -> TargetState:
        s = super().target_at(t_s)
        dt_s = max(0.0, t_s - self.t0_s)
        to = math.radians(DRIFT_TO_DEG)
        vn, ve = self.drift_mps * math.cos(to), self.drift_mps * math.sin(to)
        (n, e, d), (vn0, ve0, vd0) = s.pos_ned_m, s.vel_ned_mps
        return replace(s, pos_ned_m=(n + vn * dt_s, e + ve * dt_s, d), vel_ned_mps=(vn0 + vn, ve0 + ve, vd0),
                       precise=self.precise)  # fmt: skip


async def _fly(profile: str, radius_m: float, seed: int) -> dict[str, Any]:
    p = SIM_PROFILES[profile]
    vehicle = InProcessVehicle(seed=seed, profile=p.autopilot, vehicle_params=p.airframe, estimator=p.estimator)
    table = load_mission("circle")
    params = {"circle_radius_m": radius_m, "circle_v_reduction_s": PERIOD_S / (2.0 * math.pi), "circle_laps": LAPS}
    table = table.model_copy(update={"params": table.params.model_copy(update=params)})
    flight = await fly_mission(vehicle, table, load_settings(), LoopClock(), EventLog(None))
    return flight.figures


def fly_orbit(profile: str, radius_m: float, drift_mps: float, precise: bool, seed: int = 1) -> dict[str, Any]:
    """One case: the horizontal tracking error's p50/p95 (m) and the orbit's speed (m/s)."""
    import app.missions.circle as circle

    DriftingOrbit.drift_mps, DriftingOrbit.precise = drift_mps, precise
    plain, circle.CircleTarget = circle.CircleTarget, DriftingOrbit  # type: ignore[misc]
    loop = VirtualTimeLoop()
    try:
        fig = loop.run_until_complete(_fly(profile, radius_m, seed))
    finally:
        circle.CircleTarget = plain  # type: ignore[misc]
        loop.close()
    return {
        "profile": profile,
        "orbit_radius_m": radius_m,
        "orbit_speed_mps": round(2.0 * math.pi * radius_m / PERIOD_S, 3),
        "drift_mps": drift_mps,
        "precise": precise,
        "p50_m": round(fig["tracking_error_horizontal_p50_m"], 4),
        "p95_m": round(fig["tracking_error_horizontal_p95_m"], 4),
    }


def main(argv: list[str] | None = None) -> int:
    ap = OneLineParser(prog="python -m sim.bench_orbit", description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--profiles", type=name_list(SIM_PROFILES), default=("px4", "ardupilot"), help="e.g. px4,ardupilot")
    ap.add_argument("--radii", type=number_list(0.05, 5.0, "m"), default=(0.45, 0.79, 1.1), help="orbit radii, m")
    ap.add_argument("--drifts", type=number_list(0.0, 3.0, "m/s"), default=(0.0, 0.9), help="drift speeds, m/s")
    ap.add_argument("--json", action="store_true", help="one JSON object on stdout")
    a = ap.parse_args(argv)
    rows = [
        fly_orbit(profile, r, d, precise)
        for profile in a.profiles
        for r in a.radii
        for precise in (False, True)
        for d in a.drifts
    ]
    if a.json:
        print(json.dumps({"period_s": PERIOD_S, "cases": rows}))
        return 0
    print(f"{'profile':10} {'orbit m/s':>9} {'drift m/s':>9} {'precise':>7} {'p50 m':>7} {'p95 m':>7}")
    for r in rows:
        print(f"{r['profile']:10} {r['orbit_speed_mps']:9.2f} {r['drift_mps']:9.2f} {r['precise']!s:>7} "
              f"{r['p50_m']:7.3f} {r['p95_m']:7.3f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(run_cli(main, "python -m sim.bench_orbit"))
