"""Build the target filter a mission asks for."""

from __future__ import annotations

from app.estimators.cv_filter import ConstantVelocityFilter
from app.estimators.sea_state import SEA_STATES
from app.estimators.target_filter import LinearTargetFilter
from app.estimators.wave_filter import WaveFilter
from app.missions.params import MissionParams


def make_target_filter(params: MissionParams) -> LinearTargetFilter:
    if params.target_filter == "constant_velocity":
        return ConstantVelocityFilter()
    sea = SEA_STATES[params.sea_state]
    return WaveFilter(sea.hs_m, sea.tp_s)
