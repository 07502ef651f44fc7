"""Build the target filter a mission asks for.

The choice is described by its shape (:class:`TargetFilterChoice`), not by the mission's parameter class:
the estimators never import the missions that use them. ``MissionParams`` fits it as it is.
"""

from __future__ import annotations

from typing import Literal, Protocol

from app.estimators.cv_filter import ConstantVelocityFilter
from app.estimators.sea_state import SEA_STATES
from app.estimators.target_filter import LinearTargetFilter
from app.estimators.wave_filter import OSCILLATOR_BANKS, WaveFilter

TargetFilterKind = Literal["constant_velocity", "wave"]
WaveOscillators = Literal["standard", "wide", "fine"]  # ``OSCILLATOR_BANKS``


class TargetFilterChoice(Protocol):
    """Which motion model to run: for the wave filter the expected WMO sea state (code 0–5), for the
    constant-velocity filter its process noise (the thesis set Q from configuration parameters); the wave filter's
    bank of oscillators, how fast the drift it learns may change, and whether it reads the sea's elevation (its
    noise, 0: not); and whether the innovation gate rejects outliers."""

    @property
    def target_filter(self) -> TargetFilterKind: ...

    @property
    def sea_state(self) -> int: ...

    @property
    def wave_oscillators(self) -> WaveOscillators: ...

    @property
    def wave_elevation_std_m(self) -> float: ...

    @property
    def wave_drift_q_m2ps3(self) -> float: ...

    @property
    def cv_q_pos_m2ps(self) -> float: ...

    @property
    def cv_q_vel_m2ps3(self) -> float: ...

    @property
    def innovation_gate(self) -> bool: ...


def make_target_filter(choice: TargetFilterChoice) -> LinearTargetFilter:
    if choice.target_filter == "constant_velocity":
        gate = choice.innovation_gate
        return ConstantVelocityFilter(choice.cv_q_pos_m2ps, choice.cv_q_vel_m2ps3, innovation_gate=gate)
    sea = SEA_STATES[choice.sea_state]
    elevation_std_m = choice.wave_elevation_std_m if choice.wave_elevation_std_m > 0.0 else None
    bank = OSCILLATOR_BANKS[choice.wave_oscillators]
    return WaveFilter(
        sea.hs_m,
        sea.tp_s,
        bank.ratios,
        bank.damping,
        q_current_m2ps3=choice.wave_drift_q_m2ps3,
        innovation_gate=choice.innovation_gate,
        elevation_std_m=elevation_std_m,
    )
