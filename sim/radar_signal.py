"""What the X4M03 would measure over the simulated sea: complex baseband frames, and the truth behind them.

Model (``reference/x4m03-protocol.md`` §10; [A] marks its assumptions). A reflector at range R adds
``a · exp(−(r − R)²/(2σ_r²)) · exp(−j 4π f_c R / c + jφ)`` to bin r (Gaussian pulse, σ_r ≈ 0.055 m).

Sea echo, per frame, from the sea world's surface under the antenna:

- large scale: η and its slope ∇η at the antenna's nadir (``SeaWorld``); the surface is a tilted plane
  there; H = antenna height above it; specular range R₀ = H/√(1 + |∇η|²) (heave and wave slope);
- small scale (waves shorter than the sea world resolves, ripples) [A]: rms height σ_s (the spectrum's tail
  beyond its last component, plus 0.5 mm) and mean-square slope s² (half Cox–Munk for the PM wind of the
  sea state). Coherent fraction ρ = exp(−2(k σ_s)²), k = 2π/λ: calm water is a mirror, any real sea fades;
- amplitude a(H) = A₁ (1 m/H)ⁿ (|Γ|/0.79), n from 1 (calm) to 1.5 (rough) with 1 − ρ² [A: A₁ = 0.02];
  power ρ² of it in one specular return at R₀, the rest spread over ``facets`` glints drawn from the
  slope distribution (geometric optics), each at its own range (longer off nadir, ± its small-scale
  height) with a random phase: Rayleigh fading and range speckle emerge from the sum;
- antenna: every return weighted by the two-way amplitude pattern exp(−ln2 (α/α_h)²), α its angle off
  the boresight (body down axis) — the tilt loss; α_h = 35° [A].

Static part (the same every frame, what a background map removes): direct-path coupling
0.029·exp(−(r − 0.334)/0.09) plus a 3e-4 floor, random fixed phase per bin; optional drone-body
reflections (landing gear, gripper) as pulses at fixed ranges. Per frame it jitters by 0.5 % (measured on
the Novelda sample). Thermal noise σ = 1.8e-5 per I and per Q.

Truth: the height of the vehicle's reference point above the instantaneous sea surface under it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import integrate

from app.messages import RangeAxis
from sim.radar_track import Pose, VehicleTrack, rotation_body_to_ned
from sim.sea import SeaWorld

C_MPS = 299_792_458.0
FLAT_SEA_GAMMA = 0.79  # |Γ| of seawater at 7.29 GHz (Debye model, reference §10.4)
CAPILLARY_RMS_M = 0.0005
SLOPE_STEP_M = 0.25  # finite-difference step for the large-scale slope under the antenna


@dataclass(frozen=True, slots=True)
class RadarSignalConfig:
    fc_hz: float = 7.29e9
    pulse_sigma_m: float = 0.055
    noise_std: float = 1.8e-5  # per I and per Q
    echo_at_1m: float = 0.02  # A₁: flat sea at 1 m [A]
    exponent_calm: float = 1.0
    exponent_rough: float = 1.5
    reflection_coeff: float = FLAT_SEA_GAMMA
    beam_half_power_deg: float = 35.0  # [A]
    facets: int = 32
    direct_path: float = 0.029
    direct_path_decay_m: float = 0.09
    direct_path_at_m: float = 0.334
    clutter_floor: float = 3e-4
    jitter_fraction: float = 0.005
    body_reflections: tuple[tuple[float, float], ...] = ((0.45, 0.004), (0.62, 0.002))  # (range m, amplitude)
    antenna_offset_frd_m: tuple[float, float, float] = (0.05, 0.0, 0.08)  # from the reference point
    small_scale_rms_m: float | None = None  # None: from the sea state
    mean_square_slope: float | None = None  # None: from the sea state


@dataclass(frozen=True, slots=True)
class RadarTruth:
    t_s: float
    height_m: float  # reference point above the instantaneous sea surface under it
    antenna_height_m: float  # antenna above the (locally plane) surface under it
    specular_range_m: float
    pose: Pose


def small_scale_roughness(sea: SeaWorld) -> tuple[float, float]:
    """(rms height m, mean-square slope) of the waves the sea world does not resolve [A]."""
    s = sea.sea_state
    if s.hs_m <= 0.0:
        return CAPILLARY_RMS_M, 0.001
    omega_max = sea.config.omega_max_over_peak * sea.peak_omega_radps
    tail_m2, _ = integrate.quad(lambda w: float(sea.spectrum(w)), omega_max, 20.0 * omega_max)
    wind_mps = math.sqrt(s.hs_m * 9.80665 / 0.21)  # fully developed PM sea: Hs = 0.21 U²/g
    return math.hypot(math.sqrt(tail_m2), CAPILLARY_RMS_M), 0.5 * (0.003 + 5.12e-3 * wind_mps)


class SeaRadarScene:
    """Frames and truth for one sea, one vehicle track and one seed (deterministic, no clock)."""

    def __init__(
        self, sea: SeaWorld, track: VehicleTrack, config: RadarSignalConfig | None = None, seed: int = 0
    ) -> None:
        self.sea = sea
        self.track = track
        self.config = c = config if config is not None else RadarSignalConfig()
        self._rng = np.random.default_rng(np.random.SeedSequence([seed, 0x4AD]))
        rms_m, mss = small_scale_roughness(sea)
        self.small_scale_rms_m = c.small_scale_rms_m if c.small_scale_rms_m is not None else rms_m
        self.mean_square_slope = c.mean_square_slope if c.mean_square_slope is not None else mss
        k = 2.0 * math.pi * c.fc_hz / C_MPS
        # ρ = exp(−2(k σ_s)²): the coherent (mirror) share of the echo amplitude
        self.coherence = math.exp(-2.0 * (k * self.small_scale_rms_m) ** 2)
        self.exponent = c.exponent_calm + (c.exponent_rough - c.exponent_calm) * (1.0 - self.coherence**2)
        self._phase0 = self._rng.uniform(0.0, 2.0 * math.pi)
        self._static: dict[RangeAxis, np.ndarray] = {}
        self._offset_frd = np.array(c.antenna_offset_frd_m)

    # --------------------------------------------------------------------------------------------- truth

    def truth(self, t_s: float) -> RadarTruth:
        pose = self.track.pose(t_s)
        return self._geometry(pose)[0]

    def _geometry(self, pose: Pose) -> tuple[RadarTruth, np.ndarray, np.ndarray, float, np.ndarray]:
        """Truth, the antenna→surface unit vector of the specular point, boresight (both N, E, Up), R₀, R_nb."""
        r_nb = rotation_body_to_ned(pose.roll_rad, pose.pitch_rad, pose.yaw_rad)
        ref = np.array(pose.pos_ned_m)
        ant = ref + r_nb @ self._offset_frd
        d = SLOPE_STEP_M
        north = [ant[0], ant[0] + d, ant[0] - d, ant[0], ant[0], ref[0]]
        east = [ant[1], ant[1], ant[1], ant[1] + d, ant[1] - d, ref[1]]
        eta = np.asarray(self.sea.surface_elevation_m(pose.t_s, north, east), dtype=np.float64)
        gx, gy = (eta[1] - eta[2]) / (2 * d), (eta[3] - eta[4]) / (2 * d)  # ∂η/∂north, ∂η/∂east
        antenna_height_m = -ant[2] - eta[0]
        norm = math.sqrt(1.0 + gx * gx + gy * gy)
        r0_m = antenna_height_m / norm
        to_surface = np.array([gx, gy, -1.0]) / norm  # −n̂ of the plane, (N, E, Up)
        b_ned = r_nb @ np.array([0.0, 0.0, 1.0])
        boresight = np.array([b_ned[0], b_ned[1], -b_ned[2]])
        truth = RadarTruth(pose.t_s, float(-ref[2] - eta[5]), float(antenna_height_m), float(r0_m), pose)
        return truth, to_surface, boresight, r0_m, r_nb

    # ------------------------------------------------------------------------------------------- signal

    def baseband(self, t_s: float, axis: RangeAxis) -> tuple[np.ndarray, RadarTruth]:
        """The complex frame the radar measures at ``t_s`` on ``axis`` (I + jQ), and the truth then."""
        c = self.config
        truth, to_surface, boresight, r0_m, _ = self._geometry(self.track.pose(t_s))
        r = axis.ranges_m()
        frame = self._static_part(axis) * (1.0 + c.jitter_fraction * self._cn(axis.bins))
        if r0_m > 0.05:
            ranges, weights = self._returns(to_surface, boresight, r0_m)
            # a · exp(−(r − R)²/(2σ_r²)) · exp(−j 4π f_c R / c)
            pulse = np.exp(-((r[:, None] - ranges[None, :]) ** 2) / (2.0 * c.pulse_sigma_m**2))
            frame = frame + pulse @ (weights * np.exp(-1j * 4.0 * math.pi * c.fc_hz * ranges / C_MPS))
        frame = frame + c.noise_std * math.sqrt(2.0) * self._cn(axis.bins)
        return frame.astype(np.complex64), truth

    def _returns(self, to_surface: np.ndarray, boresight: np.ndarray, r0_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Ranges and complex weights of the specular return and the facets (the rough surface's glints)."""
        c = self.config
        rng = self._rng
        amplitude = c.echo_at_1m * (1.0 / r0_m) ** self.exponent * (c.reflection_coeff / FLAT_SEA_GAMMA)
        # facet look directions: the specular direction tilted by slopes drawn from N(0, s²/2) per axis
        u = np.cross(to_surface, [0.0, 0.0, 1.0])
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
        v = np.cross(to_surface, u)
        slopes = rng.normal(0.0, math.sqrt(self.mean_square_slope / 2.0), (c.facets, 2))
        looks = to_surface[None, :] + slopes[:, :1] * u[None, :] + slopes[:, 1:] * v[None, :]
        looks /= np.linalg.norm(looks, axis=1, keepdims=True)
        cos_beta = looks @ to_surface
        heights = rng.normal(0.0, self.small_scale_rms_m, c.facets)
        facet_ranges = r0_m / cos_beta - heights * cos_beta
        ranges = np.concatenate([[r0_m], facet_ranges])
        directions = np.vstack([to_surface, looks])
        # two-way amplitude pattern of the antenna: exp(−ln2 (α/α_h)²), α off the boresight
        alpha = np.arccos(np.clip(directions @ boresight, -1.0, 1.0))
        gain = np.exp(-math.log(2.0) * (alpha / math.radians(c.beam_half_power_deg)) ** 2)
        rho = self.coherence
        shares = np.full(c.facets + 1, math.sqrt(max(0.0, 1.0 - rho**2) / c.facets))
        shares[0] = rho
        phases = np.concatenate([[self._phase0], rng.uniform(0.0, 2.0 * math.pi, c.facets)])
        return ranges, amplitude * gain * shares * np.exp(1j * phases)

    def _static_part(self, axis: RangeAxis) -> np.ndarray:
        """Direct path + floor + drone body, fixed for the scene (what the background map captures)."""
        if axis not in self._static:
            c = self.config
            r = axis.ranges_m()
            rng = np.random.default_rng(np.random.SeedSequence([axis.bins, 0xB6]))  # same for every seed
            phases = np.exp(1j * rng.uniform(0.0, 2.0 * math.pi, axis.bins))
            decay = np.exp(-np.maximum(r - c.direct_path_at_m, 0.0) / c.direct_path_decay_m)
            level = c.direct_path * decay + c.clutter_floor
            static = level * phases
            for range_m, amplitude in c.body_reflections:
                pulse = np.exp(-((r - range_m) ** 2) / (2.0 * c.pulse_sigma_m**2))
                static = static + amplitude * pulse * np.exp(-1j * 4.0 * math.pi * c.fc_hz * range_m / C_MPS)
            self._static[axis] = static
        return self._static[axis]

    def _cn(self, n: int) -> np.ndarray:
        """n samples of CN(0, 1): unit complex variance, 1/2 per component."""
        return (self._rng.standard_normal(n) + 1j * self._rng.standard_normal(n)) / math.sqrt(2.0)
