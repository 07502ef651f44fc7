"""Target filters: the common machinery of a linear Kalman filter on the object's horizontal motion.

A concrete filter gives its state layout through ``F(dt)``, ``Q(dt)``, ``H`` and ``initial_state(z, R)``;
this base does the rest, the same way for every model:

- **Fuse at measurement time, predict to now.** ``update(obs)`` fuses a fix at its capture time;
  ``estimate(t_s)`` predicts (without changing the filter) to any later time, e.g. the planned touchdown.
  Between fixes the filter only predicts — the thesis's H = 0 steps.
- **Late fixes** (capture time before the last fused one, within ``replay_window_s``) are fused in order:
  the filter rolls back to the checkpoint before them and replays the later fixes. Older ones are dropped
  and counted.
- **Innovation gate** (``innovation_gate``, on unless a baseline turns it off): NIS = yᵀS⁻¹y > ``NIS_GATE_2DOF``
  rejects a fix (false detections); the ``OUTLIER_ESCAPE_COUNT``-th consecutive rejection re-initialises the
  filter on it (the object really moved, as AC_PrecLand's outlier escape) — only if those rejected fixes agree
  with one another (each within ``ESCAPE_AGREE_M`` + ``ESCAPE_SPEED_MPS``·Δt of the one before) and the object
  could have got there since its last fused fix (within ``ESCAPE_REACH_M`` + ``ESCAPE_SPEED_MPS``·Δt of it).
  Fixes that agree somewhere the object cannot be are clutter: a printed glyph of its marker 3–6 m off (sea
  state 3, seed 1: escapes of 3–6 m onto it in 8 of 56 glyph runs, 152 back and forth in one that failed), sun
  glints in the buoy's place (up to 14 m), while escapes of an estimate that drifted during a blind spell (0.2–1 m)
  still come at once. Off, every fix is fused, as the thesis's Listing 4.1 does; the NIS is still computed and
  returned.
- **Timeout**: no fix for ``timeout_s`` → no estimate; the next fix re-initialises.
- P is kept symmetric positive-definite: Joseph-form update (filterpy), symmetrised after every step.
- **Side measurements** (``add_scalar``): a scalar z = h·x measured at ``t_s``, e.g. the sea's elevation that the
  wave filter reads its orbital velocity from. One newer than the state waits (pending) and is fused on the way to
  the next fix, in time order; ``estimate`` predicts from the state with the pending ones fused. A late fix's replay
  takes back the side measurements after its checkpoint and fuses them again in order. Gated at
  ``SCALAR_GATE_SIGMA`` σ. They do not keep a lock alive: only fixes do.

The rest of the app sees only ``TargetObservation`` in and ``TargetEstimate`` out.
"""

from __future__ import annotations

import bisect
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update

from app.messages import TargetEstimate, TargetObservation

NIS_GATE_2DOF = 13.82  # χ²(2 dof) at p = 0.001: a fix this unlikely is an outlier
OUTLIER_ESCAPE_COUNT = 3  # this many consecutive outliers in a row: re-initialise on the last one …
ESCAPE_AGREE_M = 0.5  # … if each was this close to the one before (plus ESCAPE_SPEED_MPS × the time between) …
ESCAPE_REACH_M = 1.0  # … and the last this close to the last fused fix (plus ESCAPE_SPEED_MPS × the time since):
ESCAPE_SPEED_MPS = 2.0  # faster than the object's drift and wave orbit together (sea state 3's orbit: ±0.6 m)

SCALAR_GATE_SIGMA = 4.0  # a side measurement this many σ off the prediction is not fused

Array = np.ndarray


@dataclass(frozen=True, slots=True)
class ScalarMeasurement:
    """z = Σ h_values[j]·x[h_index[j]] + noise of variance ``var``, measured at ``t_s``."""

    t_s: float
    z: float
    var: float
    h_index: Array
    h_values: Array


@dataclass(frozen=True, slots=True)
class UpdateResult:
    accepted: bool
    nis: float | None  # None when the fix (re-)initialised the filter
    reason: str  # "init", "fused", "outlier", "outlier_escape", "late_fused", "too_late", "timeout_reinit"


@dataclass(slots=True)
class _Checkpoint:
    t_s: float
    x: Array
    P: Array
    outliers: tuple[TargetObservation, ...]
    last_fix_t_s: float
    last_fix_ne_m: tuple[float, float]
    down_m: float


