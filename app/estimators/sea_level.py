"""The mean sea level under the vehicle, from radar heights and the vehicle's own altitude. Pure.

Each radar height h at time t, added to the vehicle's down position then, is one sample of where the sea
surface is (down, in the autopilot's local frame): z = p_d(t) + h(t). That surface heaves with the waves
(±Hs/2) and, seen in the autopilot's frame, creeps with its altitude estimate's drift (a barometer, a
vertical velocity bias). Guidance wants neither the waves nor the lag: it holds a height above the *mean*
surface, and the vehicle must not chase every crest.

A second-order tracking loop (a type-2 loop, like a PLL's: zero steady-state error to a constant drift)
with natural frequency ω = 1/τ and damping ζ:

    e = z − L;   L ← L + Δt·(Ṙ + 2ζω·e);   Ṙ ← Ṙ + Δt·ω²·e          (L the level, Ṙ its drift rate)

Waves well above ω are attenuated by about 2ζω/ω_wave: τ = 5 s leaves ±4 cm of a ±0.25 m sea-state-2
swell at 1.8 rad/s. The first sample starts the level; a gap longer than ``max_gap_s`` starts it over.

``crest_m`` is the highest the surface rose above that level within the last ``crest_window_s`` (a sliding
maximum): how high a vehicle waiting over the sea must stay for a crest not to reach it. ``rise_rate_mps`` is
how fast the surface under the vehicle rises now (up positive; a least-squares slope over the samples of the last
``rate_window_s``): a crest coming or going.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

RATE_WINDOW_S = 0.4  # rise_rate_mps: the slope over this long (4–5 radar heights at 10 Hz; ±0.06 m/s of 2 cm noise)


@dataclass(frozen=True, slots=True)
class SeaLevelEstimate:
    t_s: float
    down_m: float  # mean sea surface, NED down in the autopilot's local frame
    rate_mps: float  # its drift, down positive


class MeanSeaLevel:
    def __init__(
        self, tau_s: float = 5.0, damping: float = 0.8, max_gap_s: float = 2.0, crest_window_s: float = 60.0
    ) -> None:
        if not tau_s > 0.0:
            raise ValueError(f"tau_s must be > 0, not {tau_s}")
        self.crest_window_s = crest_window_s
        self._rises: deque[tuple[float, float]] = deque()  # (t_s, rise above the level), decreasing rises
        self.rate_window_s = RATE_WINDOW_S
        self._recent: deque[tuple[float, float]] = deque()  # (t_s, surface down) of the last rate_window_s
        self.omega = 1.0 / tau_s
        self.damping = damping
        self.max_gap_s = max_gap_s
        self._t_s: float | None = None
        self._level = 0.0
        self._rate = 0.0
        self.samples = 0

    def update(self, t_s: float, surface_down_m: float) -> None:
        """One sample of the instantaneous surface (down, m) at ``t_s``; non-finite or older samples are ignored."""
        if not (math.isfinite(t_s) and math.isfinite(surface_down_m)):
            return
        if self._t_s is None or t_s - self._t_s > self.max_gap_s:
            self._t_s, self._level, self._rate = t_s, surface_down_m, 0.0
            self.samples = 1
            self._recent.clear()
            self._recent.append((t_s, surface_down_m))
            return
        dt_s = t_s - self._t_s
        if dt_s <= 0.0:
            return
        self._recent.append((t_s, surface_down_m))
        while self._recent[0][0] < t_s - self.rate_window_s:
            self._recent.popleft()
        e = surface_down_m - self._level
        self._note_rise(t_s, -e)
        self._level += dt_s * (self._rate + 2.0 * self.damping * self.omega * e)
        self._rate += dt_s * self.omega**2 * e
        self._t_s = t_s
        self.samples += 1

    def _note_rise(self, t_s: float, rise_m: float) -> None:
        rises = self._rises
        while rises and rises[-1][1] <= rise_m:
            rises.pop()
        rises.append((t_s, rise_m))
        while rises[0][0] < t_s - self.crest_window_s:
            rises.popleft()

    def crest_m(self) -> float:
        """The highest rise of the surface above the level in the last ``crest_window_s`` (0 without samples)."""
        return max(0.0, self._rises[0][1]) if self._rises else 0.0

    def rise_rate_mps(self, t_s: float) -> float | None:
        """How fast the surface under the vehicle rises (m/s, up positive): the least-squares slope of the samples
        of the last ``rate_window_s`` before ``t_s``; None with fewer than three there (the radar reads nothing:
        above its range, or the water inside its first range)."""
        pts = [(t, d) for t, d in self._recent if t_s - self.rate_window_s <= t <= t_s]
        if len(pts) < 3:
            return None
        mt = sum(t for t, _ in pts) / len(pts)
        md = sum(d for _, d in pts) / len(pts)
        stt = sum((t - mt) ** 2 for t, _ in pts)
        if stt <= 0.0:
            return None
        return -sum((t - mt) * (d - md) for t, d in pts) / stt

    def last(self) -> SeaLevelEstimate | None:
        """The level as of the last sample, however old (None before the first)."""
        return None if self._t_s is None else SeaLevelEstimate(self._t_s, self._level, self._rate)

    def estimate(self, t_s: float) -> SeaLevelEstimate | None:
        """The level extrapolated to ``t_s`` along its drift; None before the first sample or after a gap."""
        if self._t_s is None or t_s - self._t_s > self.max_gap_s:
            return None
        return SeaLevelEstimate(t_s, self._level + self._rate * max(0.0, t_s - self._t_s), self._rate)
