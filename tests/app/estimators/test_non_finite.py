"""Estimators reject and count a NaN/inf sample, change nothing, and go on as if it never came."""

from __future__ import annotations

import math

import numpy as np

from app.estimators.cv_filter import ConstantVelocityFilter
from app.estimators.state_history import StateHistory
from app.messages import AttitudeEuler, PositionVelocityNed, TargetObservation

COV = ((0.01, 0.0), (0.0, 0.01))


def fixes(n=40):
    return [TargetObservation(0.1 * i, (0.5 * 0.1 * i, 0.0, 0.0), COV) for i in range(n)]


def test_target_filter_rejects_a_nan_fix_and_ends_where_a_clean_run_ends():
    clean, dirty = ConstantVelocityFilter(), ConstantVelocityFilter()
    for i, obs in enumerate(fixes()):
        clean.update(obs)
        if i == 20:
            for bad in (
                TargetObservation(obs.t_s, (math.nan, 0.0, 0.0), COV),
                TargetObservation(obs.t_s, (0.0, 0.0, 0.0), ((math.inf, 0.0), (0.0, 0.01))),
                TargetObservation(math.nan, (0.0, 0.0, 0.0), COV),
            ):
                result = dirty.update(bad)
                assert not result.accepted and result.reason == "non_finite"
        dirty.update(obs)
    assert dirty.counts["non_finite"] == 3 and dirty.counts["fused"] == clean.counts["fused"]
    a, b = clean.estimate(4.0), dirty.estimate(4.0)
    assert a is not None and b is not None and a.pos_ned_m == b.pos_ned_m and a.vel_ned_mps == b.vel_ned_mps


def test_state_history_drops_and_counts_non_finite_samples():
    h = StateHistory()
    assert h.add_pos_vel(PositionVelocityNed(0.0, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0)))
    assert not h.add_pos_vel(PositionVelocityNed(0.1, (math.nan, 0.0, -5.0), (0.0, 0.0, 0.0)))
    assert h.add_pos_vel(PositionVelocityNed(0.2, (2.0, 0.0, -5.0), (0.0, 0.0, 0.0)))
    assert h.add_attitude(AttitudeEuler(0.0, 0.0, 0.0, 0.0))
    assert not h.add_attitude(AttitudeEuler(0.1, 0.0, math.inf, 0.0))
    assert h.add_attitude(AttitudeEuler(0.2, 0.0, 0.0, 0.2))
    assert h.dropped_non_finite == 2
    state = h.at(0.1)  # interpolated across the dropped sample
    assert np.allclose(state.pos_ned_m, (1.0, 0.0, -5.0))
