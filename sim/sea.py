"""The sea the simulator flies over: current, waves, and a small object floating on them.

One world model serves the camera renderer, the radar emulator and the evaluation (ground truth), through a
small query interface: :meth:`SeaWorld.surface_elevation_m` and :meth:`FloatingObject.state` / ``states``.

Frames and units: local NED metres with the mean sea surface at down = 0; ``t_s`` is simulation time in
seconds (the object's mean position is ``start_ne_m`` at t = 0). Directions in degrees clockwise from north:
the current the oceanographic way (``current_to_deg``: where the water flows *to*), waves and wind the
meteorological way (``*_from_deg``: where they come *from*).

Waves: linear, deep water, the seeded components of :mod:`sim.sea_spectrum` (k̂ = k/|k|), carried by the
current — they are the still-water waves in the water's frame, which moves by D(t) = ∫₀ᵗ U dt::

    η(t, x)   = Σ a cos θ,          θ = ω t − k·(x − D(t)) + φ    surface height, positive up
    u(t, x)   = Σ a ω cos θ · k̂                                  horizontal orbital velocity at the surface
    w_d(t, x) = Σ a ω sin θ                                        vertical (a water particle's), positive down

A sensor hovering at x sees the waves at ω + k·U (Doppler); what drifts with the water sees them at ω. (Before
2026-12-03 the waves stood still while the current carried the object through them: it met each at ω − k·U,
which no uniform current does — a current is a moving frame — and the short waves against the current came up
to a quarter faster.)

Current: steady ``U0`` plus a slow seeded variation, three sinusoids per axis with periods around
``current_period_s`` and RMS magnitude σ = ``current_variation_mps``::

    U(t) = U0 + b Σ_m [cos(Ω_m t + φ_m,n), cos(Ω_m t + φ_m,e)],    b = σ/√3

Floating object: small compared with the waves, so it follows the surface — first-order Lagrangian motion
about a mean position that drifts with the current and a little windage (w = windage · wind)::

    x̄(t) = x0 + D(t) + w t (+ downwash offset)          mean position, closed form
    θ(t) = ω t − k·(x̄(t) − D(t)) + φ                   phase the object sees (θ̇ = ω − k·(w + push): it meets
                                                         the waves only as fast as it moves through the water)
    p_ne = x̄ + Σ a sin θ · k̂                            surge/sway on the orbit
    p_d  = −Σ a cos θ = −η(t, x̄)                        heave

Velocity and acceleration are the exact time derivatives of these expressions. Not modelled: Stokes drift
(second order; Σ a² ω k is ~5, 8, 11, 15 cm/s along the waves at the surface in sea states 2–5), a current
that varies in space (refraction, the waves steepening against it), the hull filtering waves shorter than
itself (``diameter_m`` is for the renderer and the radar). Deterministic for a seed; no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from app.estimators.sea_state import SEA_STATES, SeaState  # one sea-state table for the app and the sim
from sim.sea_spectrum import (
    GRAVITY_MPS2,
    HORIZONTAL,
    TWO_PI,
    VERTICAL,
    FloatArray,
    PhaseTrig,
    WaveComponents,
    WaveSums,
    jonswap,
    no_components,
    pierson_moskowitz,
    row_blocks,
    synthesise_components,
)

__all__ = [
    "GRAVITY_MPS2",
    "SEA_STATES",
    "FloatingObject",
    "ObjectTruth",
    "SeaConfig",
    "SeaState",
    "SeaWorld",
    "WaveComponents",
    "downwash_velocity_ne_mps",
]

Vec3 = tuple[float, float, float]
_CURRENT_TERMS = 3

# Rotor downwash on the water: a radial wall jet under a low vehicle.
DOWNWASH_MAX_HEIGHT_M = 3.0  # no push when the vehicle is higher above the object
DOWNWASH_RADIUS_M = 1.5  # nor when it is further to the side
DOWNWASH_CORE_RADIUS_M = 0.25  # right under the rotors the flow turns outward: the push grows from 0 on the axis
DOWNWASH_SPEED_AT_1M_MPS = 0.3  # outward surface speed with the vehicle 1 m above


@dataclass(frozen=True, slots=True)
class SeaConfig:
    """Sea, current and wind parameters (waves and wind *from*, current *to*; degrees from north)."""

    sea_state: int = 3  # WMO code 0–5, see SEA_STATES
    spectrum: Literal["pm", "jonswap"] = "pm"
    jonswap_gamma: float = 3.3  # peak enhancement
    wave_from_deg: float = 240.0  # mean direction the waves come from
    spread_s: float = 4.0  # cos-2s spreading exponent (larger: longer crests)
    n_frequencies: int = 48
    n_directions: int = 7
    omega_min_over_peak: float = 0.5  # band of the components, multiples of ωp
    omega_max_over_peak: float = 3.5
    current_mps: float = 0.3
    current_to_deg: float = 60.0
    current_variation_mps: float = 0.05  # RMS magnitude of the slow variation
    current_period_s: float = 600.0  # typical period of the variation
    wind_mps: float = 5.0
    wind_from_deg: float = 240.0
    windage: float = 0.02  # fraction of the wind speed the object drifts at

    def __post_init__(self) -> None:
        if self.sea_state not in SEA_STATES:
            raise ValueError(f"sea_state must be a WMO code 0–5, got {self.sea_state}")
        if self.spectrum not in ("pm", "jonswap"):
            raise ValueError(f"spectrum must be 'pm' or 'jonswap', got {self.spectrum!r}")
        if self.n_frequencies < 1 or self.n_directions < 1:
            raise ValueError("n_frequencies and n_directions must be at least 1")
        if not 0.0 < self.omega_min_over_peak < self.omega_max_over_peak:
            raise ValueError("need 0 < omega_min_over_peak < omega_max_over_peak")
        if self.jonswap_gamma < 1.0 or self.spread_s < 0.0 or self.current_period_s <= 0.0:
            raise ValueError("need jonswap_gamma >= 1, spread_s >= 0, current_period_s > 0")


class SeaWorld:
    """Waves and current for one seed: surface height, orbital velocity and current at any time and place."""

    def __init__(self, config: SeaConfig | None = None, seed: int = 0) -> None:
        self.config = config if config is not None else SeaConfig()
        self.seed = seed
        self.sea_state: SeaState = SEA_STATES[self.config.sea_state]
        c = self.config
        wave_seed, current_seed = np.random.SeedSequence(seed).spawn(2)
        if self.sea_state.hs_m > 0.0:
            omega_p = self.peak_omega_radps
            self.components = synthesise_components(
                self.spectrum,
                (c.omega_min_over_peak * omega_p, c.omega_max_over_peak * omega_p),
                c.n_frequencies,
                c.n_directions,
                c.spread_s,
                math.radians(c.wave_from_deg + 180.0),
                np.random.default_rng(wave_seed),
            )
        else:
            self.components = no_components()
        w = self.components
        # θ = [t, n, e, 1] @ phase_matrix  =  ω t − k_n n − k_e e + φ, (n, e) in the water's frame (x − D(t))
        self._phase_matrix = np.stack([w.omega_radps, -w.k_north, -w.k_east, w.phase_rad])
        # a ω k̂ and a ω: the weights of the orbital velocity
        a_omega = w.amplitude_m * w.omega_radps
        k = np.hypot(w.k_north, w.k_east)
        self._velocity_weights = np.stack([a_omega * w.k_north / k, a_omega * w.k_east / k, a_omega], axis=1)

        rng = np.random.default_rng(current_seed)
        to_rad = math.radians(c.current_to_deg)
        self._current_steady_ne_mps = np.array([c.current_mps * math.cos(to_rad), c.current_mps * math.sin(to_rad)])
        self._current_b_mps = c.current_variation_mps / math.sqrt(_CURRENT_TERMS)
        self._current_omega_radps = TWO_PI / (c.current_period_s * rng.uniform(0.6, 1.6, _CURRENT_TERMS))
        self._current_phase_rad = rng.uniform(0.0, TWO_PI, (_CURRENT_TERMS, 2))
        # the constant factors of _current_ne's sums (terms × axis)
        cos_phase, sin_phase = np.cos(self._current_phase_rad), np.sin(self._current_phase_rad)
        omega = self._current_omega_radps[:, None]
        self._current_cos_sin_phase = (cos_phase, sin_phase)
        self._current_phase_over_omega = (cos_phase / omega, sin_phase / omega, np.sum(sin_phase / omega, axis=0))
        self._current_phase_times_omega = (cos_phase * omega, sin_phase * omega)
        self._trig_one = PhaseTrig(self._phase_matrix, 1)  # for one place and time (work arrays reused)
        # the same, as floats for current_one
        self._current_steady_one = (float(self._current_steady_ne_mps[0]), float(self._current_steady_ne_mps[1]))
        self._current_omega_one = [float(w) for w in self._current_omega_radps]
        self._current_phase_one = [
            (tuple(cos.tolist()), tuple(sin.tolist())) for cos, sin in zip(cos_phase, sin_phase, strict=True)
        ]
        from_rad = math.radians(c.wind_from_deg)
        self.windage_drift_ned_mps: Vec3 = (
            -c.windage * c.wind_mps * math.cos(from_rad),
            -c.windage * c.wind_mps * math.sin(from_rad),
            0.0,
        )

    @property
    def peak_omega_radps(self) -> float:
        """ωp = 2π/Tp of the sea state (0 for a glassy sea)."""
        tp_s = self.sea_state.tp_s
        return TWO_PI / tp_s if tp_s > 0.0 else 0.0

    @property
    def significant_wave_height_m(self) -> float:
        """Hs = 4 √m0 of the components (m0 = Σ a²/2)."""
        return 4.0 * math.sqrt(0.5 * float(np.sum(self.components.amplitude_m**2)))

    def spectrum(self, omega_radps: ArrayLike) -> FloatArray:
        """The one-sided target spectrum S(ω) the components were drawn from, m²·s/rad."""
        s = self.sea_state
        if self.config.spectrum == "jonswap":
            return jonswap(omega_radps, s.hs_m, s.tp_s, self.config.jonswap_gamma)
        return pierson_moskowitz(omega_radps, s.hs_m, s.tp_s)

    def surface_elevation_m(self, t_s: ArrayLike, north_m: ArrayLike, east_m: ArrayLike) -> float | FloatArray:
        """η, metres positive up, at (t, north, east); the arguments broadcast, scalars give a float."""
        rows, shape = self._phase_rows(t_s, north_m, east_m)
        eta = np.empty(len(rows))
        cos_sin = self._phase_trig(len(rows))
        for sl in row_blocks(len(rows)):
            # η = Σ a cos θ
            cos, _ = cos_sin(rows[sl])
            eta[sl] = cos @ self.components.amplitude_m
        return float(eta[0]) if shape == () else eta.reshape(shape)

    def surface_velocity_ned_mps(self, t_s: ArrayLike, north_m: ArrayLike, east_m: ArrayLike) -> FloatArray:
        """Orbital velocity of the water at the surface, NED m/s, shape ``broadcast(...) + (3,)``."""
        rows, shape = self._phase_rows(t_s, north_m, east_m)
        v = np.empty((len(rows), 3))
        cos_sin = self._phase_trig(len(rows))
        for sl in row_blocks(len(rows)):
            cos, sin = cos_sin(rows[sl])
            # u = Σ a ω cos θ k̂;   w_d = −∂η/∂t = Σ a ω sin θ
            v[sl, :2] = cos @ self._velocity_weights[:, :2]
            v[sl, 2] = sin @ self._velocity_weights[:, 2]
        return v.reshape((*shape, 3))

    def current_ned_mps(self, t_s: ArrayLike) -> FloatArray:
        """Current (water velocity, horizontal), NED m/s, shape ``shape(t_s) + (3,)``."""
        t = np.asarray(t_s, dtype=np.float64)
        _, vel_ne, _ = self._current_ne(t.ravel())
        return np.concatenate([vel_ne, np.zeros((t.size, 1))], axis=1).reshape((*t.shape, 3))

    def water_displacement_ne_m(self, t_s: ArrayLike) -> FloatArray:
        """D(t) = ∫₀ᵗ U dt: how far the current has carried the water (and its waves) since t = 0, north and
        east, m, shape ``shape(t_s) + (2,)``."""
        t = np.asarray(t_s, dtype=np.float64)
        return self._current_ne(t.ravel())[0].reshape((*t.shape, 2))

    def _phase_trig(self, n_rows: int) -> PhaseTrig:
        return self._trig_one if n_rows == 1 else PhaseTrig(self._phase_matrix, n_rows)

    def _phase_rows(self, t_s: ArrayLike, north_m: ArrayLike, east_m: ArrayLike) -> tuple[FloatArray, tuple[int, ...]]:
        """The rows [t, n − D_n(t), e − D_e(t), 1] of the phases at (t, north, east): each place in the water's
        frame, which the current has carried D(t) = ∫₀ᵗ U dt; and the broadcast shape (() for one point)."""
        if isinstance(t_s, float) and isinstance(north_m, float) and isinstance(east_m, float):  # one point
            (dn, de), _, _ = self.current_one(t_s)
            return np.array([[t_s, north_m - dn, east_m - de, 1.0]]), ()
        t, n, e = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (t_s, north_m, east_m)))
        if np.ndim(t_s) == 0:  # one time (a grid of places): the current's displacement once
            (dn, de), _, _ = self.current_one(float(t_s))  # type: ignore[arg-type]
            return np.stack([t.ravel(), n.ravel() - dn, e.ravel() - de, np.ones(t.size)], axis=1), t.shape
        d = self.water_displacement_ne_m(t.ravel())
        return np.stack([t.ravel(), n.ravel() - d[:, 0], e.ravel() - d[:, 1], np.ones(t.size)], axis=1), t.shape

    def current_one(self, t_s: float) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
        """``_current_ne`` at one time, in floats: ∫₀ᵗ U dt, U(t) and dU/dt, each (north, east)."""
        b = self._current_b_mps
        u0n, u0e = self._current_steady_one
        integral, velocity, acceleration = [u0n * t_s, u0e * t_s], [u0n, u0e], [0.0, 0.0]
        for omega, (cos_phase, sin_phase) in zip(self._current_omega_one, self._current_phase_one, strict=True):
            cos_wt, sin_wt = math.cos(omega * t_s), math.sin(omega * t_s)
            for axis in (0, 1):
                cos_p, sin_p = cos_phase[axis], sin_phase[axis]
                # cos(Ωt + φ);  ∫₀ᵗ: (sin(Ωt + φ) − sin φ)/Ω;  d/dt: −Ω sin(Ωt + φ)
                velocity[axis] += b * (cos_wt * cos_p - sin_wt * sin_p)
                integral[axis] += b * ((sin_wt * cos_p + cos_wt * sin_p) - sin_p) / omega
                acceleration[axis] -= b * omega * (sin_wt * cos_p + cos_wt * sin_p)
        return (integral[0], integral[1]), (velocity[0], velocity[1]), (acceleration[0], acceleration[1])

    def _current_ne(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """∫₀ᵗ U dt, U(t) and dU/dt for times ``t`` (N,), each (N, 2)."""
        omega, b, u0 = self._current_omega_radps, self._current_b_mps, self._current_steady_ne_mps
        cos_phase, sin_phase = self._current_cos_sin_phase  # terms × axis
        cos_phase_over_omega, sin_phase_over_omega, sum_sin_phase_over_omega = self._current_phase_over_omega
        cos_phase_omega, sin_phase_omega = self._current_phase_times_omega
        cos_wt, sin_wt = np.cos(np.outer(t, omega)), np.sin(np.outer(t, omega))  # N × terms
        # Σ cos(Ω t + φ) = cos Ωt · cos φ − sin Ωt · sin φ
        velocity = u0 + b * (cos_wt @ cos_phase - sin_wt @ sin_phase)
        # ∫₀ᵗ cos(Ω t + φ) dt = (sin(Ω t + φ) − sin φ) / Ω,   sin(Ω t + φ) = sin Ωt · cos φ + cos Ωt · sin φ
        integral = u0 * t[:, None] + b * (
            sin_wt @ cos_phase_over_omega + cos_wt @ sin_phase_over_omega - sum_sin_phase_over_omega
        )
        # d/dt cos(Ω t + φ) = −Ω sin(Ω t + φ)
        acceleration = -b * (sin_wt @ cos_phase_omega + cos_wt @ sin_phase_omega)
        return integral, velocity, acceleration


@dataclass(frozen=True, slots=True)
class ObjectTruth:
    """Where the floating object is at ``t_s`` (ground truth), NED."""

    t_s: float
    pos_ned_m: Vec3
    vel_ned_mps: Vec3
    acc_ned_mps2: Vec3


def downwash_velocity_ne_mps(object_pos_ned_m: Vec3, vehicle_pos_ned_m: Vec3) -> tuple[float, float]:
    """Outward push on the object from the rotor downwash of a vehicle at ``vehicle_pos_ned_m``, NE m/s."""
    d_north = object_pos_ned_m[0] - vehicle_pos_ned_m[0]
    d_east = object_pos_ned_m[1] - vehicle_pos_ned_m[1]
    height_m = object_pos_ned_m[2] - vehicle_pos_ned_m[2]  # vehicle above the object: positive
    rho_m = math.hypot(d_north, d_east)
    if not (0.0 < height_m < DOWNWASH_MAX_HEIGHT_M and 0.0 < rho_m < DOWNWASH_RADIUS_M):
        return (0.0, 0.0)
    # v = v₁ · min((H − h)/(H − 1 m), 1.5) · min(ρ/ρ_core, 1) · (1 − (ρ/R)²), directed away from the vehicle
    height_factor = min((DOWNWASH_MAX_HEIGHT_M - height_m) / (DOWNWASH_MAX_HEIGHT_M - 1.0), 1.5)
    radial_factor = min(rho_m / DOWNWASH_CORE_RADIUS_M, 1.0) * (1.0 - (rho_m / DOWNWASH_RADIUS_M) ** 2)
    speed_mps = DOWNWASH_SPEED_AT_1M_MPS * height_factor * radial_factor
    return (speed_mps * d_north / rho_m, speed_mps * d_east / rho_m)


class FloatingObject:
    """A small object floating on a :class:`SeaWorld`; its state at any time, in closed form."""

    def __init__(self, sea: SeaWorld, start_ne_m: tuple[float, float] = (0.0, 0.0), diameter_m: float = 0.15) -> None:
        self.sea = sea
        self.start_ne_m = start_ne_m
        self.diameter_m = diameter_m
        # Downwash pushes: the offset is piecewise linear in time (knots), its rate constant over each push.
        self._knot_t_s: list[float] = []
        self._knot_offset_ne_m: list[tuple[float, float]] = []
        self._push_start_s: list[float] = []
        self._push_end_s: list[float] = []
        self._push_rate_ne_mps: list[tuple[float, float]] = []
        # The wave sums the motion needs (see states()): each rate with the horizontal or the vertical weights.
        self._cos_sums = WaveSums(sea.components, (VERTICAL, HORIZONTAL, VERTICAL, HORIZONTAL))
        self._sin_sums = WaveSums(sea.components, (HORIZONTAL, VERTICAL, HORIZONTAL, VERTICAL))

    def state(self, t_s: float) -> ObjectTruth:
        """Position, velocity and acceleration at ``t_s``: :meth:`states`' sums for one time, in floats (the
        simulator asks at every camera frame, and numpy's per-call cost was most of it); equal to :meth:`states`'
        values within 1e-9 m (a few sums are added in another order, and the float32 phase rounds with them)."""
        sea = self.sea
        (cn, ce), (un, ue), (an, ae) = sea.current_one(t_s)
        # through the water (the waves' frame): x0 + w t + push, at w + push rate
        vn, ve = sea.windage_drift_ned_mps[0], sea.windage_drift_ned_mps[1]
        rn, re = self.start_ne_m[0] + vn * t_s, self.start_ne_m[1] + ve * t_s
        if self._push_start_s:
            push, rate = self._push(np.array([t_s], dtype=np.float64))
            rn, re = rn + float(push[0, 0]), re + float(push[0, 1])
            vn, ve = vn + float(rate[0, 0]), ve + float(rate[0, 1])
        # x̄ = x0 + D + w t + push;  θ = ω t − k·(x̄ − D) + φ, its rate ω − k·(w + push rate), its own rate 0
        mn, me = rn + cn, re + ce
        cos, sin = sea._trig_one(np.array([[t_s, rn, re, 1.0]]))
        monomials = ((1.0,), (1.0, vn, ve), (1.0, vn, ve, vn * vn, vn * ve, ve * ve), (0.0, 0.0))
        cos_1, cos_rate, cos_rate_sq, cos_accel = self._cos_sums.one(cos, monomials)
        sin_1, sin_rate, sin_rate_sq, sin_accel = self._sin_sums.one(sin, monomials)
        return ObjectTruth(
            t_s=t_s,
            pos_ned_m=(mn + sin_1[0], me + sin_1[1], -cos_1[0]),
            vel_ned_mps=(un + vn + cos_rate[0], ue + ve + cos_rate[1], sin_rate[0]),
            acc_ned_mps2=(
                an + (cos_accel[0] - sin_rate_sq[0]),
                ae + (cos_accel[1] - sin_rate_sq[1]),
                cos_rate_sq[0] + sin_accel[0],
            ),
        )

    def states(self, t_s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position, velocity and acceleration at the times ``t_s`` (N,), each (N, 3), NED."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        sea = self.sea
        current_ne, current_vel_ne, current_acc_ne = sea._current_ne(t)
        windage_ne = np.array(sea.windage_drift_ned_mps[:2])
        push_ne, push_rate_ne = self._push(t)
        # through the water (the waves' frame): x0 + w t + push, at w + push rate;  x̄ = that + D
        water_ne = np.array(self.start_ne_m) + windage_ne * t[:, None] + push_ne
        water_vel_ne = windage_ne + push_rate_ne
        mean_ne = water_ne + current_ne
        mean_vel_ne = current_vel_ne + water_vel_ne
        mean_acc_ne = current_acc_ne

        pos, vel, acc = np.zeros((len(t), 3)), np.zeros((len(t), 3)), np.zeros((len(t), 3))
        pos[:, :2], vel[:, :2], acc[:, :2] = mean_ne, mean_vel_ne, mean_acc_ne
        cos_sin = sea._phase_trig(len(t))
        for sl in row_blocks(len(t)):
            # θ = ω t − k·(x̄ − D) + φ;  θ̇ = ω − k·(w + push rate);  θ̈ = 0
            cos, sin = cos_sin(np.column_stack([t[sl], water_ne[sl], np.ones(len(t[sl]))]))
            monomials = WaveSums.monomials(water_vel_ne[sl], np.zeros_like(water_vel_ne[sl]))
            # [Σ a cos θ, Σ a k̂ cos θ θ̇, Σ a cos θ θ̇², Σ a k̂ cos θ θ̈]
            cos_1, cos_rate, cos_rate_sq, cos_accel = self._cos_sums(cos, monomials)
            # [Σ a k̂ sin θ, Σ a sin θ θ̇, Σ a k̂ sin θ θ̇², Σ a sin θ θ̈]
            sin_1, sin_rate, sin_rate_sq, sin_accel = self._sin_sums(sin, monomials)
            # p_ne = x̄ + Σ a sin θ k̂;                          p_d = −Σ a cos θ
            pos[sl, :2] += sin_1
            pos[sl, 2] = -cos_1[:, 0]
            # v_ne = dx̄/dt + Σ a cos θ θ̇ k̂;                    v_d = Σ a sin θ θ̇
            vel[sl, :2] += cos_rate
            vel[sl, 2] = sin_rate[:, 0]
            # a_ne = d²x̄/dt² + Σ a (cos θ θ̈ − sin θ θ̇²) k̂;     a_d = Σ a (cos θ θ̇² + sin θ θ̈)
            acc[sl, :2] += cos_accel - sin_rate_sq
            acc[sl, 2] = cos_rate_sq[:, 0] + sin_accel[:, 0]
        return pos, vel, acc

    def push_downwash(self, t_s: float, dt_s: float, vehicle_pos_ned_m: Vec3) -> None:
        """Let the downwash of a vehicle at ``vehicle_pos_ned_m`` push the object during [t, t + dt].

        The push rate is taken at ``t_s`` and held for ``dt_s``; :meth:`state` includes it from then on.
        Raises ValueError when a push starts before the previous one ended (pushes come in time order).
        """
        if dt_s <= 0.0:
            return
        if self._push_end_s and t_s < self._push_end_s[-1] - 1e-9:
            raise ValueError(f"downwash push at t={t_s} s starts before the previous one ended")
        rate_ne = downwash_velocity_ne_mps(self.state(t_s).pos_ned_m, vehicle_pos_ned_m)
        if rate_ne == (0.0, 0.0):
            return
        offset_ne = self._knot_offset_ne_m[-1] if self._knot_offset_ne_m else (0.0, 0.0)
        if not self._knot_t_s or t_s > self._knot_t_s[-1]:
            self._knot_t_s.append(t_s)
            self._knot_offset_ne_m.append(offset_ne)
        self._knot_t_s.append(t_s + dt_s)
        self._knot_offset_ne_m.append((offset_ne[0] + rate_ne[0] * dt_s, offset_ne[1] + rate_ne[1] * dt_s))
        self._push_start_s.append(t_s)
        self._push_end_s.append(t_s + dt_s)
        self._push_rate_ne_mps.append(rate_ne)

    def _push(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Downwash offset and its rate at the times ``t``, each (N, 2)."""
        if not self._push_start_s:
            return np.zeros((len(t), 2)), np.zeros((len(t), 2))
        knot_t, knot_offset = np.array(self._knot_t_s), np.array(self._knot_offset_ne_m)
        offset = np.stack([np.interp(t, knot_t, knot_offset[:, 0]), np.interp(t, knot_t, knot_offset[:, 1])], axis=1)
        i = np.searchsorted(np.array(self._push_start_s), t, side="right") - 1
        i_valid = np.clip(i, 0, None)
        pushing = (i >= 0) & (t < np.array(self._push_end_s)[i_valid])
        rate = np.where(pushing[:, None], np.array(self._push_rate_ne_mps)[i_valid], 0.0)
        return offset, rate
