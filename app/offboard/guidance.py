"""Constant-bearing guidance (Fossen 2011; thesis §2.5.1, eqs. 2.19–2.21). Pure.

    p̃   = p − p_t                               position error (vehicle minus target), NED m
    κ   = U_a,max · ‖p̃‖ / sqrt(p̃ᵀp̃ + Δ²)        approach speed, m/s               (2.21)
    v_a = −κ · p̃ / ‖p̃‖                          approach velocity, NED m/s        (2.20)
    v_d = v_a + v_t                              desired velocity, NED m/s         (2.19)

Optional lead (off when ``velocity_lead_s`` = 0, the thesis law): the autopilot's velocity loop lags its
setpoint by roughly its time constant τ, so a target that turns is followed with a lag of τ·a_t. Adding
``velocity_lead_s · a_t`` to the feed-forward (v_d = v_a + v_t + τ_lead·a_t) cancels most of that lag.

A target that asks to be followed tightly (``TargetState.precise``: the pickup going down onto the object) gets
the precise Δ_p̃ and τ_lead where they are set (``for_target``): the object's wave orbit turns faster than the
motions the lead is set for, and on PX4 the 0.7 s lead left the vehicle a median 0.05 m behind the estimate low
over the object (0.4 s with Δ 0.2 m: 0.02 m; sea state 2, 40 runs in process).

Optional damping (off when ``damping_s`` = 0; for a precise target ``precise_damping_s``): the law acts on the
horizontal error predicted τ_d ahead at the relative velocity, p̃ + τ_d (v − v_t), i.e. a derivative term of gain
(U_a,max/Δ)·τ_d near the target. Near the target the loop is ë·τ' + ė + (U_a,max/Δ)·e = 0 with τ' the velocity
response's time constant (PX4's, quickened by K_v): at 10 1/s and τ' ≈ 0.2 s its damping ratio is ~0.35, and with
the loop's delays PX4's descent swung around the object at ~1 Hz (roll/pitch ±20–35°). τ_d adds
(U_a,max/Δ)·τ_d to the ė term: 0.1 s doubles the damping ratio.

Optional integral action (off when ``integral_gain_per_s2`` = 0): real autopilots do not deliver the
velocity they are sent. PX4's velocity PID leaves 20–30 % of a step missing for seconds (its slow integrator
mode) and its estimate carries a slowly varying velocity error and a vertical bias, so a proportional
position loop keeps a position error of (velocity shortfall)/gain. ``PositionIntegral`` adds

    v_I ← v_I − K_I · p̃ · dt                   only while ‖p̃‖ < integrate_within_m and the last setpoint
                                                 went out unclamped (conditional integration: anti-windup)
    ‖v_I,h‖ ≤ v_I,max,   |v_I,d| ≤ v_I,max       and it restarts at zero on every change of target source
    v_d = v_a + v_t + τ_lead·a_t + v_I

Two more terms live in the setpoint loop, which sees the telemetry stream (``app.offboard.setpoint_loop``):
- the estimate-inconsistency observer d̂ = low-pass(dp̂/dt − v̂), subtracted from the setpoint: the
  autopilot steers its velocity *estimate* to the setpoint, so when the estimate is off (PX4 SIH: 0.2 m/s
  RMS) the reported position moves at v_sp + d̂;
- horizontal velocity-error feedback v_sp + K_v (v_sp − v̂) (its norm ≤ ``velocity_error_max_mps``, so an
  approach does not become more aggressive than guidance + 1 m/s; for a target that asks to be followed tightly
  ``precise_velocity_error_max_mps``: low over the object the vehicle swings around it at ~1 Hz with setpoints of
  ±2 m/s, and a 1 m/s bound clipped the feedback that damps the swing) for autopilots whose offboard velocity control
  is a velocity loop only (PX4): it stiffens that loop from outside (PX4's default MPC_XY_VEL_P_ACC 1.8
  leaves a gust's velocity error standing for a second, and 20–30 % of a step for seconds). ArduCopter
  integrates velocity setpoints into a position target of its own, so there K_v = 0 (feedback would fight
  its trajectory shaping: the circle's p95 went from 0.03 to 0.43 m with K_v = 1).

Far from the target the vehicle closes at U_a,max; within Δ the approach speed falls off linearly
(κ ≈ U_a,max·‖p̃‖/Δ), so near the target the law is a proportional controller with gain U_a,max/Δ plus
the target-velocity feed-forward. Saturation to the vehicle's limits is the envelope's job.

Optional separate vertical (``separate_vertical``; the thesis law is one 3-D law): eqs. 2.20–2.21 applied to the
horizontal error p̃_h and to the vertical error p̃_d apart, each with its own κ — as PX4's and ArduPilot's own
position controllers hold the two apart. In one 3-D law a climb takes the horizontal hold with it: 1.5 m to
climb and 0.15 m off the object give κ ≈ U_a,max, of which only p̃_h/‖p̃‖ = 10 % goes to closing the 0.15 m
(0.19 m/s where the horizontal law alone asks 0.70 at Δ 0.4); climbing back from low over the waves, the vehicle
slid off the object just as the crests came.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from app.messages import Vec3


@dataclass(frozen=True, slots=True)
class ConstantBearingParams:
    approach_speed_max_mps: float  # U_a,max
    transient_distance_m: float  # Δ_p̃
    velocity_lead_s: float = 0.0  # τ_lead: target-acceleration feed-forward, s (0: thesis eq. 2.19)
    integral_gain_per_s2: float = 0.0  # K_I on the position error, 1/s² (0: no integral action)
    integral_max_mps: float = 0.5  # v_I,max, per horizontal norm and vertically, m/s
    integral_within_m: float = 1.0  # integrate only this close to the target, m
    inconsistency_tau_s: float = 0.0  # low-pass of the estimate-inconsistency observer, s (0: off)
    inconsistency_max_mps: float = 0.5  # its bound per axis, m/s
    velocity_error_gain: float = 0.0  # K_v: horizontal v_sp += K_v (v_sp − v̂), for velocity-only autopilots
    velocity_error_max_mps: float = 1.0  # bound of ‖K_v (v_sp − v̂)‖, m/s
    precise_transient_distance_m: float | None = None  # Δ_p̃ for a target that asks to be followed tightly (None: Δ_p̃)
    separate_vertical: bool = False  # the law on the horizontal and the vertical error apart (False: thesis, 3-D)
    precise_velocity_lead_s: float | None = None  # τ_lead for a target that asks to be followed tightly (None: τ_lead)
    # ‖K_v (v_sp − v̂)‖'s bound for a target that asks to be followed tightly (None: velocity_error_max_mps)
    precise_velocity_error_max_mps: float | None = None
    precise_damping_s: float | None = None  # τ_d for a target that asks to be followed tightly (None: τ_d)
    damping_s: float = 0.0  # τ_d: guidance on the horizontal p̃ predicted τ_d ahead, p̃ + τ_d (v − v_t), s (0: none)
    # U_a,max of the separate vertical law when it climbs, with Δ_p̃ scaled to keep the gain U_a,max/Δ_p̃ (None: U_a,max)
    climb_speed_max_mps: float | None = None

    def for_target(self, precise: bool) -> ConstantBearingParams:
        """These params, with the precise Δ_p̃, τ_lead, velocity-error bound and τ_d for a target that asks for it."""
        if not precise:
            return self
        delta_m, lead_s = self.precise_transient_distance_m, self.precise_velocity_lead_s
        bound_mps = self.precise_velocity_error_max_mps
        return replace(
            self,
            transient_distance_m=self.transient_distance_m if delta_m is None else delta_m,
            velocity_lead_s=self.velocity_lead_s if lead_s is None else lead_s,
            velocity_error_max_mps=self.velocity_error_max_mps if bound_mps is None else bound_mps,
            damping_s=self.damping_s if self.precise_damping_s is None else self.precise_damping_s,
        )


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
    vel_ned_mps: Vec3 | None = None,
) -> Vec3:
    """Desired vehicle velocity (NED, m/s) toward a target moving at ``target_vel_ned_mps``."""
    # p̃ = p − p_t, horizontally predicted τ_d ahead at the relative velocity: p̃ + τ_d (v − v_t)
    tau_d = params.damping_s
    ahead_n = ahead_e = 0.0
    if tau_d and vel_ned_mps is not None:
        ahead_n = tau_d * (vel_ned_mps[0] - target_vel_ned_mps[0])
        ahead_e = tau_d * (vel_ned_mps[1] - target_vel_ned_mps[1])
    p_err = (
        pos_ned_m[0] - target_pos_ned_m[0] + ahead_n,
        pos_ned_m[1] - target_pos_ned_m[1] + ahead_e,
        pos_ned_m[2] - target_pos_ned_m[2],
    )
    lead = params.velocity_lead_s
    if lead:
        # v_t + τ_lead·a_t
        target_vel_ned_mps = (
            target_vel_ned_mps[0] + lead * target_acc_ned_mps2[0],
            target_vel_ned_mps[1] + lead * target_acc_ned_mps2[1],
            target_vel_ned_mps[2] + lead * target_acc_ned_mps2[2],
        )
    if params.separate_vertical:
        v_a = (*approach_velocity(p_err[:2], params), vertical_approach_velocity(p_err[2], params))
    else:
        v_a = approach_velocity(p_err, params)
    # v_d = v_a + v_t
    return (
        v_a[0] + target_vel_ned_mps[0],
        v_a[1] + target_vel_ned_mps[1],
        v_a[2] + target_vel_ned_mps[2],
    )


def vertical_approach_velocity(down_err_m: float, params: ConstantBearingParams) -> float:
    """The separate vertical law's v_a,d: as ``approach_velocity`` on p̃_d, except that a climb (below the target,
    p̃_d > 0) saturates at ``climb_speed_max_mps`` (when that is higher than U_a,max) with Δ_p̃ scaled alike, the
    same gain U_a,max/Δ_p̃ near the target."""
    u_mps, climb_mps = params.approach_speed_max_mps, params.climb_speed_max_mps
    if climb_mps is None or down_err_m <= 0.0 or climb_mps <= u_mps:
        return approach_velocity((down_err_m,), params)[0]
    delta_m = params.transient_distance_m * climb_mps / u_mps
    return -climb_mps * down_err_m / math.sqrt(down_err_m * down_err_m + delta_m * delta_m)


def approach_velocity(p_err: tuple[float, ...], params: ConstantBearingParams) -> tuple[float, ...]:
    """v_a = −κ p̃/‖p̃‖ (eqs. 2.20–2.21) for a position error p̃ of any dimension (zero on the target)."""
    dist_m = math.sqrt(sum(c * c for c in p_err))
    if dist_m < 1e-9:
        return tuple(0.0 for _ in p_err)
    kappa = approach_speed_mps(dist_m, params)
    return tuple(-kappa * c / dist_m for c in p_err)


class PositionIntegral:
    """The integral term ``v_I`` of the position loop (see the module docstring); the caller resets it."""

    def __init__(self, params: ConstantBearingParams) -> None:
        self._params = params
        self.v_ned_mps: Vec3 = (0.0, 0.0, 0.0)

    def reset(self) -> None:
        self.v_ned_mps = (0.0, 0.0, 0.0)

    def update(self, pos_err_ned_m: Vec3, dt_s: float, *, saturated: bool) -> Vec3:
        """Integrate the position error p̃ = p − p_t over ``dt_s``; returns v_I (NED, m/s)."""
        p = self._params
        if p.integral_gain_per_s2 <= 0.0:
            return self.v_ned_mps
        dist_m = math.sqrt(pos_err_ned_m[0] ** 2 + pos_err_ned_m[1] ** 2 + pos_err_ned_m[2] ** 2)
        if saturated or dist_m >= p.integral_within_m or not 0.0 < dt_s < 1.0:
            return self.v_ned_mps
        k = p.integral_gain_per_s2 * dt_s
        vn = self.v_ned_mps[0] - k * pos_err_ned_m[0]
        ve = self.v_ned_mps[1] - k * pos_err_ned_m[1]
        vd = self.v_ned_mps[2] - k * pos_err_ned_m[2]
        v_max = p.integral_max_mps
        v_h = math.hypot(vn, ve)
        if v_h > v_max:
            vn, ve = vn * v_max / v_h, ve * v_max / v_h
        vd = max(-v_max, min(v_max, vd))
        self.v_ned_mps = (vn, ve, vd)
        return self.v_ned_mps
