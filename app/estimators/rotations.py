"""Rotations between NED, body (FRD) and camera frames: Euler ZYX, quaternions, slerp. Pure.

``R_a_b`` rotates vectors from frame b into frame a (the thesis's R_b^a): ``v_a = R_a_b @ v_b``.
Euler angles are ZYX (yaw ψ, pitch θ, roll φ) — thesis eq. 4.5 — so ``R = Rz(ψ) Ry(θ) Rx(φ)``.
Quaternions are ``(w, x, y, z)`` with ``w ≥ 0`` not enforced; ``q_a_b`` rotates b into a like ``R_a_b``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
Quat = tuple[float, float, float, float]


def rot_x(phi_rad: float) -> FloatArray:
    """Eq. 4.6c."""
    c, s = math.cos(phi_rad), math.sin(phi_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(theta_rad: float) -> FloatArray:
    """Eq. 4.6b."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(psi_rad: float) -> FloatArray:
    """Eq. 4.6a (with the 1 in the corner the thesis's print dropped)."""
    c, s = math.cos(psi_rad), math.sin(psi_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_zyx_to_matrix(roll_rad: float, pitch_rad: float, yaw_rad: float) -> FloatArray:
    """Eq. 4.5: R = Rz(ψ) Ry(θ) Rx(φ)."""
    return rot_z(yaw_rad) @ rot_y(pitch_rad) @ rot_x(roll_rad)


def quat_from_euler_zyx(roll_rad: float, pitch_rad: float, yaw_rad: float) -> Quat:
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat_to_euler_zyx(q: ArrayLike) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in rad of a unit quaternion; pitch clamped at ±90°."""
    w, x, y, z = (float(c) for c in np.asarray(q, dtype=np.float64))
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def quat_to_matrix(q: ArrayLike) -> FloatArray:
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_slerp(q0: Iterable[float], q1: Iterable[float], f: float) -> Quat:
    """Spherical linear interpolation, ``f`` ∈ [0, 1], along the shorter arc (q and −q are one rotation). In
    floats: the state history slerps at every read, and numpy's per-call cost was most of it for 4 numbers."""
    a, b = _unit4(q0), _unit4(q1)
    dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
    if dot < 0.0:  # the shorter way round
        b, dot = (-b[0], -b[1], -b[2], -b[3]), -dot
    if dot > 0.9995:  # nearly parallel: lerp is exact to ~1e-7 and avoids 0/0
        q = tuple(x + f * (y - x) for x, y in zip(a, b, strict=True))
    else:
        omega = math.acos(dot)
        sin_omega = math.sin(omega)
        wa, wb = math.sin((1 - f) * omega), math.sin(f * omega)
        q = tuple((wa * x + wb * y) / sin_omega for x, y in zip(a, b, strict=True))
    return _unit4(q)


def _unit4(q: Iterable[float]) -> tuple[float, float, float, float]:
    w, x, y, z = (float(c) for c in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


def skew(v: ArrayLike) -> FloatArray:
    """[v]×, so that ``skew(a) @ b == cross(a, b)``."""
    x, y, z = np.asarray(v, dtype=np.float64)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
