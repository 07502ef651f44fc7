"""Constant-bearing guidance (Fossen 2011; thesis §2.5.1, eqs. 2.19–2.21). Pure.

    p̃   = p − p_t                               position error (vehicle minus target), NED m
    κ   = U_a,max · ‖p̃‖ / sqrt(p̃ᵀp̃ + Δ²)        approach speed, m/s               (2.21)
    v_a = −κ · p̃ / ‖p̃‖                          approach velocity, NED m/s        (2.20)
    v_d = v_a + v_t                              desired velocity, NED m/s         (2.19)

Optional lead (off when ``velocity_lead_s`` = 0, the thesis law): the autopilot's velocity loop lags its
setpoint by roughly its time constant τ, so a target that turns is followed with a lag of τ·a_t. Adding
``velocity_lead_s · a_t`` to the feed-forward (v_d = v_a + v_t + τ_lead·a_t) cancels most of that lag.

Far from the target the vehicle closes at U_a,max; within Δ the approach speed falls off linearly
(κ ≈ U_a,max·‖p̃‖/Δ), so near the target the law is a proportional controller with gain U_a,max/Δ plus
the target-velocity feed-forward. Saturation to the vehicle's limits is the envelope's job.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from app.messages import Vec3


@dataclass(frozen=True, slots=True)
class ConstantBearingParams:
    approach_speed_max_mps: float  # U_a,max
    transient_distance_m: float  # Δ_p̃
    velocity_lead_s: float = 0.0  # τ_lead: target-acceleration feed-forward, s (0: thesis eq. 2.19)


def approach_speed_mps(distance_m: float, params: ConstantBearingParams) -> float:
    """κ of eq. 2.21 for a position error of norm ``distance_m``."""
    # κ = U_a,max ‖p̃‖ / sqrt(p̃ᵀp̃ + Δ²)
    return (
        params.approach_speed_max_mps * distance_m / math.sqrt(distance_m * distance_m + params.transient_distance_m**2)
    )


def constant_bearing_velocity(
    pos_ned_m: Vec3,
    target_pos_ned_m: Vec3,
    target_vel_ned_mps: Vec3,
    params: ConstantBearingParams,
    target_acc_ned_mps2: Vec3 = (0.0, 0.0, 0.0),
) -> Vec3:
    """Desired vehicle velocity (NED, m/s) toward a target moving at ``target_vel_ned_mps``."""
    lead = params.velocity_lead_s
    if lead:
        # v_t + τ_lead·a_t
        target_vel_ned_mps = (
            target_vel_ned_mps[0] + lead * target_acc_ned_mps2[0],
            target_vel_ned_mps[1] + lead * target_acc_ned_mps2[1],
            target_vel_ned_mps[2] + lead * target_acc_ned_mps2[2],
        )
    # p̃ = p − p_t
    p_err = (
        pos_ned_m[0] - target_pos_ned_m[0],
        pos_ned_m[1] - target_pos_ned_m[1],
        pos_ned_m[2] - target_pos_ned_m[2],
    )
    dist_m = math.sqrt(p_err[0] ** 2 + p_err[1] ** 2 + p_err[2] ** 2)
    if dist_m < 1e-9:
        return target_vel_ned_mps
    kappa = approach_speed_mps(dist_m, params)
    # v_d = −κ p̃/‖p̃‖ + v_t
    return (
        -kappa * p_err[0] / dist_m + target_vel_ned_mps[0],
        -kappa * p_err[1] / dist_m + target_vel_ned_mps[1],
        -kappa * p_err[2] / dist_m + target_vel_ned_mps[2],
    )
