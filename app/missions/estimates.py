"""What guards may know about the world: an immutable snapshot of the estimates, built once per tick.

Guards never read live objects (the setpoint loop's target, a filter, a driver). Each tick the mission
(``MissionModel``) freezes what its estimators know into ``Estimates``; the runner hands that to every guard
in the tick, so all transitions of one tick judge the same facts. Mission-specific figures (circle laps
flown, search legs done, grab attempts) go in ``progress`` by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Protocol

from app.messages import TargetState

_EMPTY: Mapping[str, float] = MappingProxyType({})


@dataclass(frozen=True, slots=True)
class SensorHealth:
    """``None``: the mission has no such sensor (or it has produced nothing yet)."""

    camera_frame_age_s: float | None = None
    radar_lost: bool = False


@dataclass(frozen=True, slots=True)
class Estimates:
    t_s: float
    target: TargetState | None = None  # the object's estimated state (NED about home)
    target_cov_ne_m2: tuple[tuple[float, float], tuple[float, float]] | None = None  # horizontal, m²
    fix_age_s: float | None = None  # since the last accepted observation
    converged_for_s: float | None = None  # how long the filter has counted as converged
    height_above_sea_m: float | None = None  # from the radar, not from home
    # the vehicle over the mean sea (its altitude over the level the radar last tracked; valid for a few seconds
    # after the radar stops — under its first range, near the water)
    height_over_mean_sea_m: float | None = None
    sensors: SensorHealth = field(default_factory=SensorHealth)
    progress: Mapping[str, float] = field(default_factory=lambda: _EMPTY)  # mission-specific figures by name

    def __post_init__(self) -> None:
        if not isinstance(self.progress, MappingProxyType):
            object.__setattr__(self, "progress", MappingProxyType(dict(self.progress)))


class MissionModel(Protocol):
    """A mission's own state beyond the table: its estimates for guards and its figures for the summary."""

    def snapshot(self, t_s: float) -> Estimates: ...

    def summary(self) -> dict[str, Any]:
        """The mission's figures for ``summary.json`` (e.g. tracking error percentiles)."""
        ...


class NoEstimates:
    """A mission with nothing to estimate."""

    def snapshot(self, t_s: float) -> Estimates:
        return Estimates(t_s)

    def summary(self) -> dict[str, Any]:
        return {}
