"""Airframes calibrated against real autopilot firmware answering our velocity setpoints.

The recordings (``tests/data/autopilot_response/``, from ``shared/reference/autopilot-response/``) are PX4
(SIH physics) and ArduCopter (SITL ``quad``) flying one setpoint script through MAVSDK offboard velocity
setpoints. ``tests/sim/test_autopilot_response.py`` replays that script through ``sim.dynamics`` and checks
the velocity against each recording.

- ``PX4_SIH``: PX4's own velocity PID with its default gains (``MultirotorParams`` defaults:
  MPC_XY_VEL_P/I/D_ACC 1.8 / 0.4 / 0.2, MPC_Z_VEL_P/I_ACC 4 / 2) on SIH's plant with linear drag
  k = SIH_KDV / SIH_MASS = 1 s⁻¹, tilt-limited at MPC_TILT_MAX_AIR 45°. No free parameter; RMS residual
  0.057 / 0.072 / 0.042 m/s (n / e / d).
- ``ARDUCOPTER``: ArduCopter's GUIDED velocity control with its 4.x defaults (``sim.poscontrol``): the
  setpoint is shaped into a jerk-limited trajectory (PSC_JERK_XY 5 m/s³, WPNAV_ACCEL 2.5 m/s²; Z 5 / 1)
  integrated into a position target, tracked by PSC_POSXY_P 1 and the velocity PID PSC_VELXY_P/I 2 / 1
  (D 0: ArduCopter's D acts on the velocity error, which the acceleration feed-forward keeps small; ours
  would act on the whole measured acceleration). No fitted parameter; RMS residual 0.028 / 0.024 /
  0.020 m/s, below the README's delay + double-lag fit (0.030 / 0.038 / 0.025). The circle mission flown
  on it (in process, calm, perfect estimate) tracks at p95 0.0085 m; real ArduCopter SITL gave 0.012 m.
- ``PX4``: PX4's velocity PID as in ``PX4_SIH`` on a real airframe's drag (0.3 s⁻¹: EKF2_MCOEF's 0.15 s⁻¹
  rotor drag plus body drag), tilt-limited at MPC_TILT_MAX_AIR 45°.
- ``DEFAULT``: what the simulator flew before calibration (``MultirotorParams()``: the same PID, tilt 35°).

``SIM_PROFILES`` pairs each with the estimator error it reports (``sim.estimator``); ``default_for`` is
what a simulated PX4 or ArduPilot flies unless told otherwise (``px4`` and ``ardupilot``).
"""

from __future__ import annotations

from dataclasses import dataclass

from sim import estimator
from sim.autopilot_modes import Profile
from sim.estimator import EstimatorErrorParams
from sim.multirotor import MultirotorParams
from sim.poscontrol import PosControlParams

DEFAULT = MultirotorParams()
PX4 = MultirotorParams(tilt_max_deg=45.0)
PX4_SIH = MultirotorParams(drag_per_s=1.0, tilt_max_deg=45.0)
ARDUCOPTER = MultirotorParams(
    xy_vel_p_acc=2.0,
    xy_vel_i_acc=1.0,
    xy_vel_d_acc=0.0,
    z_vel_p_acc=5.0,
    z_vel_i_acc=2.0,
    pos_control=PosControlParams(),
)


@dataclass(frozen=True, slots=True)
class SimProfile:
    """What ``--sim-profile`` selects: the MAVLink dialect, the airframe and the estimator error."""

    autopilot: Profile
    airframe: MultirotorParams
    estimator: EstimatorErrorParams


SIM_PROFILES: dict[str, SimProfile] = {
    "px4": SimProfile(Profile.PX4, PX4, estimator.GNSS),
    "px4-sih": SimProfile(Profile.PX4, PX4_SIH, estimator.PX4_SIH),
    "ardupilot": SimProfile(Profile.ARDUPILOT, ARDUCOPTER, estimator.GNSS),
}


def default_for(autopilot: Profile) -> SimProfile:
    """The calibrated profile a simulated ``autopilot`` flies unless told otherwise."""
    return SIM_PROFILES["ardupilot" if autopilot is Profile.ARDUPILOT else "px4"]
