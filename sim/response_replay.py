"""Replay a recorded velocity-setpoint script through ``sim.dynamics`` and compare with the recording.

A recording (CSV, one row per 50 Hz setpoint tick: ``t_s``, ``segment``, ``sp_vn sp_ve sp_vd``, ``sp_yaw``,
``vel_n vel_e vel_d`` as the autopilot reported them) is flown open loop: each setpoint holds from its tick
to the next, the physics steps at ``dt_s``, no wind, starting at the recorded velocity. The residual is the
simulated velocity minus the reported one at every tick, over the whole script except the landing.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.dynamics import Dynamics
from sim.flight_stack import PHYSICS_DT_S
from sim.multirotor import ControlInput, MultirotorParams


@dataclass(frozen=True)
class Recording:
    t_s: np.ndarray
    segment: np.ndarray
    setpoint: np.ndarray  # n × 3, NED m/s
    velocity: np.ndarray  # n × 3, as reported
    yaw_sp_rad: float
    yaw_rad: float


def load(path: Path) -> Recording:
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{path}: no rows")

    def cols(*names: str) -> np.ndarray:
        return np.array([[float(r[n]) for n in names] for r in rows])

    return Recording(
        cols("t_s")[:, 0],
        np.array([r["segment"] for r in rows]),
        cols("sp_vn", "sp_ve", "sp_vd"),
        cols("vel_n", "vel_e", "vel_d"),
        float(rows[0]["sp_yaw"]),
        float(rows[0]["yaw"]),
    )


def replay(rec: Recording, params: MultirotorParams, dt_s: float = PHYSICS_DT_S) -> np.ndarray:
    """The simulated velocity at every tick (n × 3), the physics stepped at ``dt_s`` (the flight stack's rate)."""
    dyn = Dynamics(params, pos_ned_m=(0.0, 0.0, -5.0), yaw_rad=rec.yaw_rad)
    dyn.start_airborne(tuple(rec.velocity[0]))
    out = np.empty_like(rec.velocity)
    t_s = rec.t_s[0]
    for i, t_next in enumerate(rec.t_s):
        control = ControlInput(tuple(rec.setpoint[max(i - 1, 0)]), rec.yaw_sp_rad)
        while t_s < t_next - 1e-9:
            h = min(dt_s, t_next - t_s)
            dyn.step(h, control)
            t_s += h
        out[i] = dyn.estimate.vel_ned_mps
    return out


def residual_rms(rec: Recording, params: MultirotorParams, dt_s: float = PHYSICS_DT_S) -> tuple[float, float, float]:
    """RMS of simulated − reported velocity per axis (n, e, d), landing excluded."""
    keep = rec.segment != "land"
    r = replay(rec, params, dt_s)[keep] - rec.velocity[keep]
    n, e, d = (math.sqrt(float(np.mean(r[:, i] ** 2))) for i in range(3))
    return n, e, d
