"""Multirotor point mass with attitude lag, a PX4-like velocity controller, drag, ground and battery.

Frames and units: local NED (north, east, down) about home, metres, m/s, m/s²; roll/pitch/yaw in
radians (ZYX Euler, yaw clockwise from north); times in seconds. Pure: ``step(dt_s, control)`` advances
the state; there are no clock reads and the only randomness is the seeded wind.

Model per step (PX4 ``PositionControl::_velocityControl`` / ``_accelerationControl``)::

    e     = v_sp − v
    a_sp  = K_p e + ∫K_i e − K_d a              (PID on acceleration, MPC_*_VEL_*_ACC)
    |a_sp,xy| ≤ (g − a_sp,z)·tan(MPC_TILT_MAX_AIR)   vertical first; tracking anti-windup horizontally:
                                                e_I = e − (2/K_p)(a_sp − a_lim)
    z_b,sp = normalize(−a_x, −a_y, g − a_z)     tilt-limited to MPC_TILT_MAX
    T      = (g − a_z) / cos(tilt_sp)           collective specific thrust, ≤ thrust_to_weight·g
    φ, θ  ← first-order lag (τ) towards the setpoint attitude; ψ rate-limited towards ψ_sp
    a      = −T z_b(φ, θ, ψ) + g e_D − c (v − v_wind)

The hover thrust is known exactly (feed-forward g), so the integrators only have to reject drag and
wind, which is what they do in PX4 too (there the hover-thrust estimator takes care of g).

Optional ArduCopter position control (``pos_control``, see ``sim.poscontrol``): the velocity setpoint is
shaped into a jerk-limited trajectory and integrated into a position target; the PID tracks
K_pos·(p_target − p) + v_des with a_des as feed-forward. ``sim.airframes`` holds calibrated sets;
``sim.multirotor`` the parameters, the command, the truth and the battery.
"""

from __future__ import annotations

import math
from dataclasses import replace

from sim.estimator import EstimatorError
from sim.multirotor import G_MPS2, Battery, ControlInput, MultirotorParams, VehicleState, clamp, wrap_pi
from sim.poscontrol import GuidedVelocityShaper
from sim.wind import Vec3, Wind


def velocity_from_position(
    pos_sp_ned_m: Vec3,
    pos_ned_m: Vec3,
    params: MultirotorParams,
    max_hor_mps: float | None = None,
    max_up_mps: float | None = None,
    max_down_mps: float | None = None,
) -> Vec3:
    """PX4 position P-controller: v_sp = K (p_sp − p), horizontally clamped to the cruise speed."""
    vn = params.xy_pos_p * (pos_sp_ned_m[0] - pos_ned_m[0])
    ve = params.xy_pos_p * (pos_sp_ned_m[1] - pos_ned_m[1])
    vd = params.z_pos_p * (pos_sp_ned_m[2] - pos_ned_m[2])
    v_max = params.cruise_hor_mps if max_hor_mps is None else max_hor_mps
    v_h = math.hypot(vn, ve)
    if v_h > v_max > 0.0:
        vn, ve = vn * v_max / v_h, ve * v_max / v_h
    up = params.vel_up_max_mps if max_up_mps is None else max_up_mps
    down = params.vel_down_max_mps if max_down_mps is None else max_down_mps
    return (vn, ve, clamp(vd, -up, down))


