"""Wave spectra by sea state, their synthesis as a seeded sum of directional components, and fast sums over them.

Sea states follow the WMO sea-state code 0–5. Each code's significant wave height ``hs_m`` is the upper
bound of its band; the peak period is that of a fully developed Pierson–Moskowitz sea of that height::

    ωp = 0.877 g / U19.5,   Hs = 0.21 U19.5² / g   ⇒   Tp = 2π/ωp ≈ 4.99 √Hs  (s, Hs in m)

with 1.6 s as the shortest period (code 1) and no waves at all for code 0.

Spectra are one-sided, in m²·s/rad, written with Hs and ωp (ITTC / Bretschneider form)::

    S_PM(ω) = 5/16 · Hs² ωp⁴ ω⁻⁵ · exp(−5/4 (ωp/ω)⁴)                       ∫ S_PM dω = Hs²/16
    S_J(ω)  = C(γ) · S_PM(ω) · γ^exp(−(ω − ωp)² / (2 σ² ωp²)),  σ = 0.07 (ω ≤ ωp), 0.09 (ω > ωp)

where C(γ) is computed so that the JONSWAP spectrum has the same Hs. Directions spread as cos-2s
(Longuet-Higgins)::

    D(Δβ) ∝ cos^(2s)(Δβ / 2),   Δβ ∈ (−π, π]

Synthesis (deterministic amplitudes, random phases): [ω_min, ω_max] is cut into ``n_frequencies × n_directions``
equal sub-bins; each sub-bin gives one component whose energy ``a²/2`` is the spectrum integrated over the
sub-bin and whose frequency is jittered inside it, so no two components share a frequency (the variance at
a fixed point then converges to m0, and the record does not repeat). The directions are the
``n_directions`` equal-probability quantiles of D, dealt out in a seeded random order to each group of
``n_directions`` neighbouring sub-bins. Deep water: k = ω²/g.

Evaluation (:class:`PhaseTrig`, :class:`WaveSums`) works on blocks of samples × components; it is what makes
100 000 samples of the object cost a fraction of a second (see their docstrings).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from app.estimators.sea_state import GRAVITY_MPS2, pierson_moskowitz  # one spectrum for the app and the sim

JONSWAP_SIGMA_BELOW_PEAK = 0.07
JONSWAP_SIGMA_ABOVE_PEAK = 0.09
_FREQUENCY_JITTER = 0.25  # a component sits within ±25 % of its sub-bin's width from the centre
_GAUSS_POINTS = 8  # Gauss–Legendre points per sub-bin for the sub-bin energies

FloatArray = NDArray[np.float64]
TWO_PI = 2.0 * math.pi
BLOCK_ROWS = 256  # time samples per block: keeps the (samples × components) arrays in cache


def _peak_enhancement(omega: FloatArray, omega_p: float, gamma: float) -> FloatArray:
    # γ^r,  r = exp(−(ω − ωp)² / (2 σ² ωp²))
    sigma = np.where(omega <= omega_p, JONSWAP_SIGMA_BELOW_PEAK, JONSWAP_SIGMA_ABOVE_PEAK)
    r = np.exp(-((omega - omega_p) ** 2) / (2.0 * sigma**2 * omega_p**2))
    return np.asarray(gamma**r, dtype=np.float64)


def jonswap(omega_radps: ArrayLike, hs_m: float, tp_s: float, gamma: float = 3.3) -> FloatArray:
    """One-sided JONSWAP spectrum S(ω), m²·s/rad, normalised to the same Hs as Pierson–Moskowitz."""
    omega = np.asarray(omega_radps, dtype=np.float64)
    if hs_m <= 0.0 or tp_s <= 0.0:
        return np.zeros_like(omega)
    omega_p = 2.0 * math.pi / tp_s
    # C(γ) = (Hs²/16) / ∫ S_PM γ^r dω, integrated on a log grid (dω = ω d ln ω); the PM tail beyond 30 ωp
    # holds 1.5e-6 of the energy, the part below 0.3 ωp none.
    grid = omega_p * np.geomspace(0.3, 30.0, 4001)
    integrand = pierson_moskowitz(grid, hs_m, tp_s) * _peak_enhancement(grid, omega_p, gamma) * grid
    log_grid = np.log(grid)
    c_gamma = hs_m**2 / 16.0 / float(np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(log_grid)))
    return c_gamma * pierson_moskowitz(omega, hs_m, tp_s) * _peak_enhancement(omega, omega_p, gamma)


def spreading_quantiles_rad(spread_s: float, n_directions: int) -> FloatArray:
    """The ``n_directions`` equal-probability directions of cos-2s spreading, relative to the mean (rad)."""
    if n_directions == 1:
        return np.zeros(1)
    beta = np.linspace(-math.pi, math.pi, 4001)
    density = np.cos(beta / 2.0) ** (2.0 * spread_s)
    cdf = np.concatenate(([0.0], np.cumsum(0.5 * (density[1:] + density[:-1]) * np.diff(beta))))
    cdf /= cdf[-1]
    probabilities = (np.arange(n_directions) + 0.5) / n_directions
    return np.asarray(np.interp(probabilities, cdf, beta), dtype=np.float64)


@dataclass(frozen=True)
class WaveComponents:
    """The components of the surface η = Σ a cos(ω t − k_n n − k_e e + φ); read-only arrays of one length."""

    amplitude_m: FloatArray
    omega_radps: FloatArray
    k_north: FloatArray  # rad/m, along the direction the component travels to
    k_east: FloatArray
    phase_rad: FloatArray

    def __post_init__(self) -> None:
        for array in (self.amplitude_m, self.omega_radps, self.k_north, self.k_east, self.phase_rad):
            array.flags.writeable = False

    def __len__(self) -> int:
        return len(self.amplitude_m)


def synthesise_components(
    spectrum: Callable[[FloatArray], FloatArray],
    omega_range_radps: tuple[float, float],
    n_frequencies: int,
    n_directions: int,
    spread_s: float,
    mean_to_rad: float,
    rng: np.random.Generator,
) -> WaveComponents:
    """Seeded components of ``spectrum`` over ``omega_range``, travelling around ``mean_to_rad`` (module docstring)."""
    n_sub_bins = n_frequencies * n_directions
    edges = np.linspace(omega_range_radps[0], omega_range_radps[1], n_sub_bins + 1)
    lo, hi = edges[:-1], edges[1:]
    width = hi - lo
    nodes, weights = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
    # a²/2 = ∫ S dω over the sub-bin (Gauss–Legendre)
    energy_m2 = 0.5 * width * (spectrum(0.5 * (hi + lo)[:, None] + 0.5 * width[:, None] * nodes) @ weights)
    omega = 0.5 * (hi + lo) + rng.uniform(-_FREQUENCY_JITTER, _FREQUENCY_JITTER, n_sub_bins) * width
    order = np.concatenate([rng.permutation(n_directions) for _ in range(n_frequencies)])
    heading_rad = mean_to_rad + spreading_quantiles_rad(spread_s, n_directions)[order]
    # deep water: k = ω²/g
    k = omega**2 / GRAVITY_MPS2
    return WaveComponents(
        amplitude_m=np.sqrt(2.0 * energy_m2),
        omega_radps=omega,
        k_north=k * np.cos(heading_rad),
        k_east=k * np.sin(heading_rad),
        phase_rad=rng.uniform(0.0, TWO_PI, n_sub_bins),
    )


def no_components() -> WaveComponents:
    """A glassy sea."""
    return WaveComponents(*(np.zeros(0) for _ in range(5)))


def row_blocks(n: int) -> Iterator[slice]:
    """Slices of at most ``BLOCK_ROWS`` samples covering ``range(n)``."""
    for start in range(0, n, BLOCK_ROWS):
        yield slice(start, min(start + BLOCK_ROWS, n))


class PhaseTrig:
    """cos θ and sin θ for blocks of up to ``BLOCK_ROWS`` samples, in work arrays reused from block to block.

    The phase is formed in turns (θ/2π) and reduced to [−½, ½] in float64, the trig taken in float32: numpy 2's
    float64 sin/cos is ~25× slower than its float32 SIMD path, and float32 after the reduction is good to ~2e-7
    per component (well below a micrometre on the positions). Reusing the arrays matters as much: fresh ones
    cost page faults every block.
    """

    def __init__(self, phase_matrix: FloatArray, max_rows: int) -> None:
        self._turns_matrix = phase_matrix / TWO_PI
        shape = (min(max_rows, BLOCK_ROWS), phase_matrix.shape[1])
        self._turns, self._cos, self._sin = np.empty(shape), np.empty(shape), np.empty(shape)
        self._theta32, self._trig32 = np.empty(shape, np.float32), np.empty(shape, np.float32)

    def __call__(self, rows: FloatArray) -> tuple[FloatArray, FloatArray]:
        """cos θ, sin θ for ``rows`` = [t, north, east, 1] (at most ``BLOCK_ROWS``); valid until the next call."""
        n = len(rows)
        turns, cos, sin = self._turns[:n], self._cos[:n], self._sin[:n]
        theta32, trig32 = self._theta32[:n], self._trig32[:n]
        # θ/2π = (ω t − k_n n − k_e e + φ) / 2π
        np.matmul(rows, self._turns_matrix, out=turns)
        # θ/2π ← θ/2π − rint(θ/2π)
        np.rint(turns, out=cos)
        turns -= cos
        theta32[...] = turns
        theta32 *= np.float32(TWO_PI)
        np.cos(theta32, out=trig32)
        cos[...] = trig32
        np.sin(theta32, out=trig32)
        sin[...] = trig32
        return cos, sin


HORIZONTAL, VERTICAL = (0, 1), (2,)  # columns of g = [a k̂_n, a k̂_e, a]


class WaveSums:
    """Four of the object's wave sums Σᵢ gᵢ f(θᵢ) rᵢ (f = cos or sin), as one matrix product per block of samples.

    g = [a k̂_n, a k̂_e, a] weighs the horizontal or the vertical motion; the rate r is 1, θ̇, θ̇² and θ̈ in turn.
    As θ̇ᵢ = ωᵢ − kᵢ·v̄ (v̄ the mean velocity of the sample, the same for every component), each rate is a
    polynomial in v̄ (or ā) with per-component coefficients c::

        θ̇  = [1, v_n, v_e] · [ω, −k_n, −k_e]
        θ̇² = [1, v_n, v_e, v_n², v_n v_e, v_e²] · [ω², −2ω k_n, −2ω k_e, k_n², 2 k_n k_e, k_e²]
        θ̈  = [a_n, a_e] · [−k_n, −k_e]

    so Σᵢ gᵢ f(θᵢ) rᵢ = Σⱼ mⱼ (f(θ) @ (g cⱼ)), m the monomials: the (samples × components) work is one product.
    """

    def __init__(self, w: WaveComponents, columns: tuple[tuple[int, ...], ...]) -> None:
        """``columns[r]``: the columns of g wanted with rate r (``HORIZONTAL`` or ``VERTICAL``)."""
        omega, k_n, k_e, a = w.omega_radps, w.k_north, w.k_east, w.amplitude_m
        k = np.hypot(k_n, k_e)
        g = np.stack([a * k_n / k, a * k_e / k, a], axis=1)  # M × 3
        coefficients = [
            np.ones((1, len(w))),  # 1
            np.stack([omega, -k_n, -k_e]),  # θ̇
            np.stack([omega**2, -2.0 * omega * k_n, -2.0 * omega * k_e, k_n**2, 2.0 * k_n * k_e, k_e**2]),  # θ̇²
            np.stack([-k_n, -k_e]),  # θ̈
        ]
        self._shapes = [(len(cols), len(c)) for cols, c in zip(columns, coefficients, strict=True)]
        # weights[i, (column, term)] = g[i, column] · c[term, i]
        self._weights = np.ascontiguousarray(
            np.concatenate(
                [
                    (g[:, cols, None] * c.T[:, None, :]).reshape(len(w), len(cols) * len(c))
                    for cols, c in zip(columns, coefficients, strict=True)
                ],
                axis=1,
            )
        )

    @staticmethod
    def monomials(v_ne: FloatArray, a_ne: FloatArray) -> list[FloatArray]:
        """The monomials m of the mean velocity and acceleration for each rate, each (N, terms)."""
        v_n, v_e = v_ne[:, 0], v_ne[:, 1]
        ones = np.ones_like(v_n)
        return [
            ones[:, None],
            np.stack([ones, v_n, v_e], axis=1),
            np.stack([ones, v_n, v_e, v_n * v_n, v_n * v_e, v_e * v_e], axis=1),
            a_ne,
        ]

    def one(self, f: FloatArray, monomials: Sequence[Sequence[float]]) -> list[list[float]]:
        """``__call__`` for one sample (``f`` 1 × M), in floats: the monomials as tuples, the sums as lists."""
        products = (f @ self._weights)[0].tolist()
        sums, start = [], 0
        for m, (n_columns, n_terms) in zip(monomials, self._shapes, strict=True):
            column_sums = []
            for column in range(n_columns):
                s, i = 0.0, start + column * n_terms
                for term in m:
                    s += products[i] * term
                    i += 1
                column_sums.append(s)
            sums.append(column_sums)
            start += n_columns * n_terms
        return sums

    def __call__(self, f: FloatArray, monomials: list[FloatArray]) -> list[FloatArray]:
        """[Σ g f(θ), Σ g f(θ) θ̇, Σ g f(θ) θ̇², Σ g f(θ) θ̈], each (N, its number of columns)."""
        products = f @ self._weights
        sums, start = [], 0
        for m, (n_columns, n_terms) in zip(monomials, self._shapes, strict=True):
            block = products[:, start : start + n_columns * n_terms].reshape(len(f), n_columns, n_terms)
            sums.append(np.einsum("nct,nt->nc", block, m))
            start += n_columns * n_terms
        return sums
