"""ArduCopter's GUIDED velocity control (AC_PosControl ``input_vel_accel_xy`` / ``_z``), for ``sim.dynamics``.

A velocity-only setpoint is not handed to the velocity PID as it is. AC_PosControl shapes it into a
kinematic trajectory (desired acceleration moves toward a sqrt-controller correction of the velocity error,
at most ``jerk`` m/s³; the correction is limited to ``accel`` m/s²), integrates that trajectory into a
*position target*, and tracks the target with its position P-controller plus the desired velocity and
acceleration as feed-forward (``update_xy_controller``)::

    a_target  = sqrt_controller(v_in − v_des, K_a = jerk/accel, jerk)     |a_target| ≤ accel
    a_des    ← a_des + clamp(a_target − a_des, ±jerk·dt)                  (shape_accel)
    v_des    ← v_des + a_des·dt,     p_target ← p_target + v_des·dt + ½a_des·dt²
    v_target  = K_pos (p_target − p) + v_des,                             |p_target − p| ≤ leash
    a_sp      = PID(v_target − v) + a_des                                 (the velocity PID, in Dynamics)

Small corrections therefore see a first-order lag of 1/K_a (0.5 s with the defaults) and large steps an
S-curve (the jerk limit), which is what the recorded step responses show; the position target makes the
vehicle fly the *integral* of the shaped velocity, so wind and the PID's own lag are corrected.
``sqrt_controller`` is AP_Math's (linear below ``limit/K²``, then √(2·limit·(|e| − limit/(2K²)))).
Vectors are NED; the horizontal pair is shaped as one vector, the vertical axis on its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.wind import Vec3


@dataclass(frozen=True, slots=True)
class PosControlParams:
    """ArduCopter 4.x defaults (parameter names in comments); SI units."""

    pos_xy_p: float = 1.0  # PSC_POSXY_P, 1/s
    pos_z_p: float = 1.0  # PSC_POSZ_P, 1/s
    accel_xy_mps2: float = 2.5  # WPNAV_ACCEL (GUIDED sets it as the shaping limit), m/s²
    jerk_xy_mps3: float = 5.0  # PSC_JERK_XY, m/s³
    accel_z_mps2: float = 1.0  # WPNAV_ACCEL_Z, m/s²
    jerk_z_mps3: float = 5.0  # PSC_JERK_Z, m/s³
    leash_xy_m: float = 5.0  # the position error the P-controller keeps (AC_P_2D error limit), m
    leash_z_m: float = 2.0


def sqrt_controller(error: float, p: float, second_ord_lim: float, dt_s: float) -> float:
    """AP_Math ``sqrt_controller``: linear near zero, square-root beyond, never overshooting in one step."""
    if second_ord_lim <= 0.0:
        out = error * p
    elif p == 0.0:
        out = math.copysign(math.sqrt(2.0 * second_ord_lim * abs(error)), error)
    else:
        linear_dist = second_ord_lim / (p * p)
        if abs(error) > linear_dist:
            out = math.copysign(math.sqrt(2.0 * second_ord_lim * (abs(error) - linear_dist / 2.0)), error)
        else:
            out = error * p
    if dt_s > 0.0 and abs(out) > abs(error) / dt_s:
        out = error / dt_s  # do not overshoot the target within one step
    return out


def _limit_norm(x: float, y: float, limit: float) -> tuple[float, float]:
    n = math.hypot(x, y)
    if n > limit > 0.0:
        return x * limit / n, y * limit / n
    return x, y


class GuidedVelocityShaper:
    """The trajectory AC_PosControl builds from velocity setpoints; ``step`` returns (v_target, a_des)."""

    def __init__(self, params: PosControlParams) -> None:
        self.params = params
        self.pos_target = [0.0, 0.0, 0.0]
        self.vel_desired = [0.0, 0.0, 0.0]
        self.accel_desired = [0.0, 0.0, 0.0]

    def reset(self, pos: Vec3, vel: Vec3) -> None:
        """``init_xy_controller``/``init_z_controller``: start the trajectory where the vehicle is."""
        self.pos_target = list(pos)
        self.vel_desired = list(vel)
        self.accel_desired = [0.0, 0.0, 0.0]

    def step(self, dt_s: float, vel_in: Vec3, pos: Vec3) -> tuple[Vec3, Vec3]:
        pr = self.params
        pt, vd, ad = self.pos_target, self.vel_desired, self.accel_desired
        # update_pos_vel_accel: advance the trajectory
        for i in range(3):
            pt[i] += vd[i] * dt_s + 0.5 * ad[i] * dt_s * dt_s
            vd[i] += ad[i] * dt_s
        # shape_vel_accel_xy: the horizontal velocity error as one vector
        ex, ey = vel_in[0] - vd[0], vel_in[1] - vd[1]
        e_h = math.hypot(ex, ey)
        kpa_xy = pr.jerk_xy_mps3 / pr.accel_xy_mps2
        a_h = sqrt_controller(e_h, kpa_xy, pr.jerk_xy_mps3, dt_s) if e_h > 0.0 else 0.0
        a_h = min(a_h, pr.accel_xy_mps2)
        atx, aty = (a_h * ex / e_h, a_h * ey / e_h) if e_h > 0.0 else (0.0, 0.0)
        dx, dy = _limit_norm(atx - ad[0], aty - ad[1], pr.jerk_xy_mps3 * dt_s)
        ad[0] += dx
        ad[1] += dy
        # shape_vel_accel (z)
        ez = vel_in[2] - vd[2]
        kpa_z = pr.jerk_z_mps3 / pr.accel_z_mps2
        atz = max(-pr.accel_z_mps2, min(pr.accel_z_mps2, sqrt_controller(ez, kpa_z, pr.jerk_z_mps3, dt_s)))
        ad[2] += max(-pr.jerk_z_mps3 * dt_s, min(pr.jerk_z_mps3 * dt_s, atz - ad[2]))
        # The position loop keeps the target within its leash of the vehicle (AC_P_2D::update_all).
        ox, oy = _limit_norm(pt[0] - pos[0], pt[1] - pos[1], pr.leash_xy_m)
        pt[0], pt[1] = pos[0] + ox, pos[1] + oy
        oz = max(-pr.leash_z_m, min(pr.leash_z_m, pt[2] - pos[2]))
        pt[2] = pos[2] + oz
        v_target = (pr.pos_xy_p * ox + vd[0], pr.pos_xy_p * oy + vd[1], pr.pos_z_p * oz + vd[2])
        return v_target, (ad[0], ad[1], ad[2])