class Dynamics:
    """The vehicle: state, controller integrators, wind and battery; ``step`` is the only mover."""

    def __init__(
        self,
        params: MultirotorParams | None = None,
        wind: Wind | None = None,
        pos_ned_m: Vec3 = (0.0, 0.0, 0.0),
        yaw_rad: float = 0.0,
        estimator: EstimatorError | None = None,
    ) -> None:
        """``estimator`` None: the controller and ``estimate`` see the truth."""
        self.params = params if params is not None else MultirotorParams()
        self.estimator = estimator
        self.wind = wind if wind is not None else Wind.off()
        self.battery = Battery(self.params.battery)
        self.ground_down_m = 0.0  # the ground/sea surface under the vehicle (home level)
        # … and how it moves horizontally: a vehicle resting on it moves with it (the water's orbital velocity and
        # current carry a vehicle sitting on the sea as they carry the object; the ground stands still)
        self.ground_vel_ne_mps: tuple[float, float] = (0.0, 0.0)
        self._p = list(pos_ned_m)
        self._v = [0.0, 0.0, 0.0]
        self._a = [0.0, 0.0, 0.0]
        self._roll_rad = 0.0
        self._pitch_rad = 0.0
        self._yaw_rad = yaw_rad
        self._rates = (0.0, 0.0, 0.0)
        self._vel_int = [0.0, 0.0, 0.0]
        self._shaper = GuidedVelocityShaper(self.params.pos_control) if self.params.pos_control is not None else None
        self._thrust_mps2 = 0.0
        self._on_ground = self._p[2] >= self.ground_down_m
        self._wind_ned_mps = self.wind.wind_ned_mps
        # the estimate, built at most once per step (the hottest read of a run): position and velocity, and the state
        self._estimate_pv: tuple[Vec3, Vec3] | None = None
        self._estimate: VehicleState | None = None
        pr = self.params
        self._tilt_max_rad = math.radians(pr.tilt_max_deg)
        self._tan_tilt_max = math.tan(self._tilt_max_rad)
        self._yaw_rate_max_radps = math.radians(pr.yaw_rate_max_dps)
        self._attitude_dt_s, self._attitude_k = math.nan, 0.0  # the lag's 1 − e^{−dt/τ}, for the last dt

    @property
    def state(self) -> VehicleState:
        p, v = self._p, self._v
        return self._state_at((p[0], p[1], p[2]), (v[0], v[1], v[2]))

    @property
    def on_ground(self) -> bool:
        """Resting on the ground (or the water) under the vehicle."""
        return self._on_ground

    @property
    def estimate(self) -> VehicleState:
        """What the autopilot believes: the truth with the estimator's error (the velocity error is
        dropped while on the ground, where EKF2/EKF3 fuse zero velocity)."""
        est = self._estimate
        if est is None:
            tilt_err = (0.0, 0.0) if self.estimator is None else self.estimator.tilt_err_rad
            est = self._estimate = self._state_at(*self.estimate_pos_vel(), tilt_err)
        return est

    def estimate_pos_vel(self) -> tuple[Vec3, Vec3]:
        """The estimate's position and velocity alone: what the controllers read every step."""
        pv = self._estimate_pv
        if pv is None:
            p, v = self._p, self._v
            true_pos, true_vel = (p[0], p[1], p[2]), (v[0], v[1], v[2])
            if self.estimator is None:
                pv = (true_pos, true_vel)
            else:
                pos, vel = self.estimator.apply(true_pos, true_vel)
                pv = (pos, true_vel if self._on_ground else vel)
            self._estimate_pv = pv
        return pv

    def _moved(self) -> None:
        """The state (or the estimator's error, or the wind) changed: the estimate is built anew when read."""
        self._estimate_pv = self._estimate = None

    def _state_at(
        self, pos_ned_m: Vec3, vel_ned_mps: Vec3, tilt_err_rad: tuple[float, float] = (0.0, 0.0)
    ) -> VehicleState:
        """The vehicle's state with this position and velocity (the truth's, or the estimate's, with its roll and
        pitch error: built directly, not as a replace() of ``state`` — ``estimate`` is the hottest property of a
        run)."""
        a = self._a
        return VehicleState(
            pos_ned_m=pos_ned_m,
            vel_ned_mps=vel_ned_mps,
            acc_ned_mps2=(a[0], a[1], a[2]),
            roll_rad=self._roll_rad + tilt_err_rad[0],
            pitch_rad=self._pitch_rad + tilt_err_rad[1],
            yaw_rad=self._yaw_rad,
            rates_radps=self._rates,
            on_ground=self._on_ground,
            thrust_mps2=self._thrust_mps2,
            wind_ned_mps=self._wind_ned_mps,
        )

    @property
    def vel_int_ned_mps2(self) -> Vec3:
        """The velocity-controller integrator (the acceleration it adds to reject drag/wind)."""
        i = self._vel_int
        return (i[0], i[1], i[2])

    def tilt_rad(self) -> float:
        """Angle between the thrust axis and the vertical."""
        return math.acos(clamp(math.cos(self._roll_rad) * math.cos(self._pitch_rad), -1.0, 1.0))

    def start_airborne(self, vel_ned_mps: Vec3) -> None:
        """Begin in flight at ``vel_ned_mps`` (for replays that start mid-air)."""
        self._on_ground = False
        self._v = list(vel_ned_mps)
        self._moved()
        if self._shaper is not None:
            self._shaper.reset(self.estimate.pos_ned_m, self.estimate.vel_ned_mps)

    @property
    def shaping_xy(self) -> tuple[float, float] | None:
        """ArduCopter's horizontal shaping limits in use: (jerk m/s³, acceleration m/s²); None without it."""
        sh = self._shaper
        return None if sh is None else (sh.params.jerk_xy_mps3, sh.params.accel_xy_mps2)

    @property
    def shaping_z(self) -> tuple[float, float] | None:
        """ArduCopter's vertical shaping limits in use: (jerk m/s³, acceleration m/s²); None without it."""
        sh = self._shaper
        return None if sh is None else (sh.params.jerk_z_mps3, sh.params.accel_z_mps2)

    def set_shaping(self, jerk_xy_mps3: float, accel_xy_mps2: float, jerk_z_mps3: float, accel_z_mps2: float) -> None:
        """ArduCopter's shaping limits (PSC_JERK_XY, WPNAV_ACCEL, PSC_JERK_Z, WPNAV_ACCEL_Z) from now on; no-op
        without it."""
        sh = self._shaper
        if sh is not None:
            sh.params = replace(
                sh.params,
                jerk_xy_mps3=jerk_xy_mps3,
                accel_xy_mps2=accel_xy_mps2,
                jerk_z_mps3=jerk_z_mps3,
                accel_z_mps2=accel_z_mps2,
            )

    def reset_integrators(self) -> None:
        self._vel_int = [0.0, 0.0, 0.0]

    # -- the controller ------------------------------------------------------------------------

    def _acceleration_setpoint(
        self, vel_sp: Vec3, dt_s: float, acc_ff: Vec3 = (0.0, 0.0, 0.0)
    ) -> tuple[float, float, float]:
        """PID (+ feed-forward ``acc_ff``) on acceleration with limits and anti-windup; a_sp (NED, m/s²)."""
        pr = self.params
        v_h = math.hypot(vel_sp[0], vel_sp[1])
        vn_sp, ve_sp = vel_sp[0], vel_sp[1]
        if v_h > pr.vel_hor_max_mps:
            vn_sp, ve_sp = vn_sp * pr.vel_hor_max_mps / v_h, ve_sp * pr.vel_hor_max_mps / v_h
        vd_sp = clamp(vel_sp[2], -pr.vel_up_max_mps, pr.vel_down_max_mps)
        v = self.estimate_pos_vel()[1]  # the controller acts on the estimate
        e = (vn_sp - v[0], ve_sp - v[1], vd_sp - v[2])
        # a_sp = K_p e + I − K_d a
        ax = pr.xy_vel_p_acc * e[0] + self._vel_int[0] - pr.xy_vel_d_acc * self._a[0] + acc_ff[0]
        ay = pr.xy_vel_p_acc * e[1] + self._vel_int[1] - pr.xy_vel_d_acc * self._a[1] + acc_ff[1]
        az = pr.z_vel_p_acc * e[2] + self._vel_int[2] + acc_ff[2]
        az_lim = clamp(az, -pr.acc_up_max_mps2, pr.acc_down_max_mps2)
        # What the tilt limit lets through horizontally once the vertical is served (PX4: thrust_max_xy);
        # MPC_ACC_HOR_MAX shapes PX4's own trajectories, not offboard velocity control.
        acc_h_max = (G_MPS2 - az_lim) * self._tan_tilt_max
        a_h = math.hypot(ax, ay)
        ax_lim, ay_lim = ax, ay
        if a_h > acc_h_max:
            ax_lim, ay_lim = ax * acc_h_max / a_h, ay * acc_h_max / a_h
        if not self._on_ground:
            # Tracking anti-windup horizontally: e_I = e − (2/K_p)(a_sp − a_lim)
            arw = 2.0 / pr.xy_vel_p_acc
            ei_x = e[0] - arw * (ax - ax_lim)
            ei_y = e[1] - arw * (ay - ay_lim)
            # Vertically: stop integrating into the saturation.
            ei_z = 0.0 if (az != az_lim and (az - az_lim) * e[2] > 0.0) else e[2]
            self._vel_int[0] += pr.xy_vel_i_acc * ei_x * dt_s
            self._vel_int[1] += pr.xy_vel_i_acc * ei_y * dt_s
            self._vel_int[2] += pr.z_vel_i_acc * ei_z * dt_s
            i_h = math.hypot(self._vel_int[0], self._vel_int[1])
            if i_h > acc_h_max:
                self._vel_int[0] *= acc_h_max / i_h
                self._vel_int[1] *= acc_h_max / i_h
            self._vel_int[2] = clamp(self._vel_int[2], -pr.acc_up_max_mps2, pr.acc_down_max_mps2)
        return ax_lim, ay_lim, az_lim

    def _attitude_setpoint(self, acc_sp: Vec3) -> tuple[float, float, float]:
        """Roll, pitch (rad) and collective specific thrust (m/s²) for an acceleration setpoint."""
        pr = self.params
        # Specific force the thrust has to make: f = a_sp − g e_D; body z points along −f.
        fz_up = G_MPS2 - acc_sp[2]  # > 0: upward thrust component needed
        fx, fy = acc_sp[0], acc_sp[1]
        f_h = math.hypot(fx, fy)
        tilt_max_rad = self._tilt_max_rad
        tilt_rad = math.atan2(f_h, fz_up)
        if tilt_rad > tilt_max_rad:
            scale = fz_up * self._tan_tilt_max / f_h
            fx, fy, tilt_rad = fx * scale, fy * scale, tilt_max_rad
        norm = math.sqrt(fx * fx + fy * fy + fz_up * fz_up)
        # −z_b = (fx, fy, −fz_up)/|f|; rotate into the heading frame to read off roll and pitch.
        c, s = math.cos(self._yaw_rad), math.sin(self._yaw_rad)
        # Thrust direction −z_b in the heading frame is (−sinθ cosφ, sinφ, cosθ cosφ).
        thrust_fwd = (c * fx + s * fy) / norm
        thrust_right = (-s * fx + c * fy) / norm
        roll_sp = math.asin(clamp(thrust_right, -1.0, 1.0))
        pitch_sp = math.atan2(-thrust_fwd, fz_up / norm)
        thrust = min(fz_up / math.cos(tilt_rad), pr.thrust_to_weight * G_MPS2)
        return roll_sp, pitch_sp, max(thrust, 0.0)

    # -- the step ------------------------------------------------------------------------------

    def step(self, dt_s: float, control: ControlInput, armed: bool = True) -> None:
        """Advance the vehicle by ``dt_s`` seconds under ``control``."""
        if dt_s <= 0.0:
            return
        pr = self.params
        wind = self.wind.step(dt_s)
        self._wind_ned_mps = wind
        roll0, pitch0, yaw0 = self._roll_rad, self._pitch_rad, self._yaw_rad

        if self.estimator is not None:
            self.estimator.step(dt_s)
        self._moved()  # the wind and the estimator's error moved on
        if control.motors_on:
            vel_sp, acc_ff = control.vel_sp_ned_mps, (0.0, 0.0, 0.0)
            if self._shaper is not None:
                est_pos, est_vel = self.estimate_pos_vel()
                if self._on_ground or not control.shaped:  # the trajectory starts where the vehicle is
                    self._shaper.reset(est_pos, est_vel)
                if control.shaped:
                    vel_sp, acc_ff = self._shaper.step(dt_s, vel_sp, est_pos)
            acc_sp = self._acceleration_setpoint(vel_sp, dt_s, acc_ff)
            roll_sp, pitch_sp, thrust = self._attitude_setpoint(acc_sp)
        else:
            self.reset_integrators()
            if self._shaper is not None:
                self._shaper.reset(*self.estimate_pos_vel())
            roll_sp, pitch_sp, thrust = 0.0, 0.0, 0.0
        if self._on_ground and not control.motors_on:
            roll_sp = pitch_sp = 0.0

        # Attitude: first-order lag on roll/pitch; yaw rate-limited P towards the setpoint.
        if dt_s != self._attitude_dt_s:
            self._attitude_dt_s, self._attitude_k = dt_s, 1.0 - math.exp(-dt_s / pr.attitude_tau_s)
        k = self._attitude_k
        self._roll_rad += k * (roll_sp - self._roll_rad)
        self._pitch_rad += k * (pitch_sp - self._pitch_rad)
        yaw_rate_max = self._yaw_rate_max_radps
        if control.yaw_rate_sp_radps is not None:
            yaw_rate = clamp(control.yaw_rate_sp_radps, -yaw_rate_max, yaw_rate_max)
        elif control.yaw_sp_rad is not None:
            yaw_rate = clamp(pr.yaw_p * wrap_pi(control.yaw_sp_rad - self._yaw_rad), -yaw_rate_max, yaw_rate_max)
        else:
            yaw_rate = 0.0
        if not control.motors_on and self._on_ground:
            yaw_rate = 0.0
        self._yaw_rad = wrap_pi(self._yaw_rad + yaw_rate * dt_s)
        self._thrust_mps2 = thrust

        # a = −T z_b + g e_D − c (v − v_wind), z_b from the *actual* attitude.
        cr, sr = math.cos(self._roll_rad), math.sin(self._roll_rad)
        cp, sp = math.cos(self._pitch_rad), math.sin(self._pitch_rad)
        cy, sy = math.cos(self._yaw_rad), math.sin(self._yaw_rad)
        zb_n, zb_e, zb_d = cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr
        c = pr.drag_per_s
        v, p = self._v, self._p
        a = [
            -thrust * zb_n - c * (v[0] - wind[0]),
            -thrust * zb_e - c * (v[1] - wind[1]),
            -thrust * zb_d + G_MPS2 - c * (v[2] - wind[2]),
        ]
        if self._on_ground and a[2] >= 0.0:
            a = [0.0, 0.0, 0.0]  # resting on the ground: friction holds it (to the ground's own motion)
            v[0], v[1] = self.ground_vel_ne_mps
        # v ← v + a dt,  p ← p + v dt
        v[0] += a[0] * dt_s
        v[1] += a[1] * dt_s
        v[2] += a[2] * dt_s
        p[0] += v[0] * dt_s
        p[1] += v[1] * dt_s
        p[2] += v[2] * dt_s
        if self._p[2] >= self.ground_down_m:
            self._p[2] = self.ground_down_m
            if self._v[2] >= 0.0:
                self._v = [self.ground_vel_ne_mps[0], self.ground_vel_ne_mps[1], 0.0]
                a = [0.0, 0.0, 0.0]
                self._on_ground = True
        else:
            self._on_ground = False
        self._a = a
        self._rates = (
            (self._roll_rad - roll0) / dt_s,
            (self._pitch_rad - pitch0) / dt_s,
            wrap_pi(self._yaw_rad - yaw0) / dt_s,
        )
        self.battery.step(dt_s, thrust, control.motors_on, armed)
        self._moved()