class LinearTargetFilter(ABC):
    """Common Kalman machinery; subclasses define the motion model."""

    name = "linear"

    def __init__(self, timeout_s: float = 3.0, replay_window_s: float = 1.0, innovation_gate: bool = True) -> None:
        self.timeout_s = timeout_s
        self.replay_window_s = replay_window_s
        self.innovation_gate = innovation_gate
        self.x: Array | None = None
        self.P: Array | None = None
        self.t_s = -math.inf  # time of the state x, P (the last fused fix)
        self._last_fix_t_s = -math.inf
        self._last_fix_ne_m = (0.0, 0.0)  # where the last fused fix put the object
        self._down_m = 0.0
        self._outliers: tuple[TargetObservation, ...] = ()  # the rejected fixes since the last fused one that agree
        # (checkpoint before the fix, the fix) for fixes inside the replay window, in time order
        self._history: list[tuple[_Checkpoint, TargetObservation]] = []
        self._pending: list[ScalarMeasurement] = []  # side measurements after t_s, not yet in x, P (time order)
        self._side_fused: list[ScalarMeasurement] = []  # those in x, P within the replay window
        self._head: tuple[float, Array, Array] | None = None  # x, P with the pending ones fused, and their time
        self.version = 0  # changes whenever what ``estimate`` answers may have changed
        self.counts = {
            "fused": 0, "outlier": 0, "outlier_escape": 0, "too_late": 0, "init": 0, "late_fused": 0, "non_finite": 0,
            "side_fused": 0, "side_gated": 0, "side_too_late": 0,
        }  # fmt: skip

    # ---- the model ------------------------------------------------------------------------------

    @abstractmethod
    def F(self, dt_s: float) -> Array: ...

    @abstractmethod
    def Q(self, dt_s: float) -> Array: ...

    @property
    @abstractmethod
    def H(self) -> Array:
        """Position (north, east) from the state: 2×n."""

    @abstractmethod
    def initial_state(self, z: Array, R: Array) -> tuple[Array, Array]: ...

    @abstractmethod
    def velocity_acceleration(self, x: Array) -> tuple[Array, Array]:
        """Horizontal velocity and acceleration (2-vectors) implied by a state."""

    def mean_motion(self, x: Array) -> tuple[Array, Array]:
        """The object's mean position and drift velocity (2-vectors) in a state, for predicting seconds ahead,
        beyond what the filter's own estimate covers; the whole motion unless a model separates out its waves."""
        return self.H @ x, self.velocity_acceleration(x)[0]

    # ---- public ---------------------------------------------------------------------------------

    def reset(self) -> None:
        self.x = self.P = None
        self.t_s = self._last_fix_t_s = -math.inf
        self._outliers = ()
        self._history.clear()
        self._pending, self._side_fused, self._head = [], [], None
        self.version += 1

    @property
    def initialised(self) -> bool:
        return self.x is not None

    def update(self, obs: TargetObservation) -> UpdateResult:
        """Fuse one fix at its capture time; a fix with a NaN/inf is rejected and counted, changing nothing."""
        values = (obs.t_s, *obs.pos_ned_m, *obs.cov_ne_m2[0], *obs.cov_ne_m2[1])
        if not all(map(math.isfinite, values)):
            self.counts["non_finite"] += 1
            return UpdateResult(False, None, "non_finite")
        self.version += 1
        if self.x is not None and obs.t_s < self.t_s:
            return self._fuse_late(obs)
        return self._fuse(obs)

    def add_scalar(self, m: ScalarMeasurement) -> bool:
        """A side measurement (see the module docstring): False when there is no lock or it is older than the
        newest fix, changing nothing."""
        if self.x is None or self.P is None or not m.t_s >= self.t_s or not math.isfinite(m.z):
            self.counts["side_too_late"] += 1
            return False
        self.version += 1
        i = bisect.bisect_right([p.t_s for p in self._pending], m.t_s)
        self._pending.insert(i, m)
        head = self._head
        if head is not None and i == len(self._pending) - 1 and m.t_s >= head[0]:
            self._head = (m.t_s, *self._fuse_scalar(head[1], head[2], m.t_s - head[0], m))
        else:
            self._head = None
        return True

    @property
    def takes_elevation(self) -> bool:
        """Whether ``update_elevation`` can use the sea's elevation (a model without waves has no use for it)."""
        return False

    def update_elevation(self, t_s: float, elevation_m: float) -> bool:
        """The sea's elevation at the object (m, up from the mean sea) measured at ``t_s``; True when it was taken."""
        return False

    def _fuse_scalar(self, x: Array, P: Array, dt_s: float, m: ScalarMeasurement) -> tuple[Array, Array]:
        """Predict x, P by ``dt_s`` and fuse ``m`` (unless it is more than ``SCALAR_GATE_SIGMA`` σ off)."""
        F = self.F(dt_s)
        x = F @ x
        P = F @ P @ F.T + self.Q(dt_s)
        idx, h = m.h_index, m.h_values
        # S = h P hᵀ + r,  y = z − h x,  K = P hᵀ / S,  P ← P − K (h P)
        Ph = P[:, idx] @ h
        S = float(h @ Ph[idx]) + m.var
        y = m.z - float(h @ x[idx])
        if y * y > SCALAR_GATE_SIGMA**2 * S:
            self.counts["side_gated"] += 1
            return x, P
        K = Ph / S
        self.counts["side_fused"] += 1
        P = P - np.outer(K, Ph)
        return x + K * y, 0.5 * (P + P.T)

    def _state_with_pending(self, t_s: float) -> tuple[float, Array, Array]:
        """The state with the side measurements up to ``t_s`` fused, and its time."""
        assert self.x is not None and self.P is not None
        if not self._pending:
            return self.t_s, self.x, self.P
        head = self._head
        if head is None or head[0] > t_s:
            t0, x, P = self.t_s, self.x, self.P
            for m in self._pending:
                if m.t_s > t_s:
                    break
                x, P = self._fuse_scalar(x, P, m.t_s - t0, m)
                t0 = m.t_s
            if t0 < self._pending[-1].t_s:
                return t0, x, P  # not kept: asked for an instant before the newest
            head = self._head = (t0, x, P)
        return head

    def _fuse_pending(self, until_t_s: float) -> None:
        """Fuse the pending side measurements up to ``until_t_s`` into the state, in time order."""
        assert self.x is not None and self.P is not None
        while self._pending and self._pending[0].t_s <= until_t_s:
            m = self._pending.pop(0)
            self.x, self.P = self._fuse_scalar(self.x, self.P, m.t_s - self.t_s, m)
            self.t_s = m.t_s
            self._side_fused.append(m)
        while self._side_fused and self._side_fused[0].t_s < until_t_s - self.replay_window_s:
            self._side_fused.pop(0)
        self._head = None

    def estimate(self, t_s: float) -> TargetEstimate | None:
        """The object at ``t_s`` (≥ the last fix), predicted without changing the filter."""
        if self.x is None or self.P is None or t_s - self._last_fix_t_s > self.timeout_s:
            return None
        state_t_s, x0, P0 = self._state_with_pending(t_s)
        dt_s = max(0.0, t_s - state_t_s)
        F, H = self.F(dt_s), self.H
        x = F @ x0
        pos = H @ x
        vel, acc = self.velocity_acceleration(x)
        # only the position's covariance: H (F P Fᵀ + Q) Hᵀ = (H F) P (H F)ᵀ + H Q Hᵀ, without the full F P Fᵀ
        HF = H @ F
        cov = HF @ P0 @ HF.T + H @ self.Q(dt_s) @ H.T
        return TargetEstimate(
            t_s,
            (float(pos[0]), float(pos[1]), self._down_m),
            (float(vel[0]), float(vel[1]), 0.0),
            (float(acc[0]), float(acc[1]), 0.0),
            ((float(cov[0, 0]), float(cov[0, 1])), (float(cov[1, 0]), float(cov[1, 1]))),
        )

    def drifted(self, t_s: float) -> tuple[tuple[float, float], tuple[float, float]] | None:
        """Where the object's mean drift (``mean_motion`` at the last fix) takes it by ``t_s``, and that drift
        (NE m, NE m/s): still answered after the timeout, until the filter is reset or re-initialised (``None``
        before any fix)."""
        if self.x is None:
            return None
        pos, vel = self.mean_motion(self.x)
        dt_s = max(0.0, t_s - self.t_s)
        return (float(pos[0] + vel[0] * dt_s), float(pos[1] + vel[1] * dt_s)), (float(vel[0]), float(vel[1]))

    # ---- internals ------------------------------------------------------------------------------

    def _checkpoint(self) -> _Checkpoint:
        assert self.x is not None and self.P is not None
        return _Checkpoint(
            self.t_s,
            self.x.copy(),
            self.P.copy(),
            self._outliers,
            self._last_fix_t_s,
            self._last_fix_ne_m,
            self._down_m,
        )

    def _restore(self, c: _Checkpoint) -> None:
        self.t_s, self.x, self.P = c.t_s, c.x.copy(), c.P.copy()
        self._outliers, self._last_fix_t_s, self._down_m = c.outliers, c.last_fix_t_s, c.down_m
        self._last_fix_ne_m = c.last_fix_ne_m
        if self._side_fused:  # the side measurements after the checkpoint wait again, to be fused in order
            later = [m for m in self._side_fused if m.t_s > c.t_s]
            self._side_fused = [m for m in self._side_fused if m.t_s <= c.t_s]
            self._pending = sorted(later + self._pending, key=lambda m: m.t_s)
        self._head = None

    def _init(self, obs: TargetObservation, reason: str) -> UpdateResult:
        z, R = _zR(obs)
        self.x, self.P = self.initial_state(z, R)
        self.t_s = self._last_fix_t_s = obs.t_s
        self._last_fix_ne_m = (obs.pos_ned_m[0], obs.pos_ned_m[1])
        self._down_m = obs.pos_ned_m[2]
        self._outliers = ()
        self._history.clear()
        self._pending = [m for m in self._pending if m.t_s > obs.t_s]
        self._side_fused, self._head = [], None
        self.counts["init"] += 1
        return UpdateResult(True, None, reason)

    def _fuse(self, obs: TargetObservation) -> UpdateResult:
        if self.x is None or self.P is None:
            return self._init(obs, "init")
        if obs.t_s - self._last_fix_t_s > self.timeout_s:
            return self._init(obs, "timeout_reinit")
        before = self._checkpoint()  # (without the side measurements since: a replay from it fuses them again)
        if self._pending:
            self._fuse_pending(obs.t_s)
        z, R = _zR(obs)
        dt_s = obs.t_s - self.t_s
        # x⁻ = F x,  P⁻ = F P Fᵀ + Q
        x, P = kf_predict(self.x, self.P, self.F(dt_s), self.Q(dt_s))
        H = self.H
        # y = z − H x⁻,  S = H P⁻ Hᵀ + R,  NIS = yᵀ S⁻¹ y
        y = z - H @ x
        S = H @ P @ H.T + R
        nis = float(y @ np.linalg.solve(S, y))
        if self.innovation_gate and nis > NIS_GATE_2DOF:
            self._outliers = _agreeing(self._outliers, obs)
            if len(self._outliers) >= OUTLIER_ESCAPE_COUNT and self._reachable(obs):
                self.counts["outlier_escape"] += 1
                return self._init(obs, "outlier_escape")
            self.counts["outlier"] += 1
            return UpdateResult(False, nis, "outlier")
        # K = P⁻Hᵀ S⁻¹,  x = x⁻ + K y,  P = (I − KH) P⁻ (I − KH)ᵀ + K R Kᵀ   (filterpy, Joseph form)
        x, P = kf_update(x, P, z, R, H)
        self.x, self.P = x, 0.5 * (P + P.T)
        self.t_s = self._last_fix_t_s = obs.t_s
        self._last_fix_ne_m = (obs.pos_ned_m[0], obs.pos_ned_m[1])
        self._down_m = obs.pos_ned_m[2]
        self._outliers = ()
        self._history.append((before, obs))
        while self._history and self._history[0][1].t_s < obs.t_s - self.replay_window_s:
            self._history.pop(0)
        self.counts["fused"] += 1
        return UpdateResult(True, nis, "fused")

    def _reachable(self, obs: TargetObservation) -> bool:
        """Could the object have got to ``obs`` since the last fused fix?"""
        n_m, e_m = self._last_fix_ne_m
        apart_m = math.hypot(obs.pos_ned_m[0] - n_m, obs.pos_ned_m[1] - e_m)
        return apart_m <= ESCAPE_REACH_M + ESCAPE_SPEED_MPS * (obs.t_s - self._last_fix_t_s)

    def _fuse_late(self, obs: TargetObservation) -> UpdateResult:
        # Insert before the first fix captured after it; the checkpoint before that fix must not be
        # later than the late fix (we can only predict forward).
        i = bisect.bisect_right([o.t_s for _, o in self._history], obs.t_s)
        if i >= len(self._history) or self._history[i][0].t_s > obs.t_s:
            self.counts["too_late"] += 1
            return UpdateResult(False, None, "too_late")
        replay = [o for _, o in self._history[i:]]
        self._restore(self._history[i][0])
        del self._history[i:]
        result = self._fuse(obs)
        for o in replay:
            self._fuse(o)
        self.counts["late_fused"] += 1
        return UpdateResult(result.accepted, result.nis, "late_fused" if result.accepted else result.reason)


def _zR(obs: TargetObservation) -> tuple[Array, Array]:
    z = np.array(obs.pos_ned_m[:2], dtype=float)
    R = np.array(obs.cov_ne_m2, dtype=float)
    return z, R


def _agreeing(outliers: tuple[TargetObservation, ...], obs: TargetObservation) -> tuple[TargetObservation, ...]:
    """The run of rejected fixes that ends with ``obs``: the run so far and ``obs`` if ``obs`` agrees with its last
    fix (within ``ESCAPE_AGREE_M`` + ``ESCAPE_SPEED_MPS`` × the time between), else ``obs`` alone."""
    if outliers:
        last = outliers[-1]
        apart_m = math.hypot(obs.pos_ned_m[0] - last.pos_ned_m[0], obs.pos_ned_m[1] - last.pos_ned_m[1])
        if apart_m <= ESCAPE_AGREE_M + ESCAPE_SPEED_MPS * abs(obs.t_s - last.t_s):
            return (*outliers[-(OUTLIER_ESCAPE_COUNT - 1) :], obs)
    return (obs,)
