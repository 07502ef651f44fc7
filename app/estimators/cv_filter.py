"""The thesis's constant-velocity target filter (§4.2.4, Listing 4.1), kept as the baseline. Pure.

State (eq. 4.12):  x = [p_N, p_E, v_N, v_E]ᵀ   (m, m, m/s, m/s)

    F(dt) = [[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]]      (4.13)
    H     = [[1, 0, 0, 0], [0, 1, 0, 0]]                                    (4.14a)
    Q(dt) = diag(q_p, q_p, q_v, q_v) · dt       (the thesis's diagonal Q per step, made rate-independent)
    x₀    = [z_N, z_E, 0, 0],  P₀ = diag(R_NN, R_EE, σ²_v0, σ²_v0)           (initialised at the first fix)

Listing 4.1 per step: P⁻ = F P Fᵀ + Q;  S = R + H P⁻ Hᵀ;  K = P⁻ Hᵀ S⁻¹;  P = P⁻ − K H P⁻;  x = F x + K(z − H·).
A step without a fix is prediction only (the thesis's H = 0). One deliberate difference: Listing 4.1
writes the innovation as z − H x with the *previous* x; here it is z − H F x (the predicted state, as in
every textbook Kalman filter). The two agree whenever the velocity is zero — as on the first update.
The innovation gate of ``LinearTargetFilter`` is on by default; the thesis had none (``innovation_gate=False``
reproduces Listing 4.1, which fuses every fix).
"""

from __future__ import annotations

import numpy as np

from app.estimators.target_filter import Array, LinearTargetFilter


class ConstantVelocityFilter(LinearTargetFilter):
    name = "constant_velocity"

    def __init__(
        self,
        q_pos_m2ps: float = 0.01,
        q_vel_m2ps3: float = 0.05,
        initial_vel_std_mps: float = 1.0,
        timeout_s: float = 3.0,
        replay_window_s: float = 1.0,
        innovation_gate: bool = True,
    ) -> None:
        super().__init__(timeout_s, replay_window_s, innovation_gate)
        self.q_pos_m2ps = q_pos_m2ps
        self.q_vel_m2ps3 = q_vel_m2ps3
        self.initial_vel_std_mps = initial_vel_std_mps
        self._H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])

    def F(self, dt_s: float) -> Array:
        return np.array([[1.0, 0.0, dt_s, 0.0], [0.0, 1.0, 0.0, dt_s], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])

    def Q(self, dt_s: float) -> Array:
        q = self.q_pos_m2ps, self.q_pos_m2ps, self.q_vel_m2ps3, self.q_vel_m2ps3
        return np.diag(q) * dt_s

    @property
    def H(self) -> Array:
        return self._H

    def initial_state(self, z: Array, R: Array) -> tuple[Array, Array]:
        x = np.array([z[0], z[1], 0.0, 0.0])
        P = np.zeros((4, 4))
        P[:2, :2] = R
        P[2, 2] = P[3, 3] = self.initial_vel_std_mps**2
        return x, P

    def velocity_acceleration(self, x: Array) -> tuple[Array, Array]:
        return x[2:4].copy(), np.zeros(2)
